"""Detectability: for each extension of :data:`.extensions.EXTENSIONS`, the weakest effect
this campaign could have named, so that ``none`` says what it rules out.

Nothing here knows a truth. At the baseline fit, the data are imagined to carry the
effect at magnitude theta, and the held-out error statistics the decision uses are
predicted from the model:

* **response** extensions: the effect changes the prediction by dG = G_theta - G_0 (the
  extension's transfer at theta minus the baseline's). The baseline refit absorbs what
  its own parameters can mimic: dG is projected off the span of the baseline's parameter
  sensitivities, weighted as its fit weighs the training data (a linearised refit). What
  is left adds diag(dG S_uu dG^H) to the held-out residual power of each band, over the
  signal bands that data with the effect would have; a perfect extension removes it
  again. The gain on a channel is that addition over the baseline's measured held-out
  residual plus it. As in the decision, a gain counts only on a channel with a model
  error: its systematic residual with the effect (the fit's, held-out error x input
  coherence, plus the addition) at or above ``systematic_floor`` of its power. Without
  that rule the limit read gains the decision never counts (a reservoir's on a bogie
  channel already within a model's accuracy) and ``none`` claimed too much: on bench
  seeds 8107, 8112, 8115 and 8116 the limits were 0.47-0.54 where reservoirs of
  0.54-0.66 had gone unnamed.
* The "baseline" of a response limit is the model the diagnosis ends with when it names no
  vehicle cause (the vehicle's properties found: its own bending, its equipment, the
  journeys' loads), the effect's own parameters in place of the model's of their kind
  (:meth:`_Responses.with_effect`), on the baseline's signal bands: a cause is judged after
  those, and against the baseline alone the carbody's own bending would stand in the
  residual every effect is measured against. Otherwise the baseline fit. The linearised
  refit moves the car's parameters only, not the properties' own, which the decision's
  refit also moves: on that model the limits lean optimistic.
* **wheel_out_of_round**: a radius amplitude A at wavelength lambda is a line of curvature
  A (2 pi / lambda)^2 in the consistency channel, mean square half its square, against
  the channel's measured held-out mean square.
* **track_flexibility**: the axle boxes' spectra multiplied by the track's
  transmissibility and the rigid rail's misfit held out by speed recomputed
  (:func:`.track.collapse_shift`), against its measured value.

An effect is *detectable* at theta when the predicted gain, less ``Z`` of its sampling
standard deviation (the effect's cross term with the measured residual, from the
held-out data's degrees of freedom), reaches the decision's bar, ``min_gain`` plus
``penalty`` per extension parameter. The limit is found on the extension's own physical
magnitude, from the weak end of its search range towards the strong end (a grid, then
bisection); the extension's other parameters are held at stated values. An effect that
even at the strong end of its range moves no channel's held-out error by ``Z`` of its
sampling scatter is *not observable* with this sensor set.
"""
from __future__ import annotations

from dataclasses import fields, replace

import numpy as np

from ...models.car2d import CarExtras
from ..limits import Z, Detectability, Limit, Magnitude, search, weakest
from .evidence import DiagnosisData, signal_bands
from .extensions import EXTENSIONS, FLOOR_DX_M
from .response import (FIT_NAMES, ResponseFit, SensorModel, channel_power, input_coherence, input_noise_power,
                       response_nrp, transfer)
from .track import collapse_shift
from .wheels import polygon_error

#: effects on the carbody itself: what they give back to the bogies through the air springs
#: is all a bogie-only sensor set has of them
CARBODY_EFFECTS = ("carbody_bending", "cog_offset")
_EXTRAS = CarExtras()
#: the response extensions' magnitudes (their ranges are the extensions' own search ranges)
RESPONSE_MAGNITUDES = {
    "sensor_offset": Magnitude("dx", "m", 0.0, 2.5, {"gyro_gain": 1.0}, signed=True, log=False),
    "carbody_bending": Magnitude("bending_hz", "Hz", 18.0, 4.0, {"bending_damping": _EXTRAS.bending_damping,
                                                                 "bending_mass_ratio": _EXTRAS.bending_mass_ratio}),
    "cog_offset": Magnitude("cog_offset", "m", 0.0, 3.0, signed=True, log=False),
    # one floor sensor off its declared x, the others in place: the limit is the weakest over
    # the sensors (which one shows its offset least depends on the car and its modes)
    "floor_sensor_offset": Magnitude("dx", "m", 0.0, FLOOR_DX_M, signed=True, log=False),
    # an orifice's corner moves with the flow (a quadratic orifice's with the amplitude): the
    # default corner and 2.5 times below and above it, across the carbody and bogie bands
    "airspring_reservoir": Magnitude("reservoir_ratio", "-", 0.05, 5.0,
                                     {"reservoir_corner_hz": _EXTRAS.reservoir_corner_hz},
                                     across=({"reservoir_corner_hz": _EXTRAS.reservoir_corner_hz / 2.5},
                                             {"reservoir_corner_hz": _EXTRAS.reservoir_corner_hz * 2.5})),
}
#: extensions for what every vehicle has (:attr:`.extensions.Extension.always_normal`) name no
#: cause, so "no effect above these sizes" has no size of theirs to give
_missing = [n for n, e in EXTENSIONS.items()
            if e.kind == "response" and not e.always_normal and n not in RESPONSE_MAGNITUDES]
