"""Speed-dependent excitations and speed-independent tones in the full-band spectra.

The seed (section 4, Figure 7) compares PSDs of three runs at different speeds by eye:
a 77.64 Hz line present at every speed is not the vehicle's; a line whose frequency
rises with speed is track excitation (sleepers at 0.7 m, welds every 39 m). Here that
is done over many short windows of steady speed:

1. windows of ``window`` seconds where the speed varies by less than ``speed_tolerance``
   are drawn from every run (seeded), and each channel's Welch PSD is taken;
2. two averages of the log spectra are formed: over frequency (a fixed tone stays sharp,
   a speed-proportional line smears) and over spatial frequency nu = f / v (the reverse);
3. each peak of either average is tracked through the windows, and the exponent alpha of
   f ~ v^alpha is fitted: alpha = 1 is speed-dependent (wavelength v / f), alpha = 0 a
   speed-independent tone; the channels in which it stands out are listed;
4. periodic impacts (rail-panel welds give a comb of lines k / Lambda too dense to list
   one by one) are found as the peak over distance lag of the autocorrelation of each
   window's high-passed energy envelope, averaged over windows: the impact spacing
   Lambda is reported as one speed-dependent line.

Frequencies in Hz, wavelengths in m, prominences in dB.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.signal

from ..data.campaign import Campaign
from .. import checks
from .peaks import parabolic_shift
from .resample import is_regular, regular_run, to_uniform_grid


@dataclass(frozen=True)
class LineSettings:
    window_s: float = 8.0  # [s] an analysis window, short enough for the speed to hold
    welch_s: float = 2.0  # [s] Welch segment inside a window (nperseg = welch_s x fs)
    speed_tolerance: float = 0.01  # relative speed spread inside a window
    windows_per_run: int = 8
    min_frequency: float = 2.0  # [Hz] below this the vehicle's own response dominates
    prominence_db: float = 4.0  # of a peak in the averaged spectra
    presence_db: float = 3.0  # of the tracked peak in one window
    search: float = 0.03  # relative search half-width when tracking
    min_speed_ratio: float = 1.15  # fastest / slowest window needed to tell the kinds apart
    tone_presence: float = 0.6  # a fixed tone is there at every speed: in this share of windows at least
    impact_highpass: float = 20.0  # [Hz] before the energy envelope is formed
    impact_lags: tuple[float, float] = (5.0, 100.0)  # [m] spacings searched for periodic impacts
    impact_z: float = 6.0  # significance of the autocorrelation peak (robust z-score)
    seed: int = 0

    def __post_init__(self):
        checks.positive(self, "window_s", "welch_s", "speed_tolerance", "min_frequency", "prominence_db",
                        "presence_db", "search", "impact_highpass", "impact_z")
        checks.whole(self, "windows_per_run")
        checks.fraction(self, "tone_presence", closed=True)
        checks.increasing(self, "impact_lags", low=0.0)
        if self.welch_s > self.window_s:
            raise ValueError(f"LineSettings.welch_s = {self.welch_s} s must fit in window_s = {self.window_s} s")
        if not self.min_speed_ratio > 1:
            raise ValueError(f"LineSettings.min_speed_ratio must be > 1, got {self.min_speed_ratio!r}")


@dataclass(frozen=True)
class SpectralLine:
    kind: str  # 'speed_dependent' | 'speed_independent' | 'ambiguous'
    frequency_hz: float | None  # tones: the frequency; speed-dependent: at the median speed
    wavelength_m: float | None  # speed-dependent: v / f
    exponent: float | None  # fitted alpha in f ~ v^alpha; None where the speeds are too close to fit it
    exponent_stderr: float | None
    channels: tuple[str, ...]
    prominence_db: float
    n_windows: int
    speed_range: tuple[float, float]
    interpretation: str

    def to_json(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class _Window:
    speed: float
    psd: np.ndarray  # (n_ch, n_f) log10, median removed
    psd_si: np.ndarray  # (n_ch, n_f) [SI unit^2 / Hz]
    impacts: np.ndarray  # (n_ch, n_lag) envelope autocorrelation over distance lag


LAG_STEP = 0.25  # [m]


def _impact_autocorrelation(x: np.ndarray, fs: float, speed: float, settings: LineSettings) -> np.ndarray:
    """Normalised autocorrelation of the energy envelope, on the distance-lag grid."""
    sos = scipy.signal.butter(4, min(settings.impact_highpass, 0.4 * fs), "highpass", fs=fs, output="sos")
    e = scipy.signal.sosfiltfilt(sos, x, axis=1) ** 2
    e -= e.mean(axis=1, keepdims=True)
    n = e.shape[1]
    F = np.fft.rfft(e, 2 * n, axis=1)
    ac = np.fft.irfft(F * np.conj(F), axis=1)[:, :n]
    ac /= np.maximum(ac[:, :1], 1e-300)
    lags = np.arange(*settings.impact_lags, LAG_STEP)
    return np.stack([np.interp(lags, np.arange(n) * speed / fs, row, right=np.nan) for row in ac])


class LineWindowCollector:
    """Collects steady-speed windows run by run (streaming); :meth:`classify` does the rest."""

    def __init__(self, channels: tuple[str, ...], fs: float, settings: LineSettings = LineSettings()):
        self.channels, self.fs, self.settings = channels, fs, settings
        self.rng = np.random.default_rng(settings.seed)
        self.windows: list[_Window] = []
        self.f = None

    def add_run(self, run) -> None:
        """Windows of this run; sampled at the run's own rate (its time column is
        authoritative), spectra put on the collector's frequency grid."""
        st = self.settings
        run = regular_run(run, self.fs)
        fs = 1.0 / float(np.median(np.diff(run.time)))
        if abs(fs / self.fs - 1) < 1e-6:
            fs = self.fs
        n = int(st.window_s * fs)
        nper = int(st.welch_s * fs)
        if run.speed is not None:
            speed = run.speed
        elif run.distance is not None:
            speed = np.gradient(run.distance, run.time)
        else:
            return
        starts = [s0 for a, b in run.blocks for s0 in range(a, b - n, n)]
        self.rng.shuffle(starts)
        taken = 0
        for s0 in starts:
            if taken >= st.windows_per_run:
                break
            v = speed[s0:s0 + n]
            if not np.all(np.isfinite(v)) or v.mean() <= 0 or np.ptp(v) / v.mean() > st.speed_tolerance:
                continue
            if not all(run.valid[ch][s0:s0 + n].all() for ch in self.channels):
                continue
            X = np.vstack([run.channels[ch][s0:s0 + n] for ch in self.channels])
            if not is_regular(run.time[s0:s0 + n], fs):  # Welch needs evenly spaced samples
                _, X = to_uniform_grid(run.time[s0:s0 + n], X, fs, axis=1)
            f, P_si = scipy.signal.welch(X, fs=fs, nperseg=nper, detrend="linear", axis=1)
            if self.f is None:
                self.f = f
            elif f.size != self.f.size or not np.allclose(f, self.f):
                P_si = np.stack([np.interp(self.f, f, row, right=np.nan) for row in P_si])
                if np.isnan(P_si).any():
                    continue
            P = np.log10(np.maximum(P_si, 1e-300))
            P -= np.median(P, axis=1, keepdims=True)
            self.windows.append(_Window(float(v.mean()), P, P_si,
                                        _impact_autocorrelation(X, fs, float(v.mean()), st)))
            taken += 1

    def classify(self) -> list[SpectralLine]:
        return _classify(self.f, self.windows, self.channels, self.settings)

    def psd_by_speed(self, n_classes: int = 3, units: dict | None = None) -> "ChannelPSDs | None":
        """Mean PSD of each channel over the windows of each speed class (equal-count classes);
        ``units``: each channel's SI unit, for the figures."""
        if len(self.windows) < n_classes:
            return None
        speeds = np.array([w.speed for w in self.windows])
        order = np.argsort(speeds)
        classes = np.array_split(order, n_classes)
        P = np.stack([w.psd_si for w in self.windows])
        return ChannelPSDs(self.f, tuple((float(speeds[c].min()), float(speeds[c].max())) for c in classes),
                           {ch: np.stack([P[c, i].mean(axis=0) for c in classes])
                            for i, ch in enumerate(self.channels)},
                           dict(units or {}))


