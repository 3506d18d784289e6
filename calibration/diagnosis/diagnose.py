"""``railcal diagnose``: what the calibrated 2D car gets wrong on an in-service campaign,
the cause, the extended model and the gain.

1. **Data.** Gap-free records of rail input (axle boxes), responses (bogie and carbody
   sensors) and the axle-box consistency channel (:mod:`.records`); runs split into
   training (odd) and held-out (even) runs; a single run is split in halves.
2. **Baseline.** The seed's car, its masses, inertias, stiffnesses and dampings fitted to
   the training runs by residual energy (:mod:`.response`), within the campaign's priors.
3. **Evidence** from the baseline's residuals: per channel the held-out normalised
   residual power (NRP), the residual's coherence with the rail input (systematic model
   error), residual PSD peaks over a running-median floor and whether each is fixed in
   frequency or proportional to speed (then its wavelength), the residuals' spectral
   flatness, parameters at their bounds; a wheel-fixed line in the consistency channel
   and which wheelset carries it (:mod:`.wheels`); how well the axle boxes' spectra
   collapse over speed (:mod:`.track`).
4. **Hypotheses.** Every extension of :data:`.extensions.EXTENSIONS` is scored by the
   evidence that speaks for it and ranked; the leading ones are fitted on the training
   runs (global start, then joint refinement with the baseline) and judged by the
   held-out error of the channels they change: *gain* = relative reduction of that
   error on the channel where it is largest, less ``penalty`` per extension parameter.
5. **Decision.** The best hypothesis whose penalised gain exceeds ``min_gain``, that
   makes no held-out channel worse by more than ``max_loss`` of its error (unless that
   worsening is under ``max_loss`` of what the hypothesis gains on its best channel, in
   the same units: a channel explained to within a per cent of its signal that loses a
   tenth of a per cent does not outweigh a carbody channel's error cut by nine tenths)
   and, for a response
   extension, that explains the systematic residual on the channel it gains on (held-out
   error times the residual's coherence with the rail input falls to ``max_systematic_left``
   of the baseline's or below: an extension that only rescales what it cannot model, e.g.
   a gyro gain against a bogie resonance, leaves the residual as coherent as before) is
   the cause. Otherwise
   ``none`` when the evidence shows nothing systematic (residual input-coherence, peaks
   and lines all below their thresholds), or ``unexplained`` with the evidence.

Held-out error per channel kind: response channels, NRP over the bands where the
measured channel stands 4x above its own spectral floor (noise-only bands excluded, the
same bands before and after); consistency, its mean square after the wheel line is
removed; axle boxes, the mean squared log10 misfit of the spectra's collapse over speed
less their sampling variance, held out *by speed* (low, middle and high speed bins, each
predicted from the other two, :func:`.track.speed_folds`: a track resonance is a claim
about other speeds, which held-out runs at the training runs' speeds cannot test).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.ndimage

from ..data.campaign import Campaign
from ..data.errors import CampaignError
from ..identification.in_service import prior_parameters
from ..models.car2d import CarExtras
from ..progress import counter
from .extensions import EXTENSIONS, Extension
from .records import Layout, RecordSettings, Statistics, layout, read_records, statistics
from .response import (FIT_NAMES, fit_response, input_coherence, input_noise_power, residual_cross_spectrum,
                       response_nrp, transfer)
from .track import TrackSettings, fit_track, speed_folds, track_cross_validation, track_error
from .threads import one_blas_thread
from .wheels import WheelSettings, fit_polygon, line_spectrum, polygon_error

FORMAT = "railcal-diagnosis/1"
#: a residual PSD peak is systematic when it carries more than this share of the measured power
PEAK_SHARE = 0.3


@dataclass(frozen=True)
class DiagnoseSettings:
    records: RecordSettings = field(default_factory=RecordSettings)
    wheels: WheelSettings = field(default_factory=WheelSettings)
    track: TrackSettings = field(default_factory=TrackSettings)
    min_gain: float = 0.15  # penalised held-out error reduction for a cause
    penalty: float = 0.01  # per extension parameter
    max_loss: float = 0.05  # largest held-out worsening of any channel (relative, and against the gain)
    # a response extension must explain the systematic residual it gains on: on its best
    # channel, held-out error x residual input-coherence, after / before, at most this
    max_systematic_left: float = 0.25
    coherence_alarm: float = 0.35  # residual input-coherence (mean over signal bands) that is systematic
    peak_alarm: float = 4.0  # residual PSD peak over its floor
    line_alarm: float = 30.0  # wheel-line power over floor (with one-sided wheelset asymmetry)
    asymmetry: float = 2.0  # line power ratio between the two axle boxes of a wheel line
    fit_leading: int = 6  # hypotheses fitted, best evidence first
    starts: int = 6
    signal_factor: float = 4.0
    input_noise_share: float = 0.3  # bands where input noise makes more of the residual are not evidence
    prior_spread: float = 3.0  # search factor around nominal for parameters without priors


# ---------------------------------------------------------------------------- helpers
def _split_runs(runs: tuple[str, ...]) -> tuple[set, set]:
    return set(runs[0::2]), set(runs[1::2])


def _keys(stats: Statistics, runs) -> set:
    return {k for k in stats.S if k[0] in runs}


def _signal_bands(P: np.ndarray, bw: np.ndarray, factor: float) -> np.ndarray:
    """Bands where the measured PSD stands ``factor`` above the channel's floor (the 5th
    percentile of its PSD over the band), per channel: (n_band, n_out) booleans."""
    psd = P / bw[:, None]
    floor = np.percentile(psd, 5, axis=0)
    return psd > factor * floor[None, :]


def _peaks(f, ratio, weight, band, alarm):
    """Local maxima of ``ratio`` (residual over floor) above ``alarm`` inside ``band``."""
    out = []
    for i in range(1, f.size - 1):
        if band[0] <= f[i] <= band[1] and ratio[i] >= alarm and ratio[i] >= ratio[i - 1] and ratio[i] >= ratio[i + 1] \
                and weight[i] > 0.05:
            out.append((float(f[i]), float(ratio[i]), float(weight[i])))
    kept = []
    for p in sorted(out, key=lambda x: -x[1]):  # one peak per 5 % of frequency
        if all(abs(p[0] / q[0] - 1) > 0.05 for q in kept):
            kept.append(p)
    return kept[:3]


def _floor(x: np.ndarray, width: int = 41) -> np.ndarray:
    return scipy.ndimage.median_filter(x, size=width, mode="nearest")


@dataclass
class _Context:
    campaign: Campaign
    lay: Layout
    records: list
    rows: dict
    stats: Statistics
    train: set
    test: set
    base: object
    bounds: dict
    settings: DiagnoseSettings


# ----------------------------------------------------------------------------- steps
def _baseline(ctx: _Context):
    return fit_response(ctx.stats, ctx.lay, _keys(ctx.stats, ctx.train), ctx.base, ctx.bounds)


def _response_errors(ctx: _Context, fit, masks) -> np.ndarray:
    R, P = response_nrp(ctx.stats, ctx.lay, _keys(ctx.stats, ctx.test), fit.parameters, fit.extras, fit.sensors,
                        by_band=True)
    return np.array([R[masks[:, c], c].sum() / max(P[masks[:, c], c].sum(), 1e-300) for c in range(R.shape[1])])


def _speed_scaling(ctx: _Context, fit, c: int, f0: float) -> dict:
    """Is the residual peak at f0 fixed in frequency or proportional to speed? Compare the
    residual-over-floor at f0 and at f0 v / v_mean in each speed bin."""
    bins = ctx.stats.speed_bins
    if len(bins) < 2:
        return {"scaling": "unknown", "reason": "one speed bin only"}
    vw = ctx.settings.records.speed_bin
    vs, fixed, scaled, weights = [], [], [], []
    for vb in bins:
        keys = {k for k in ctx.stats.S if k[1] == vb}
        R, P = response_nrp(ctx.stats, ctx.lay, keys, fit.parameters, fit.extras, fit.sensors, by_band=True)
        bw = np.diff(ctx.stats.edges)
        r = R[:, c] / bw
        ratio = r / np.maximum(_floor(r), 1e-300)
        vs.append(vb + vw / 2)
        fixed.append(ratio)
        weights.append(sum(ctx.stats.seconds[k] for k in keys))
        scaled.append(None)
    vs = np.array(vs)
    v_mean = float(np.average(vs, weights=weights))
    f = ctx.stats.centres
    at_fixed = [np.interp(f0, f, r) for r in fixed]
    at_scaled = [np.interp(f0 * v / v_mean, f, r) for r, v in zip(fixed, vs)]
    a, b = float(np.average(at_fixed, weights=weights)), float(np.average(at_scaled, weights=weights))
    spread = float(vs.max() / vs.min())
    if spread < 1.15:
        return {"scaling": "unknown", "reason": f"speeds span only {vs.min():.1f}-{vs.max():.1f} m/s",
                "fixed_ratio": a, "scaled_ratio": b}
    if b > 1.3 * a:
        return {"scaling": "speed_proportional", "wavelength_m": v_mean / f0, "fixed_ratio": a, "scaled_ratio": b}
    if a > 1.3 * b:
        return {"scaling": "fixed_frequency", "fixed_ratio": a, "scaled_ratio": b}
    return {"scaling": "ambiguous", "fixed_ratio": a, "scaled_ratio": b}


def _channel_evidence(ctx: _Context, fit, masks=None) -> tuple[dict, np.ndarray]:
    """Per response channel, what the residuals of ``fit`` (a response fit) show: held-out
    NRP, coherence with the rail input, PSD peaks over the floor (speed scaling, phase
    between the car ends), flatness; and the signal-band masks (``masks``: given ones, e.g.
    the baseline's, so that a fit is judged on the same bands)."""
    s, lay = ctx.settings, ctx.lay
    bw = np.diff(ctx.stats.edges)
    f = ctx.stats.centres
    all_keys = set(ctx.stats.S)
    R, P = response_nrp(ctx.stats, lay, all_keys, fit.parameters, fit.extras, fit.sensors,
                        by_band=True)
    _, Ptest = response_nrp(ctx.stats, lay, _keys(ctx.stats, ctx.test), fit.parameters, fit.extras,
                            fit.sensors, by_band=True)
    eiv = input_noise_power(ctx.stats, lay, all_keys, fit.parameters, fit.extras, fit.sensors)
    clean = eiv < s.input_noise_share * R  # bands where the rail input's own noise does not dominate
    if masks is None:
        masks = _signal_bands(Ptest, bw, s.signal_factor) & clean
    coh = input_coherence(ctx.stats, lay, all_keys, fit.parameters, fit.extras, fit.sensors)
    nrp_test = _response_errors(ctx, fit, masks)
    S_all, _ = ctx.stats.total()
    G = transfer(fit.parameters, fit.extras, fit.sensors, lay, f)
    Rx = residual_cross_spectrum(G, S_all, 4, len(lay.responses))
    pairs = {}  # residual phase between the ends of the car: bogie-end carbody sensors (front, rear)
    ends = [c for c, o in enumerate(lay.responses) if o.body == "carbody" and o.kind == "acceleration"]
    if len(ends) >= 2:
        xs = [lay.responses[c].x for c in ends]
        front, rear = ends[int(np.argmax(xs))], ends[int(np.argmin(xs))]
        pairs = {"front": lay.response_names[front], "rear": lay.response_names[rear], "i": front, "j": rear}
    channels = {}
    for c, name in enumerate(lay.response_names):
        m = masks[:, c]
        rpsd = R[:, c] / bw
        ratio = np.where(clean[:, c], rpsd / np.maximum(_floor(rpsd), 1e-300), 0.0)
        share = R[:, c] / np.maximum(P[:, c], 1e-300)
        peaks = []
        for f0, rr, sh in _peaks(f, ratio, share, (0.5, 40.0), s.peak_alarm):
            peak = {"frequency_hz": f0, "over_floor": rr, "residual_share": sh, **_speed_scaling(ctx, fit, c, f0)}
            if pairs:
                k = int(np.argmin(np.abs(f - f0)))
                x = Rx[k, pairs["i"], pairs["j"]]
                peak["front_rear_residual"] = {
                    "phase_deg": float(np.degrees(np.angle(x))),
                    "coherence": float(abs(x) ** 2 / max(Rx[k, pairs["i"], pairs["i"]].real
                                                          * Rx[k, pairs["j"], pairs["j"]].real, 1e-300))}
            peaks.append(peak)
        flat = rpsd[m] if m.any() else rpsd
        channels[name] = {
            "heldout_nrp": float(nrp_test[c]),
            "input_coherence": float(np.average(coh[m, c], weights=R[m, c])) if m.any() else 0.0,
            "peaks": peaks,
            "spectral_flatness": float(np.exp(np.mean(np.log(flat))) / np.mean(flat)),
            "signal_bands_hz": [float(f[m].min()), float(f[m].max())] if m.any() else None,
            "low_band_coherence": float(np.average(coh[(f < 3) & m, c], weights=R[(f < 3) & m, c]))
            if ((f < 3) & m).any() else 0.0,
        }
    return channels, masks


def _evidence(ctx: _Context, base_fit) -> dict:
    s = ctx.settings
    channels, masks = _channel_evidence(ctx, base_fit)
    spec = line_spectrum(ctx.records, ctx.rows, set(ctx.campaign.run_ids), s.wheels)
    i, line_ratio = spec.strongest(s.wheels)
    a1, a2 = spec.axle1[i], spec.axle2[i]
    asym = float(max(a1, a2) / max(min(a1, a2), 1e-300))
    wheel = {"wavelength_m": float(1 / spec.wavenumber[i]), "over_floor": line_ratio, "axle_asymmetry": asym,
             "stronger_on_wheelset": 1 if a1 >= a2 else 2}
    # the rigid rail's collapse: fitted at some speeds, how well does it predict the others?
    # (misfits less the spectra's sampling variance, so the two are comparable)
    fitted, held = [], []
    for fit_keys, test_keys in speed_folds(ctx.stats, set(ctx.stats.S)):
        tb = fit_track(ctx.stats, fit_keys, False, s.track)
        fitted.append(float(np.mean(track_error(ctx.stats, fit_keys, tb, s.track))))
        held.append(track_error(ctx.stats, test_keys, tb, s.track))
    track = {"collapse_misfit_fitted_speeds": float(np.mean(fitted)) if fitted else None,
             "collapse_misfit_other_speeds": np.mean(held, axis=0).tolist() if held else None,
             "speeds_m_s": [min(ctx.stats.speed_bins), max(ctx.stats.speed_bins) + s.records.speed_bin]}
    return {"channels": channels, "wheel_line": wheel, "track": track, "masks": masks,
            "parameters_at_bounds": list(base_fit.at_bounds)}


def _scores(ev: dict, lay: Layout, s: DiagnoseSettings) -> dict:
    """Evidence for each hypothesis, 0 (none) upwards; used to rank them."""
    ch = ev["channels"]
    bogie = [n for n, o in zip(lay.response_names, lay.responses) if o.body.startswith("bogie")]
    carbody = [n for n, o in zip(lay.response_names, lay.responses) if o.body == "carbody"]
    coh = {n: ch[n]["input_coherence"] for n in ch}
    peaks = {n: ch[n]["peaks"] for n in ch}
    fixed_mid = max([p["over_floor"] for n in carbody for p in peaks[n]
                     if 4 <= p["frequency_hz"] <= 18 and p.get("scaling") != "speed_proportional"] + [0.0])
    at_bounds = set(ev["parameters_at_bounds"])
    w = ev["wheel_line"]
    sc = {
        "sensor_offset": max([coh[n] for n in bogie] + [0.0]),
        "carbody_bending": fixed_mid / s.peak_alarm,
        "cog_offset": max([ch[n]["low_band_coherence"] for n in carbody] + [0.0]),
        "airspring_reservoir": max([coh[n] for n in carbody] + [0.0]) + 0.5 * bool(at_bounds & {"k_s", "c_s"}),
        "wheel_out_of_round": (w["over_floor"] / s.line_alarm) * (w["axle_asymmetry"] >= s.asymmetry),
        "track_flexibility": (max(ev["track"]["collapse_misfit_other_speeds"])
                              / max(ev["track"]["collapse_misfit_fitted_speeds"], 1e-12) - 1.0)
        if ev["track"]["collapse_misfit_fitted_speeds"] else 0.0,
    }
    return {k: float(max(v, 0.0)) for k, v in sc.items()}


def _fit_hypothesis(ctx: _Context, ext: Extension, base_fit, ev) -> dict:
    s = ctx.settings
    masks = ev["masks"]
    if ext.kind == "response":
        fit = fit_response(ctx.stats, ctx.lay, _keys(ctx.stats, ctx.train), base_fit.parameters, ctx.bounds,
                           ext.params, ext.make, starts=s.starts)
        before = _response_errors(ctx, base_fit, masks)
        after = _response_errors(ctx, fit, masks)
        names = ctx.lay.response_names
        params = fit.values
        model = {"parameters": fit.parameters.as_dict(), "extras": _extras_json(fit.extras),
                 "sensors": {"dx_m": fit.sensors.dx, "gyro_gain": fit.sensors.gyro_gain}}
        at = [n for n in fit.at_bounds if n in params]
        left, _ = _channel_evidence(ctx, fit, masks)
        residual = {n: {"before": _systematic(ev["channels"][n]), "after": _systematic(left[n])} for n in names}
    elif ext.kind == "wheel":
        poly = fit_polygon(ctx.records, ctx.rows, ctx.train, s.wheels)
        before = np.array([polygon_error(ctx.records, ctx.rows, ctx.test, None, s.wheels)])
        after = np.array([polygon_error(ctx.records, ctx.rows, ctx.test, poly, s.wheels)])
        names = ("consistency",)
        params = poly.to_json()
        model = {"wheel_polygon": params}
        at = []
        residual = None
    else:
        # held out by speed (the model's claim is about speeds it was not fitted at; held-out
        # runs at the training runs' speeds cannot tell): low, middle, high speeds, each from the others
        tf = fit_track(ctx.stats, set(ctx.stats.S), True, s.track)
        before, after = track_cross_validation(ctx.stats, set(ctx.stats.S), s.track)
        if before.size < 2:  # one speed bin: held-out runs instead
            tb = fit_track(ctx.stats, _keys(ctx.stats, ctx.train), False, s.track)
            tf = fit_track(ctx.stats, _keys(ctx.stats, ctx.train), True, s.track)
            before = track_error(ctx.stats, _keys(ctx.stats, ctx.test), tb, s.track)
            after = track_error(ctx.stats, _keys(ctx.stats, ctx.test), tf, s.track)
        names = ("axle1_mean", "axle2_mean")
        m_eff = base_fit.parameters.m_w + CarExtras().track_mass
        params = {**tf.to_json(), "track_stiffness_n_per_m": float((2 * np.pi * tf.f_t) ** 2 * m_eff),
                  "assumed_moving_mass_kg": m_eff}
        model = {"extras": {"track_stiffness": params["track_stiffness_n_per_m"],
                            "track_damping_ratio": tf.zeta}}
        at = [n for n, v, (lo, hi) in (("track_resonance_hz", tf.f_t, s.track.f_t_range),
                                       ("damping_ratio", tf.zeta, s.track.zeta_range))
              if min(abs(np.log(v / lo)), abs(np.log(hi / v))) < 0.01 * np.log(hi / lo)]
        residual = None
    red = reductions(before, after)
    seen = ~np.isnan(red)
    best = int(np.nanargmax(red)) if seen.any() else 0
    gain = float(red[best]) if seen.any() else 0.0
    left = None
    if residual is not None and seen.any():  # the systematic residual left on the best channel
        r = residual[names[best]]
        left = (1.0 - gain) * r["after"]["input_coherence"] / max(r["before"]["input_coherence"], 1e-12)
    return {"name": ext.name, "kind": ext.kind, "description": ext.description, "parameters": params,
            "parameters_at_bounds": at, "model": model, "n_params": ext.n_params,
            "heldout_error": {n: {"before": float(b), "after": float(a), "reduction": float(r) if ok else None}
                              for n, b, a, r, ok in zip(names, before, after, red, seen)},
            "residual": residual, "systematic_left": left, "best_channel": names[best], "gain": gain,
            "worst_change": float(np.nanmin(red)) if seen.any() else 0.0,
            "losses": _losses(names, before, after, best, s.max_loss),
            "penalised_gain": gain - s.penalty * ext.n_params}


def _losses(names, before, after, best: int, max_loss: float) -> list[str]:
    """Channels a hypothesis makes worse on held-out data: error up by more than
    ``max_loss`` of its own and by more than ``max_loss`` of the error the hypothesis
    removes on its best channel (a hypothesis's channels share one unit: NRP for response
    channels, log misfit for the axle boxes). Seed 1825 (CoG 0.96 m off): the fit cut the
    carbody centre's error from 0.72 to 0.07 while the pitch gyro's rose from 0.0088 to
    0.0099; by the relative rule alone that 12 % loss left the cause unnamed."""
    before, after = np.asarray(before, float), np.asarray(after, float)
    removed = max(before[best] - after[best], 0.0)
    return [n for n, b, a in zip(names, before, after)
            if b > 0 and a - b > max_loss * b and a - b > max_loss * removed]


def _leaves_systematic(h: dict, s: DiagnoseSettings) -> bool:
    """Does response extension ``h`` leave more of the systematic residual on its best
    channel than ``max_systematic_left``, i.e. not explain it? (False for other kinds.)"""
    return h["systematic_left"] is not None and h["systematic_left"] > s.max_systematic_left


def _systematic(channel: dict) -> dict:
    """What is systematic in one channel's residual: its coherence with the rail input and
    its strongest PSD peak over the floor among those carrying > PEAK_SHARE of the measured power."""
    peaks = [p["over_floor"] for p in channel["peaks"] if p["residual_share"] > PEAK_SHARE]
    return {"input_coherence": channel["input_coherence"], "peak_over_floor": max(peaks, default=0.0)}


def reductions(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """Relative held-out error reduction per channel, 1 - after / before; NaN where the
    channel has no held-out error to reduce (no signal band of it survived the masks: 0 / 0
    would read as a 100 % gain on a channel that says nothing)."""
    before, after = np.asarray(before, float), np.asarray(after, float)
    ok = before > 0
    return np.where(ok, 1.0 - after / np.where(ok, before, 1.0), np.nan)


def _extras_json(ex: CarExtras) -> dict:
    d = {k: getattr(ex, k) for k in ("cog_offset", "bending_hz", "bending_damping", "bending_mass_ratio",
                                     "reservoir_ratio", "reservoir_corner_hz")}
    return {k: v for k, v in d.items() if v not in (None, 0.0) or k in ("cog_offset",)}


def _alarms(ev: dict, s: DiagnoseSettings) -> list[str]:
    """What in the evidence is systematic (the baseline does not explain the data within
    the noise), in words."""
    out = []
    for name, c in ev["channels"].items():
        if c["input_coherence"] >= s.coherence_alarm:
            out.append(f"{name}: residual coherent with the rail input ({c['input_coherence']:.2f}), "
                       "a systematic model error")
        for p in c["peaks"]:
            if p["over_floor"] >= s.peak_alarm and p["residual_share"] > PEAK_SHARE:
                kind = p.get("scaling", "unknown").replace("_", " ")
                extra = f", wavelength {p['wavelength_m']:.2f} m" if "wavelength_m" in p else ""
                fr = p.get("front_rear_residual")
                if fr and fr["coherence"] > 0.5:
                    extra += (", car ends in phase" if abs(fr["phase_deg"]) < 45 else
                              ", car ends in anti-phase" if abs(fr["phase_deg"]) > 135 else "")
                out.append(f"{name}: residual peak at {p['frequency_hz']:.2f} Hz, {p['over_floor']:.1f}x its floor "
                           f"({kind}{extra})")
    w = ev["wheel_line"]
    if w["over_floor"] >= s.line_alarm and w["axle_asymmetry"] >= s.asymmetry:
        out.append(f"axle-box consistency: line at wavelength {w['wavelength_m']:.3f} m, {w['over_floor']:.0f}x "
                   f"the floor, {w['axle_asymmetry']:.1f}x stronger on wheelset {w['stronger_on_wheelset']}")
    return out


# ------------------------------------------------------------------------------- main
@one_blas_thread  # the answer must not depend on the machine's thread count (threads.py)
def diagnose(campaign: Campaign, *, settings: DiagnoseSettings = DiagnoseSettings(), progress=None) -> dict:
    say = progress or (lambda msg: None)
    stages = counter(progress, 3 + settings.fit_leading, "in-service diagnosis", unit="stage")
    lay = layout(campaign)
    records = read_records(campaign, lay, settings.records, progress=say)
    stages.update()
    runs = tuple(campaign.run_ids)
    if len(runs) == 1:  # one run: its first and second halves play training and held-out runs
        split = []
        for r in records:
            h = r.z.shape[1] // 2
            for tag, sl in (("a", slice(0, h)), ("b", slice(h, None))):
                split.append(type(r)(f"{r.run_id}#{tag}", r.t0, r.speed[sl], r.distance[sl], r.z[:, sl]))
        records = split
        runs = tuple(sorted({r.run_id for r in records}))
    stats = statistics(records, lay.channels, settings.records)
    if len(stats.runs) < 2:
        raise CampaignError(f"the diagnosis needs data from two runs (or one long run) to hold one out; usable "
                            f"{settings.records.window:g} s windows came from {len(stats.runs)}", path=campaign.root)
    train, test = _split_runs(stats.runs)
    base = prior_parameters(campaign)
    pri = campaign.meta.priors
    bounds = {n: (pri[n].low, pri[n].high) if n in pri else
              (getattr(base, n) / settings.prior_spread, getattr(base, n) * settings.prior_spread)
              for n in FIT_NAMES}
    ctx = _Context(campaign, lay, records, {n: i for i, n in enumerate(lay.channels)}, stats, train, test, base,
                   bounds, settings)
    say(f"{len(records)} records, {sum(stats.seconds.values()):.0f} s in {len(stats.S)} (run, speed) cells; "
        f"training runs {sorted(train)}, held out {sorted(test)}")
    base_fit = _baseline(ctx)
    stages.update()
    say(f"baseline fitted ({base_fit.evaluations} evaluations)")
    ev = _evidence(ctx, base_fit)
    scores = _scores(ev, lay, settings)
    ranked = sorted(scores, key=lambda k: -scores[k])
    hyps = []
    for name in ranked[:settings.fit_leading]:
        h = _fit_hypothesis(ctx, EXTENSIONS[name], base_fit, ev)
        stages.update()
        h["evidence_score"] = scores[name]
        hyps.append(h)
        say(f"{name}: held-out gain {h['gain']:.1%} on {h['best_channel']}")
    ok = [h for h in hyps if h["penalised_gain"] >= settings.min_gain and not h["losses"]
          and not _leaves_systematic(h, settings)]
    alarms = _alarms(ev, settings)
    if ok:
        best = max(ok, key=lambda h: h["penalised_gain"])
        cause = best["name"]
    else:
        best = None
        cause = "unexplained" if alarms else "none"
    words = _summary(cause, best, alarms, ev, hyps, settings)
    stages.update(stages.total - stages.n)  # fewer hypotheses than fit_leading: the rest skipped
    stages.close()
    masks = ev.pop("masks")
    ev["signal_band_count"] = {n: int(masks[:, c].sum()) for c, n in enumerate(lay.response_names)}
    return {
        "format": FORMAT, "campaign": str(campaign.root), "cause": cause,
        "evidence": {"summary": words, **ev},
        "extension": None if best is None else {"name": best["name"], "parameters": best["parameters"],
                                               "model": best["model"]},
        "gain": None if best is None else {"heldout_error": best["heldout_error"], "best_channel": best["best_channel"],
                                           "reduction": best["gain"]},
        "baseline": {"parameters": base_fit.parameters.as_dict(), "parameters_at_bounds": list(base_fit.at_bounds),
                     "bounds": {k: list(v) for k, v in bounds.items()}},
        "hypotheses": [{k: v for k, v in h.items() if k != "model"} for h in hyps],
        "split": {"training_runs": sorted(train), "heldout_runs": sorted(test)},
        "settings": {"min_gain": settings.min_gain, "penalty_per_parameter": settings.penalty,
                     "max_loss": settings.max_loss, "max_systematic_left": settings.max_systematic_left},
        "_plot": {"ctx": ctx, "base_fit": base_fit, "best": best},
    }


def _summary(cause, best, alarms, ev, hyps, s: DiagnoseSettings) -> list[str]:
    out = []
    if best is not None:
        out.append(f"cause: {cause} ({best['description']}); held-out error on {best['best_channel']} reduced by "
                   f"{best['gain']:.0%}")
        out.append("extension parameters: " + ", ".join(
            f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in best["parameters"].items()))
    elif cause == "unexplained":
        out.append("unexplained: the baseline leaves systematic residuals and no extension in the registry "
                   "reduces the held-out error enough")
    else:
        out.append("none: the baseline explains the data within the noise (no systematic residual, no extension gains)")
    out += alarms
    for h in hyps:
        if h is best or h["penalised_gain"] < s.min_gain:
            continue
        if h["losses"]:
            worse = ", ".join(f"{n} ({h['heldout_error'][n]['before']:.3g} -> {h['heldout_error'][n]['after']:.3g})"
                              for n in h["losses"])
            out.append(f"{h['name']} gains {h['gain']:.0%} on {h['best_channel']} but makes held-out {worse} worse")
        if _leaves_systematic(h, s):
            out.append(f"{h['name']} gains {h['gain']:.0%} on {h['best_channel']} but leaves "
                       f"{h['systematic_left']:.0%} of its systematic residual (error x input coherence): "
                       "it does not explain it")
    others = sorted(hyps, key=lambda h: -h["penalised_gain"])
    out.append("hypotheses by held-out gain: " + ", ".join(f"{h['name']} {h['gain']:.0%}" for h in others))
    if ev["parameters_at_bounds"]:
        out.append("baseline parameters at their bounds: " + ", ".join(ev["parameters_at_bounds"]))
    return out