if _missing:
    raise ImportError(f"detectability.RESPONSE_MAGNITUDES lacks the response extension(s) {', '.join(_missing)}")


class _Responses:
    """The baseline's held-out residual and the linearised refit, formed once."""

    def __init__(self, data: DiagnosisData, base: ResponseFit, baseline: ResponseFit | None = None):
        stats, lay = data.stats, data.layout
        self.data, self.base = data, base
        self.what = "baseline" if baseline is None else "model with the properties found"
        self.f, self.bw = stats.centres, np.diff(stats.edges)
        n_out = len(lay.responses)
        self.n_out = n_out
        test, all_keys = data.keys(data.test), set(stats.S)
        S_tr, _ = stats.total(lambda k: k in data.keys(data.train))
        self.S_te, _ = stats.total(lambda k: k in test)
        self.S_all, _ = stats.total()
        self.R0, self.P = response_nrp(stats, lay, test, base, by_band=True)
        self.R_all, _ = response_nrp(stats, lay, all_keys, base, by_band=True)
        self.coherence = input_coherence(stats, lay, all_keys, base)
        # the decision judges every step on the bands its baseline's residual gives (ev.masks)
        mask_fit = base if baseline is None else baseline
        self.eiv = input_noise_power(stats, lay, all_keys, mask_fit)
        self.R_mask = self.R_all if baseline is None else response_nrp(stats, lay, all_keys, baseline, by_band=True)[0]
        self.nu = np.maximum(self.bw * stats.seconds_of(test), 1.0)[:, None]  # held-out averages per band
        self.G0 = self._G(base.extras, base.sensors)
        norm = 1.0 / np.maximum(channel_power(S_tr, 4, n_out).sum(axis=0), 1e-300)
        h = 1e-4  # the baseline's sensitivities per relative change of each fitted parameter
        D = [(self._G(base.extras, base.sensors, base.parameters.replace(
            **{n: getattr(base.parameters, n) * (1 + h)})) - self.G0) / h for n in FIT_NAMES]
        self.D = np.stack(D)  # (n_param, n_band, n_out, 4)
        self.w = np.sqrt(norm)[None, None, :, None]
        self.Suu_tr = S_tr[:, :4, :4]
        A = np.einsum("pkcj,kjl,qkcl->pq", self.D * self.w, self.Suu_tr, (self.D * self.w).conj()).real
        self.A = A + 1e-9 * np.trace(A) / len(A) * np.eye(len(A))

    def _G(self, extras, sensors, p=None):
        return transfer(self.base.parameters if p is None else p, extras, sensors, self.data.layout, self.f)

    def with_effect(self, ext, values: dict) -> tuple[CarExtras, SensorModel]:
        """The fit's extras and sensors with the effect of extension ``ext`` at ``values`` in
        place of its own: every car addition ``values`` names (a bending at the limit's
        frequency and held shape in place of the one found, the fit's node kept), a bogie
        sensor's offset, a floor sensor's offset (the others, and every gain, the fit's)."""
        ex, se = ext.make(values)
        own = {f.name for f in fields(CarExtras)}
        extras = replace(self.base.extras, **{k: getattr(ex, k) for k in values if k in own})
        sensors = self.base.sensors
        if "dx" in values:
            sensors = replace(sensors, dx=se.dx)
        moved = {n: dx for n, dx, _ in se.floor if f"dx:{n}" in values}
        if moved:
            floor = {n: (dx, g) for n, dx, g in sensors.floor}
            floor.update({n: (dx, floor.get(n, (0.0, 1.0))[1]) for n, dx in moved.items()})
            sensors = replace(sensors, floor=tuple((n, dx, g) for n, (dx, g) in sorted(floor.items())))
        return extras, sensors

    def judge(self, extras: CarExtras, sensors: SensorModel) -> tuple[float, float]:
        """(gain less Z sigma on the best channel with a model error, 0 when no channel would
        have one; the largest effect over Z sigma among the channels) if the data carried
        the model with ``extras`` / ``sensors`` (:meth:`with_effect`) instead of the fit's."""
        s = self.data.settings
        dG = self._G(extras, sensors) - self.G0
        rhs = np.einsum("pkcj,kjl,kcl->p", self.D * self.w, self.Suu_tr, (dG * self.w[0]).conj()).real
        left = dG - np.einsum("p,pkcj->kcj", np.linalg.solve(self.A, rhs), self.D)
        dP = np.einsum("kcj,kjl,kcl->kc", left, self.S_te[:, :4, :4], left.conj()).real
        dP_all = np.einsum("kcj,kjl,kcl->kc", left, self.S_all[:, :4, :4], left.conj()).real
        # the signal bands the decision would judge on: the held-out channels' power with the effect
        Syu = self.S_te[:, 4:4 + self.n_out, :4]
        P = self.P + np.einsum("kcj,kjl,kcl->kc", dG, self.S_te[:, :4, :4], dG.conj()).real \
            + 2 * np.einsum("kcj,kcj->kc", dG, Syu.conj()).real
        masks = signal_bands(np.maximum(P, 0.0), self.bw, s.signal_factor) \
            & (self.eiv < s.input_noise_share * (self.R_mask + dP_all))
        before = np.sum(np.where(masks, self.R0 + dP, 0.0), axis=0)
        added = np.sum(np.where(masks, dP, 0.0), axis=0)
        sigma = np.sqrt(np.sum(np.where(masks, 2 * dP * self.R0 / self.nu, 0.0), axis=0))
        ok = before > 0
        gain = np.where(ok, added / np.where(ok, before, 1.0), 0.0)
        zs = np.where(ok, Z * sigma / np.where(ok, before, 1.0), 0.0)
        signif = added / np.maximum(Z * sigma, 1e-300)
        # the systematic share each channel would have: the fit's (its held-out error x input
        # coherence over these bands) plus the effect's addition, all of it coherent
        coh = np.sum(np.where(masks, self.coherence * self.R_all, 0.0), axis=0) \
            / np.maximum(np.sum(np.where(masks, self.R_all, 0.0), axis=0), 1e-300)
        power = np.sum(np.where(masks, np.maximum(P, 0.0), 0.0), axis=0)
        share = (coh * np.sum(np.where(masks, self.R0, 0.0), axis=0) + added) / np.maximum(power, 1e-300)
        error = ok & (share >= s.systematic_floor)
        margin = float(np.max(np.where(error, gain - zs, -np.inf))) if error.any() else 0.0
        return margin, float(np.max(signif))


