"""What the baseline's residuals show: per response channel the held-out normalised
residual power, the residual's coherence with the rail input, residual PSD peaks over a
running-median floor (fixed in frequency or proportional to speed, the phase between the
car's ends), the residual's spectral flatness; a wheel-fixed line in the axle-box
consistency channel (:mod:`.wheels`); how well the axle boxes' spectra collapse over speed
(:mod:`.track`). Each extension is scored by the evidence that speaks for it
(:func:`scores`), and what is systematic is put in words (:func:`alarms`).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.ndimage

from ...models.parameters import CarParameters
from .records import Layout, Record, Statistics
from .response import ResponseFit, grouped_residual_cross_spectrum, input_coherence, input_noise_power, response_nrp
from .settings import DiagnosisSettings
from .track import fit_track, speed_folds, track_error
from .wheels import line_spectrum

#: A residual PSD peak is systematic when it carries more than this share of the measured
#: power; set with the other thresholds while the diagnosis was developed (:class:`DiagnosisSettings`).
PEAK_SHARE = 0.3


@dataclass(frozen=True)
class DiagnosisData:
    """What every step of the diagnosis reads: the campaign's records and their band
    statistics, the split into training and held-out runs, the prior car and the bounds
    of the baseline fit."""

    root: Path  # the campaign folder
    campaign_runs: frozenset  # the campaign's run ids
    layout: Layout
    records: tuple[Record, ...]
    stats: Statistics
    train: frozenset  # training run ids (a single run's halves: "<run>#a")
    test: frozenset  # held-out run ids
    prior: CarParameters
    bounds: dict  # baseline parameter -> (low, high) searched
    settings: DiagnosisSettings

    @property
    def rows(self) -> dict:
        """Channel name -> row of a record's ``z``."""
        return {n: i for i, n in enumerate(self.layout.channels)}

    def keys(self, runs) -> set:
        """The statistics' (run, speed bin) keys of ``runs``."""
        return {k for k in self.stats.S if k[0] in runs}


@dataclass(frozen=True)
class Evidence:
    """The baseline's evidence. ``channels``, ``wheel_line`` and ``track`` hold JSON values
    (see :meth:`to_json`); ``masks`` the signal bands each response channel is judged on."""

    channels: dict  # response channel -> its evidence (held-out NRP, input coherence, peaks, ...)
    wheel_line: dict  # the consistency channel's strongest line and its wheelset asymmetry
    track: dict  # the rigid rail's collapse misfit at fitted and at other speeds
    parameters_at_bounds: tuple[str, ...]  # baseline parameters at a bound of their search
    masks: np.ndarray  # (n_band, n_response) booleans

    def to_json(self) -> dict:
        return {"channels": self.channels, "wheel_line": self.wheel_line, "track": self.track,
                "parameters_at_bounds": list(self.parameters_at_bounds),
                "signal_band_count": {n: int(self.masks[:, c].sum()) for c, n in enumerate(self.channels)}}


def signal_bands(P: np.ndarray, bw: np.ndarray, factor: float) -> np.ndarray:
    """Bands where the measured PSD stands ``factor`` above the channel's floor (the 5th
    percentile of its PSD over the band), per channel: (n_band, n_out) booleans."""
    psd = P / bw[:, None]
    floor = np.percentile(psd, 5, axis=0)
    return psd > factor * floor[None, :]


def _peaks(f, ratio, weight, band, alarm):
    """Local maxima of ``ratio`` (residual over floor) above ``alarm`` inside ``band``
    carrying more than 5 % of the measured power, one per 5 % of frequency, the three
    strongest."""
    out = []
    for i in range(1, f.size - 1):
        if band[0] <= f[i] <= band[1] and ratio[i] >= alarm and ratio[i] >= ratio[i - 1] and ratio[i] >= ratio[i + 1] \
                and weight[i] > 0.05:
            out.append((float(f[i]), float(ratio[i]), float(weight[i])))
    kept = []
    for p in sorted(out, key=lambda x: -x[1]):
        if all(abs(p[0] / q[0] - 1) > 0.05 for q in kept):
            kept.append(p)
    return kept[:3]