@dataclass(frozen=True)
class ChannelPSDs:
    """Welch PSDs [SI unit^2/Hz] per channel, averaged over steady-speed windows per speed class."""

    frequency: np.ndarray  # [Hz]
    speed_classes: tuple[tuple[float, float], ...]  # [m/s]
    psd: dict  # channel -> (n_classes, n_f)
    units: dict = field(default_factory=dict)  # channel -> its SI unit, where known

    def to_json(self, n_points: int = 200) -> dict:
        f = self.frequency
        grid = np.unique(np.round(np.geomspace(max(f[1], 0.5), f[-1], n_points) / (f[1] - f[0])).astype(int))
        return {"frequency_hz": f[grid].tolist(), "speed_classes_m_s": [list(c) for c in self.speed_classes],
                "psd_si_per_hz": {ch: p[:, grid].tolist() for ch, p in self.psd.items()}}


def _periodic_impacts(windows, channels, speeds, settings: LineSettings) -> list[SpectralLine]:
    lags = np.arange(*settings.impact_lags, LAG_STEP)
    R = np.stack([w.impacts for w in windows])  # (n_w, n_ch, n_lag)
    found = []
    for c, ch in enumerate(channels):
        mean = np.nanmean(R[:, c], axis=0)
        ok = np.isfinite(mean)
        if ok.sum() < 20:
            continue
        med = np.median(mean[ok])
        mad = 1.4826 * np.median(np.abs(mean[ok] - med))
        k = int(np.nanargmax(mean))
        z = (mean[k] - med) / max(mad, 1e-12)
        if z >= settings.impact_z:
            found.append((ch, lags[k], z))
    if not found:
        return []
    spacing = float(np.median([x[1] for x in found]))
    present = tuple(ch for ch, lag, _ in found if abs(lag / spacing - 1) < 0.03)
    v_med = float(np.median(speeds))
    return [SpectralLine("speed_dependent", v_med / spacing, spacing, 1.0, 0.0, present,
                         float(max(x[2] for x in found)), len(windows), (float(speeds.min()), float(speeds.max())),
                         f"periodic impacts every {spacing:.2f} m (autocorrelation of the energy envelope over "
                         f"distance; rail-panel welds); exponent 1 by construction")]