def _carbody_words(data: DiagnosisData) -> str:
    if data.layout.carbody_sensed:
        return "its predicted change on every channel of this campaign stays within the data's scatter"
    return ("it changes the bogie channels by less than the data's scatter; carbody floor accelerometers "
            "(above the bogies and at the centre) would see it")


def _response_limit(name: str, ext, r: _Responses, bar: float) -> Limit:
    mag = RESPONSE_MAGNITUDES[name]
    per_sensor = EXTENSIONS[name].per_sensor is not None

    def judge_at(held: dict, parameter: str):
        def judge(theta: float) -> tuple[float, float]:
            out = [r.judge(*r.with_effect(ext, {**held, parameter: sgn * theta}))
                   for sgn in ((1.0, -1.0) if mag.signed else (1.0,))]
            return min(o[0] for o in out), min(o[1] for o in out)
        return judge

    if per_sensor:  # the magnitude of one sensor at a time
        each_sensor = [p.name for p in ext.params if p.name.startswith(f"{mag.parameter}:")]
        variants, names = tuple({} for _ in each_sensor), each_sensor
    else:
        variants, names = (mag.held, *mag.across), [mag.parameter] * (1 + len(mag.across))
    found = [search(mag, judge_at(v, n), bar) for v, n in zip(variants, names)]
    k = weakest(mag, found)
    limit, strong, observable = found[k]
    stronger = "above" if mag.strong > mag.weak else "below"
    held = ", ".join(f"{key} = {v:g}" for key, v in variants[k].items())
    tail = ""
    if per_sensor:
        each = "; ".join(f"{n.split(':', 1)[1]}: {'not detectable' if x[0] is None else f'{x[0]:.3g}'}"
                         for n, x in zip(names, found))
        held = f" (one sensor off, the others in place; the weakest of {each})"
    elif len(variants) > 1:  # the limit at each held value, the weakest taken
        each = "; ".join(f"{', '.join(f'{v:g}' for v in var.values())}: "
                         f"{'not detectable' if x[0] is None else f'{x[0]:.3g}'}" for var, x in zip(variants, found))
        tail = f"; the weakest of {', '.join(mag.held)} = {each}"
    if not per_sensor:
        held = f" ({held} held{tail})" if held else ""
    rng = f"{min(mag.weak, mag.strong):g}-{max(mag.weak, mag.strong):g} {mag.unit}"
    if not observable:
        why = f"not observable with this sensor set: even at {mag.strong:g} {mag.unit}{held} {_carbody_words(r.data)}" \
            if name != "sensor_offset" else f"even at {mag.strong:g} {mag.unit} it changes no channel beyond the scatter"
    elif limit is None:
        why = (f"not detectable within its range {rng}{held}: at {mag.strong:g} {mag.unit} the predicted held-out "
               f"gain less its scatter, on a channel it would leave with a model error (a systematic residual of "
               f"{r.data.settings.systematic_floor:.0%} of its power or more), is {strong:.0%}, under the bar of "
               f"{bar:.0%}")
        if name in CARBODY_EFFECTS and not r.data.layout.carbody_sensed:
            return Limit(name, mag.parameter, mag.unit, None, True, f"{why}; {_carbody_words(r.data)}", stronger,
                         needs="carbody sensors")
    else:
        side = "and above" if stronger == "above" else "and below"
        what = f"|{mag.parameter}|" if mag.signed else mag.parameter
        why = (f"{what} {limit:.3g} {mag.unit} {side}{held} would gain {bar:.0%} on held-out data, on a channel "
               f"it leaves with a model error, after a refit of the {r.what} absorbs what it can")
    return Limit(name, mag.parameter, mag.unit, limit if observable else None, observable, why, stronger,
                 signed=mag.signed)