def _floor(x: np.ndarray, width: int = 41) -> np.ndarray:
    """Running median over ``width`` bands."""
    return scipy.ndimage.median_filter(x, size=width, mode="nearest")


def response_errors(data: DiagnosisData, fit: ResponseFit, masks: np.ndarray) -> np.ndarray:
    """Held-out NRP of ``fit`` per response channel over its signal bands ``masks``."""
    R, P = response_nrp(data.stats, data.layout, data.keys(data.test), fit,
                        by_band=True)
    return np.array([R[masks[:, c], c].sum() / max(P[masks[:, c], c].sum(), 1e-300) for c in range(R.shape[1])])


def _speed_scaling(data: DiagnosisData, fit: ResponseFit, c: int, f0: float) -> dict:
    """Is the residual peak at f0 fixed in frequency or proportional to speed? Compare the
    residual-over-floor at f0 and at f0 v / v_mean in each speed bin."""
    stats = data.stats
    bins = stats.speed_bins
    if len(bins) < 2:
        return {"scaling": "unknown", "reason": "one speed bin only"}
    vw = data.settings.records.speed_bin
    vs, ratios, weights = [], [], []
    for vb in bins:
        keys = {k for k in stats.S if k[1] == vb}
        R, P = response_nrp(stats, data.layout, keys, fit, by_band=True)
        bw = np.diff(stats.edges)
        r = R[:, c] / bw
        ratios.append(r / np.maximum(_floor(r), 1e-300))
        vs.append(vb + vw / 2)
        weights.append(stats.seconds_of(keys))
    vs = np.array(vs)
    v_mean = float(np.average(vs, weights=weights))
    f = stats.centres
    at_fixed = [np.interp(f0, f, r) for r in ratios]
    at_scaled = [np.interp(f0 * v / v_mean, f, r) for r, v in zip(ratios, vs)]
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


def channel_evidence(data: DiagnosisData, fit: ResponseFit, masks: np.ndarray | None = None
                     ) -> tuple[dict, np.ndarray]:
    """Per response channel, what the residuals of ``fit`` (a response fit) show: held-out
    NRP, coherence with the rail input, PSD peaks over the floor (speed scaling, phase
    between the car ends), flatness; and the signal-band masks (``masks``: given ones, e.g.
    the baseline's, so that a fit is judged on the same bands)."""
    s, lay, stats = data.settings, data.layout, data.stats
    bw = np.diff(stats.edges)
    f = stats.centres
    all_keys = set(stats.S)
    R, P = response_nrp(stats, lay, all_keys, fit, by_band=True)
    _, Ptest = response_nrp(stats, lay, data.keys(data.test), fit, by_band=True)
    eiv = input_noise_power(stats, lay, all_keys, fit)
    clean = eiv < s.input_noise_share * R  # bands where the rail input's own noise does not dominate
    if masks is None:
        masks = signal_bands(Ptest, bw, s.signal_factor) & clean
    coh = input_coherence(stats, lay, all_keys, fit)
    nrp_test = response_errors(data, fit, masks)
    Rx = grouped_residual_cross_spectrum(stats, lay, all_keys, fit)
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
            k = int(np.argmin(np.abs(f - f0)))
            near = slice(max(k - 2, 0), k + 3)
            peak = {"frequency_hz": f0, "over_floor": rr, "residual_share": sh,
                    "input_coherence": float(np.average(coh[near, c], weights=R[near, c] + 1e-300)),
                    **_speed_scaling(data, fit, c, f0)}
            if pairs:
                x = Rx[k, pairs["i"], pairs["j"]]
                peak["front_rear_residual"] = {
                    "phase_deg": float(np.degrees(np.angle(x))),
                    "coherence": float(abs(x) ** 2 / max(Rx[k, pairs["i"], pairs["i"]].real
                                                          * Rx[k, pairs["j"], pairs["j"]].real, 1e-300))}
            peaks.append(peak)
        flat = rpsd[m] if m.any() else rpsd
        low = (f < 3) & m  # the carbody's rigid modes' bands, where a CoG offset shows
        channels[name] = {
            "heldout_nrp": float(nrp_test[c]),
            "input_coherence": float(np.average(coh[m, c], weights=R[m, c])) if m.any() else 0.0,
            "peaks": peaks,
            "spectral_flatness": float(np.exp(np.mean(np.log(flat))) / np.mean(flat)),
            "signal_bands_hz": [float(f[m].min()), float(f[m].max())] if m.any() else None,
            "low_band_coherence": float(np.average(coh[low, c], weights=R[low, c])) if low.any() else 0.0,
        }
    return channels, masks