def _peaks(x: np.ndarray, prominence_decades: float):
    idx, props = scipy.signal.find_peaks(x, prominence=prominence_decades)
    return idx, props["prominences"]


def _local_peak(logp: np.ndarray, f: np.ndarray, f_expected: float, rel: float):
    """Frequency and prominence [decades] of the highest bin within f_expected*(1 +- rel)."""
    df = f[1] - f[0]
    half = max(rel * f_expected, 1.5 * df)
    sel = np.flatnonzero(np.abs(f - f_expected) <= half)
    if sel.size < 1:
        return None
    k = sel[np.argmax(logp[sel])]
    if k <= 0 or k >= f.size - 1:
        return None
    ring = np.flatnonzero((np.abs(f - f[k]) > 3 * df) & (np.abs(f - f[k]) < max(0.15 * f[k], 8 * df)))
    if ring.size == 0:
        return None
    return f[k] + parabolic_shift(logp, k) * df, logp[k] - np.median(logp[ring])


def classify_lines(campaign: Campaign, channels: tuple[str, ...] | None = None, *,
                   settings: LineSettings = LineSettings()) -> list[SpectralLine]:
    """Classify the spectral lines of a campaign's channels (see module docstring)."""
    channels = tuple(s.name for s in campaign.meta.sensors) if channels is None else channels
    collector = LineWindowCollector(channels, campaign.meta.sampling_rate, settings)
    for run in campaign.iter_runs():
        collector.add_run(run)
    return collector.classify()