def _wheel_limit(data: DiagnosisData, bar: float) -> Limit:
    s = data.settings.wheels
    floor = polygon_error(data.records, data.rows, data.test, None, s)
    n = int(round(s.segment_m / s.step_m))
    segments = sum(int((r.distance[-1] - r.distance[0]) // s.segment_m) for r in data.records if r.run_id in data.test)
    lam = s.wavelengths_m[1]  # the longest wavelength searched: the smallest curvature per unit radius
    # line mean square dE = a^2/2 against the floor E0: gain dE / (E0 + dE), its scatter the
    # line's cross term with the white floor in its bin, sqrt(2 dE E0 / (n/2) / segments)
    per_bin = floor / (n / 2) / max(segments, 1)
    dE, k = bar / (1 - bar) * floor, 0.0
    for _ in range(50):  # dE = bar (E0 + dE) + Z sqrt(2 dE per_bin): a fixed point, contracting
        k = (bar * floor + Z * np.sqrt(2 * dE * per_bin)) / (1 - bar)
        if abs(k - dE) <= 1e-9 * k:
            break
        dE = k
    radius = float(np.sqrt(2 * dE) * (lam / (2 * np.pi)) ** 2)
    why = (f"radius amplitude {radius:.3g} m and above at wavelength {lam:g} m (the longest searched); at "
           f"wavelength L the limit is (L / {lam:g} m)^2 times this, its curvature line then carrying {bar:.0%} "
           "of the consistency channel's held-out mean square")
    return Limit("wheel_out_of_round", "radius_amplitude", "m", radius, True, why, "above")


def _track_limit(data: DiagnosisData, base: ResponseFit, bar: float) -> Limit:
    s = data.settings.track
    m_t, zeta = _EXTRAS.track_mass, _EXTRAS.track_damping_ratio
    k_of = lambda f_t: float((2 * np.pi * f_t) ** 2 * m_t)  # noqa: E731
    mag = Magnitude("track_stiffness", "N/m", k_of(s.f_t_range[1]), k_of(s.f_t_range[0]))
    got = collapse_shift(data.stats, set(data.stats.S), s, vehicle=base.parameters)
    if got is None:
        return Limit("track_flexibility", mag.parameter, mag.unit, None, False,
                     "all data lie in one speed bin: a track resonance shows only across speeds", "below")
    floor, shift = got
    floor = np.maximum(floor, 0.0)

    def judge(k: float) -> tuple[float, float]:
        up, sd = shift(float(np.sqrt(k / m_t) / (2 * np.pi)), zeta, m_t)
        before = floor + np.maximum(up, 0.0)
        g = np.where(before > 0, (np.maximum(up, 0.0) - Z * sd) / np.maximum(before, 1e-300), 0.0)
        c = int(np.argmax(g))
        return float(g[c]), float(up[c] / max(Z * sd[c], 1e-300))

    limit, strong, observable = search(mag, judge, bar)
    held = f"damping ratio {zeta:g}, track mass {m_t:.0f} kg per wheelset"
    if limit is None:
        why = (f"not detectable within its range {mag.strong:.3g}-{mag.weak:.3g} N/m (the track's own frequency "
               f"{s.f_t_range[0]:g}-{s.f_t_range[1]:g} Hz; {held}): the axle boxes' collapse over this campaign's "
               "speeds would not change enough")
    else:
        why = (f"track stiffness {limit:.3g} N/m and below (the track's own frequency "
               f"{np.sqrt(limit / m_t) / (2 * np.pi):.0f} Hz; {held}) would gain {bar:.0%} on the axle boxes' "
               "collapse held out by speed")
    return Limit("track_flexibility", mag.parameter, mag.unit, limit, observable or limit is not None, why, "below")


def with_track_fit(detect: Detectability, h, settings) -> Detectability:
    """``detect`` with the track's limit from the track hypothesis ``h`` when that gains
    enough: the data then carry a track resonance (a normal track's too), and whether a
    soft track is named hangs on its fitted stiffness against the catalogue's line, not on
    a gain over the rigid rail (whose misfit holds that normal track's own, so the limit
    of :func:`_track_limit` falls to a few MN/m on some clean campaigns). A track found
    here would be named at moderate confidence when its highest fold stays under the line,
    which the model's form may overstate it by :attr:`.extensions.Extension.form_allowance`:
    the line over the folds' upward spread and that allowance."""
    if h is None or not h.parameter_ranges or not h.gains_enough(settings):
        return detect
    ext = EXTENSIONS["track_flexibility"]
    line = ext.normal_above[1]
    k = h.parameters["track_stiffness_n_per_m"]
    hi = h.parameter_ranges["track_stiffness_n_per_m"][1]
    limit = line * k / hi / (1.0 + ext.form_allowance)
    why = (f"track stiffness {limit:.3g} N/m and below: the track found here, {k:.3g} N/m, reaches {hi:.3g} N/m "
           f"over the speed folds, and the one-mass track may overstate a layered one's by "
           f"{ext.form_allowance:.0%}; a track softer by both than the catalogue's line ({line:.3g} N/m) would be "
           "named")
    return Detectability(tuple(replace(x, detectable_beyond=limit, observable=True, why=why)
                               if x.name == "track_flexibility" else x for x in detect.limits))


def detectability(data: DiagnosisData, base: ResponseFit, vehicle: ResponseFit | None = None) -> Detectability:
    """Each extension's detectable limit on this campaign, from the baseline fit ``base``
    and the measured held-out residuals (see the module's description); the response
    extensions' on ``vehicle`` (the model the diagnosis ends with) when given."""
    s = data.settings
    r = None
    limits = []
    for name, ext in EXTENSIONS.items():
        if ext.always_normal:
            continue
        ext = ext.on(data.layout)
        if ext is None:  # an extension of the campaign's floor sensors, and it has none
            mag = RESPONSE_MAGNITUDES[name]
            limits.append(Limit(name, mag.parameter, mag.unit, None, False, "this campaign has no sensor it acts on",
                                "above", needs="carbody floor accelerometers"))
            continue
        bar = s.bar(ext.n_params)
        if ext.kind == "response":
            r = r or (_Responses(data, base) if vehicle is None else _Responses(data, vehicle, baseline=base))
            limits.append(_response_limit(name, ext, r, bar))
        elif ext.kind == "wheel":
            limits.append(_wheel_limit(data, bar))
        else:
            limits.append(_track_limit(data, base, bar))
    return Detectability(tuple(limits))