def baseline_evidence(data: DiagnosisData, base_fit: ResponseFit) -> Evidence:
    """The evidence of the baseline's residuals, the consistency channel's line over all
    runs and the rigid rail's collapse over speed."""
    s, stats = data.settings, data.stats
    channels, masks = channel_evidence(data, base_fit)
    spec = line_spectrum(data.records, data.rows, data.campaign_runs, s.wheels)
    i, line_ratio = spec.strongest(s.wheels)
    a1, a2 = spec.axle1[i], spec.axle2[i]
    asym = float(max(a1, a2) / max(min(a1, a2), 1e-300))
    wheel = {"wavelength_m": float(1 / spec.wavenumber[i]), "over_floor": line_ratio, "axle_asymmetry": asym,
             "stronger_on_wheelset": 1 if a1 >= a2 else 2}
    # the rigid rail's collapse: fitted at some speeds, how well does it predict the others?
    # (misfits less the spectra's sampling variance, so the two are comparable)
    fitted, held = [], []
    for fit_keys, test_keys in speed_folds(stats, set(stats.S)):
        tb = fit_track(stats, fit_keys, flexible=False, settings=s.track)
        fitted.append(float(np.mean(track_error(stats, fit_keys, tb, s.track))))
        held.append(track_error(stats, test_keys, tb, s.track))
    track = {"collapse_misfit_fitted_speeds": float(np.mean(fitted)) if fitted else None,
             "collapse_misfit_other_speeds": np.mean(held, axis=0).tolist() if held else None,
             "speeds_m_s": [min(stats.speed_bins), max(stats.speed_bins) + s.records.speed_bin]}
    return Evidence(channels, wheel, track, tuple(base_fit.at_bounds), masks)


def scores(ev: Evidence, lay: Layout, s: DiagnosisSettings) -> dict[str, float]:
    """Evidence for each hypothesis (the names of :data:`.extensions.EXTENSIONS`), 0 (none)
    upwards; used to rank them."""
    ch = ev.channels
    bogie = [n for n, o in zip(lay.response_names, lay.responses) if o.body.startswith("bogie")]
    carbody = [n for n, o in zip(lay.response_names, lay.responses) if o.body == "carbody"]
    coh = {n: ch[n]["input_coherence"] for n in ch}
    peaks = {n: ch[n]["peaks"] for n in ch}
    fixed_mid = max([p["over_floor"] for n in carbody for p in peaks[n]
                     if 4 <= p["frequency_hz"] <= 18 and p.get("scaling") != "speed_proportional"] + [0.0])
    at_bounds = set(ev.parameters_at_bounds)
    w = ev.wheel_line
    track = ev.track
    sc = {
        "sensor_offset": max([coh[n] for n in bogie] + [0.0]),
        "floor_sensor_offset": max([ch[n]["low_band_coherence"] for n in carbody] + [0.0]),
        "carbody_bending": fixed_mid / s.peak_alarm,
        "mounted_equipment": 0.5 * fixed_mid / s.peak_alarm + max([coh[n] for n in carbody] + [0.0]),
        "journey_load": max([coh[n] for n in carbody] + [0.0]),
        "amplitude_dependent_suspension": max([coh[n] for n in bogie + carbody] + [0.0]),
        "cog_offset": max([ch[n]["low_band_coherence"] for n in carbody] + [0.0]),
        "airspring_reservoir": max([coh[n] for n in carbody] + [0.0]) + 0.5 * bool(at_bounds & {"k_s", "c_s"}),
        "wheel_out_of_round": (w["over_floor"] / s.line_alarm) * (w["axle_asymmetry"] >= s.asymmetry),
        "track_flexibility": (max(track["collapse_misfit_other_speeds"])
                              / max(track["collapse_misfit_fitted_speeds"], 1e-12) - 1.0)
        if track["collapse_misfit_fitted_speeds"] else 0.0,
    }
    return {k: float(max(v, 0.0)) for k, v in sc.items()}