def _classify(f, windows, channels, settings: LineSettings) -> list[SpectralLine]:
    if len(windows) < 3:
        return []
    speeds = np.array([w.speed for w in windows])
    P = np.stack([w.psd for w in windows])  # (n_w, n_ch, n_f)
    df = f[1] - f[0]
    v_med = float(np.median(speeds))
    nu = np.arange(settings.min_frequency / speeds.min(), f[-1] / speeds.max(), df / v_med)
    A_t = P.mean(axis=0)
    A_s = np.stack([np.stack([np.interp(nu * w.speed, f, w.psd[c]) for c in range(len(channels))])
                    for w in windows]).mean(axis=0)
    prom = settings.prominence_db / 10.0
    candidates = []  # (kind hypothesis, value)
    for c in range(len(channels)):
        idx, _ = _peaks(A_t[c], prom)
        candidates += [("speed_independent", f[i]) for i in idx if f[i] >= settings.min_frequency]
        idx, _ = _peaks(A_s[c], prom)
        candidates += [("speed_dependent", nu[i]) for i in idx]
    lines: list[SpectralLine] = []
    seen: list[tuple[str, float]] = []
    for hyp, value in sorted(candidates, key=lambda t: t[1]):
        if any(h == hyp and abs(value / v - 1) < 0.02 for h, v in seen):
            continue
        seen.append((hyp, value))
        per_channel = []
        for c in range(len(channels)):
            found = []
            for w, sp in zip(P[:, c], speeds):
                fe = value if hyp == "speed_independent" else value * sp
                if not settings.min_frequency <= fe <= f[-2]:
                    continue
                r = _local_peak(w, f, fe, settings.search)
                if r is not None and r[0] > 0 and r[1] * 10 >= settings.presence_db:
                    found.append((sp, r[0], r[1]))
            per_channel.append(found)
        best = int(np.argmax([len(x) for x in per_channel]))
        found = per_channel[best]
        if len(found) < max(3, 0.3 * len(windows)):
            continue
        sp = np.array([x[0] for x in found])
        fr = np.array([x[1] for x in found])
        if sp.max() / sp.min() < settings.min_speed_ratio:
            # over so narrow a speed range f ~ v^alpha has no usable slope: the exponent is
            # undetermined (None), not a number, and the line cannot be called either kind
            kind, alpha, se = "ambiguous", None, None
        else:
            X = np.column_stack([np.log(sp), np.ones(sp.size)])
            coef, res, *_ = np.linalg.lstsq(X, np.log(fr), rcond=None)
            alpha = float(coef[0])
            dof = max(1, sp.size - 2)
            sigma2 = float(np.sum((np.log(fr) - X @ coef) ** 2) / dof)
            se = float(np.sqrt(sigma2 * np.linalg.inv(X.T @ X)[0, 0]))
            if abs(alpha - 1) < 0.1:
                kind = "speed_dependent"
            elif abs(alpha) < 0.1 and len(found) >= settings.tone_presence * len(windows):
                kind = "speed_independent"
            else:
                kind = "ambiguous"
        if kind != hyp and kind != "ambiguous":
            continue  # found by the other average as well; that entry reports it
        present = tuple(ch for ch, x in zip(channels, per_channel) if len(x) >= 0.5 * len(found))
        prominence = float(10 * np.median([x[2] for x in found]))
        if kind == "speed_dependent":
            wavelength = float(np.median(sp / fr))
            freq = v_med / wavelength
            text = f"track excitation at wavelength {wavelength:.3f} m (frequency proportional to speed)"
            if 0.55 <= wavelength <= 0.8:
                text += "; sleeper passing"
        else:
            wavelength = None
            freq = float(np.median(fr))
            if kind == "speed_independent":
                text = ("speed-independent tone in " + (f"{present[0]} only" if len(present) == 1 else
                                                         f"{len(present)} channels"))
                if len(present) == 1:
                    text += ": not a vehicle mode (instrument or electrical pick-up)"
                else:
                    text += ": a candidate vehicle mode (present at every speed on several sensors)"
            elif alpha is None:
                text = (f"seen only at {sp.min():.1f}-{sp.max():.1f} m/s: too narrow a speed range to tell a "
                        f"fixed tone from track excitation (needs a fastest/slowest ratio of "
                        f"{settings.min_speed_ratio:g})")
            else:
                text = "neither fixed nor proportional to speed"
        lines.append(SpectralLine(kind, freq, wavelength, alpha, se, present, prominence, len(found),
                                  (float(sp.min()), float(sp.max())), text))
    impacts = _periodic_impacts(windows, channels, speeds, settings)
    if impacts:
        spacing = impacts[0].wavelength_m
        for i, ln in enumerate(lines):
            if ln.kind == "speed_dependent" and ln.wavelength_m:
                k = round(spacing / ln.wavelength_m)
                if k >= 2 and abs(spacing / ln.wavelength_m - k) < 0.01 * k:
                    lines[i] = SpectralLine(**{**ln.__dict__, "interpretation": ln.interpretation
                                               + f"; harmonic {k} of the {spacing:.2f} m impacts"})
    lines += impacts
    # one entry per physical line: merge duplicates found in several channels
    merged: list[SpectralLine] = []
    for ln in sorted(lines, key=lambda x: -x.n_windows):
        key = ln.wavelength_m if ln.kind == "speed_dependent" else ln.frequency_hz
        if any(m.kind == ln.kind and abs((m.wavelength_m if m.kind == "speed_dependent" else m.frequency_hz)
                                         / key - 1) < 0.02 for m in merged):
            continue
        merged.append(ln)
    return sorted(merged, key=lambda x: (x.kind, x.frequency_hz or 0))