def systematic(channel: dict) -> dict:
    """What is systematic in one channel's residual: its coherence with the rail input and
    its strongest PSD peak over the floor among those carrying > PEAK_SHARE of the measured power."""
    peaks = [p["over_floor"] for p in channel["peaks"] if p["residual_share"] > PEAK_SHARE]
    return {"input_coherence": channel["input_coherence"], "peak_over_floor": max(peaks, default=0.0)}


def _peak_words(name: str, p: dict) -> str:
    kind = p.get("scaling", "unknown").replace("_", " ")
    extra = f", wavelength {p['wavelength_m']:.2f} m" if "wavelength_m" in p else ""
    fr = p.get("front_rear_residual")
    if fr and fr["coherence"] > 0.5:
        extra += (", car ends in phase" if abs(fr["phase_deg"]) < 45 else
                  ", car ends in anti-phase" if abs(fr["phase_deg"]) > 135 else "")
    return f"{name}: residual peak at {p['frequency_hz']:.2f} Hz, {p['over_floor']:.1f}x its floor ({kind}{extra})"


def _peak_counts(p: dict, s: DiagnosisSettings) -> bool:
    return p["over_floor"] >= s.peak_alarm and p["residual_share"] > PEAK_SHARE


def alarms(ev: Evidence, s: DiagnosisSettings) -> list[str]:
    """What in the evidence is systematic (the baseline does not explain the data within
    the noise), in words.

    A residual peak is systematic where the residual in its bands is coherent with the rail
    input: the model could have predicted it and did not. A peak the input does not
    explain is response to an excitation the sensors do not measure (the rear bogie's own
    rail where its wheelsets carry no sensor, machinery on the carbody), which no model
    driven by these inputs can predict; :func:`notes` reports it."""
    out = []
    for name, c in ev.channels.items():
        if _coherent(c, s) and not within_accuracy(c, s):
            out.append(f"{name}: residual coherent with the rail input ({c['input_coherence']:.2f}), "
                       f"a systematic model error ({_systematic_words(c)})")
        for p in c["peaks"]:
            if _peak_counts(p, s) and p.get("input_coherence", 1.0) >= s.coherence_alarm:
                out.append(_peak_words(name, p))
    w = ev.wheel_line
    if w["over_floor"] >= s.line_alarm and w["axle_asymmetry"] >= s.asymmetry:
        out.append(f"axle-box consistency: line at wavelength {w['wavelength_m']:.3f} m, {w['over_floor']:.0f}x "
                   f"the floor, {w['axle_asymmetry']:.1f}x stronger on wheelset {w['stronger_on_wheelset']}")
    return out


def _coherent(c: dict, s: DiagnosisSettings) -> bool:
    return c["input_coherence"] >= s.coherence_alarm


def within_accuracy(c: dict, s: DiagnosisSettings) -> bool:
    """Is a channel's coherent residual (held-out NRP x input coherence) under ``systematic_floor``?"""
    return c["heldout_nrp"] * c["input_coherence"] < s.systematic_floor


def _systematic_words(c: dict) -> str:
    share = c["heldout_nrp"] * c["input_coherence"]
    return f"{share:.1%} of its held-out power, an rms error of {np.sqrt(share):.0%}"


def notes(ev: Evidence, s: DiagnosisSettings) -> list[str]:
    """What is in the residuals but not systematic (:func:`alarms`): coherent residuals
    within a model's accuracy, and strong peaks not coherent with the rail input."""
    small = [f"{name}: residual coherent with the rail input ({c['input_coherence']:.2f}) but within a model's "
             f"accuracy ({_systematic_words(c)}; a model error from {s.systematic_floor:.0%})"
             for name, c in ev.channels.items() if _coherent(c, s) and within_accuracy(c, s)]
    return small + [
        f"{_peak_words(name, p)}; not coherent with the rail input ({p['input_coherence']:.2f}): response to "
        "an excitation the sensors do not measure, not counted as a model error"
        for name, c in ev.channels.items() for p in c["peaks"]
        if _peak_counts(p, s) and p.get("input_coherence", 1.0) < s.coherence_alarm]
