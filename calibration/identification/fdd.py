"""Segmental frequency domain decomposition (in-service seed, section 5).

Classical FDD (Brincker et al. 2001) takes the cross-spectral density (CSD) matrix of
simultaneously measured channels, decomposes it by SVD at every frequency and picks the
peaks of the first singular value. The seed's *segmental* variant draws random 2 km
segments from many journeys, runs one FDD per segment and sums the singular values, so
that what the track, the speed and the noise put into one segment averages out while the
vehicle's own frequencies add up.

Pipeline here (pure functions of arrays; :func:`segmental_fdd` streams the runs):

1. :func:`plan_segments` draws segment start distances over all runs from their
   distance ranges only (one cheap read per run), more than needed, in a seeded order.
2. :func:`segmental_fdd` reads each run once; for each planned segment it checks the
   segment lies in one gap-free block with every analysis channel valid, band-passes it
   (zero-phase Butterworth, seed: 6th order 0.25-25 Hz) with filter padding from the
   surrounding data, resamples it to ``fs_analysis``, and forms the Welch CSD matrix.
   Irregularly sampled runs (allowed by the campaign format) first have each gap-free block
   put on a uniform grid (:func:`calibration.signals.resample.regular_run`).
3. Each segment's CSD is normalised to unit in-band power before summation (the seed
   sums raw singular values, which lets the fastest, loudest segments dominate).
4. Singular values (and the CSD matrices, for mode shapes) are summed over the first
   ``n_fdds`` valid segments of each analysis.

Units: frequencies in Hz; the summed singular values are normalised (1/Hz).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
import scipy.ndimage
import scipy.signal

from .. import checks
from ..data.campaign import Campaign, CampaignMeta, Run
from ..signals.filters import SEED_BAND_HZ, SEED_ORDER, bandpass
from ..signals.peaks import parabolic_shift
from ..signals.resample import is_regular, regular_run, to_uniform_grid


@dataclass(frozen=True)
class FDDSettings:
    """Run settings of the segmental FDD (keyword-only use recommended)."""

    segment_length: float = 2000.0  # [m] seed: 2 km
    band: tuple[float, float] = SEED_BAND_HZ  # [Hz]
    order: int = SEED_ORDER
    fs_analysis: float = 100.0  # [Hz] after band-pass and resampling
    welch_s: float = 20.48  # [s] Welch segment length (nperseg = welch_s x fs_analysis)
    overlap: float = 0.5  # fraction of a Welch segment shared with the next
    nfft_factor: int = 4  # zero padding of each Welch segment (finer peak location)
    # [s] filter padding taken from surrounding valid data: the 0.25 Hz high-pass section of
    # the seed's band-pass rings with a 2.4 s e-fold time after an edge; 20 s leave e^-8
    pad: float = 20.0
    normalise: bool = True
    redraws: int = 10  # a segment with a gap or bad samples is redrawn from the same run
    seed: int = 0

    def __post_init__(self):
        checks.positive(self, "segment_length", "fs_analysis", "welch_s", "pad")
        checks.whole(self, "order", "nfft_factor")
        checks.whole(self, "redraws", minimum=0)
        checks.fraction(self, "overlap")
        if not 0 < self.band[0] < self.band[1] < self.fs_analysis / 2:
            raise ValueError(f"FDDSettings.band {self.band} Hz must lie inside (0, fs_analysis/2)")


@dataclass(frozen=True)
class Analysis:
    """One FDD analysis: which channels, how many segment FDDs are summed (seed Table 3)."""

    name: str
    channels: tuple[str, ...]
    n_fdds: int
    role: str  # 'axle_bounce' | 'bogie_bounce' | 'bogie_pitch' | 'system'
    body: str = ""


@dataclass(frozen=True)
class CentreAcceleration:
    """Vertical acceleration at a bogie centre from an off-centre accelerometer and a pitch
    gyro on the same body: z''_c = z''(x_s) + (x_s - x_c) theta'' (positive pitch moves the
    front down, campaign-format.md). Removes the pitch the seed saw in its bogie accelerometer."""

    name: str
    accelerometer: str
    gyro: str
    lever: float  # [m] x_s - x_c

    def evaluate(self, run: Run, i0: int, i1: int, d: np.ndarray):
        acc, ok_a = _raw(run, self.accelerometer, i0, i1)
        rate, ok_g = _raw(run, self.gyro, i0, i1)
        # the central difference at a sample reads its neighbours: a bad gyro sample spoils three
        ok_g = ok_g & np.concatenate([[True], ok_g[:-1]]) & np.concatenate([ok_g[1:], [True]])
        return acc + self.lever * np.gradient(np.nan_to_num(rate), run.time[i0:i1]), ok_a & ok_g


@dataclass(frozen=True)
class RailInput:
    """Rail acceleration under a bogie from its axle-box accelerometers (wheelsets on the
    rail): bounce = mean over the bogie's axle boxes [m/s^2], pitch = (rear - front axle
    mean) / (2 L_b) [rad/s^2] (a point at x moves z - x theta, so a rail lower under the
    front wheelset is a positive pitch), optionally seen ``delay`` metres later, i.e. under a
    bogie that follows at that distance (the trailing bogie runs over the same rail)."""

    name: str
    front: tuple[str, ...]
    rear: tuple[str, ...]
    kind: str  # 'bounce' | 'pitch'
    semi_wheelbase: float  # [m]
    delay: float = 0.0  # [m]

    def _value(self, run: Run, i0: int, i1: int):
        parts, ok = {}, np.ones(i1 - i0, bool)
        for group, names in (("front", self.front), ("rear", self.rear)):
            vals = []
            for n in names:
                x, v = _raw(run, n, i0, i1)
                vals.append(x)
                ok &= v
            parts[group] = np.mean(vals, axis=0)
        if self.kind == "bounce":
            return 0.5 * (parts["front"] + parts["rear"]), ok
        return (parts["rear"] - parts["front"]) / (2 * self.semi_wheelbase), ok

    def evaluate(self, run: Run, i0: int, i1: int, d: np.ndarray):
        if self.delay == 0.0:
            return self._value(run, i0, i1)
        # the value at distance d - delay, from samples earlier in the same block
        block = next((a, b) for a, b in run.blocks if a <= i0 < b)
        j0 = max(block[0], int(np.searchsorted(d, d[i0] - self.delay)) - 2)
        x, ok = self._value(run, j0, i1)
        target = d[i0:i1] - self.delay
        out = np.interp(target, d[j0:i1], x)
        bad_src = np.interp(target, d[j0:i1], (~ok).astype(float)) > 0
        return out, ~bad_src & (target >= d[j0])


def _raw(run: Run, name: str, i0: int, i1: int):
    return run.channels[name][i0:i1], run.valid[name][i0:i1]


def derived_channels(meta: CampaignMeta) -> dict:
    """Channels computed from declared sensors and the known geometry (name -> channel)."""
    spacing = meta.geometry.get("bogie_semi_spacing")
    semi_wb = meta.geometry.get("semi_wheelbase")
    out: dict = {}
    if spacing is None:
        return out
    for body, xc in (("bogie1", spacing), ("bogie2", -spacing)):
        accs = [s for s in meta.sensors if s.body == body and s.quantity == "acceleration" and s.direction == "z"]
        gyros = [s for s in meta.sensors if s.body == body and s.quantity == "angular_velocity"
                 and s.direction == "pitch"]
        if accs and gyros:
            c = CentreAcceleration(f"{body}_centre_acc_z", accs[0].name, gyros[0].name, accs[0].position[0] - xc)
            out[c.name] = c
    if semi_wb is None:
        return out
    acc_z = [s for s in meta.sensors if s.quantity == "acceleration" and s.direction == "z"]
    # leading bogie: axles 1 (front) and 2 (rear); trailing: 3 and 4
    for bogie, (fa, ra) in (("bogie1", ("axle1", "axle2")), ("bogie2", ("axle3", "axle4"))):
        front = tuple(s.name for s in acc_z if s.body == fa)
        rear = tuple(s.name for s in acc_z if s.body == ra)
        if front and rear:
            for kind in ("bounce", "pitch"):
                c = RailInput(f"rail_{kind}_{bogie}", front, rear, kind, semi_wb)
                out[c.name] = c
            if bogie == "bogie1":  # bogie 2 runs over the same rail 2 L_v later
                c = RailInput("rail_bounce_bogie2_from_bogie1", front, rear, "bounce", semi_wb, 2 * spacing)
                out[c.name] = c
    return out


def plan_analyses(meta: CampaignMeta) -> tuple[Analysis, ...]:
    """Seed Table 3, built from the sensors a campaign declares."""
    derived = derived_channels(meta)
    vz = {n.split("_")[0]: c for n, c in derived.items() if isinstance(c, CentreAcceleration)}
    out = []
    acc_z = [s for s in meta.sensors if s.quantity == "acceleration" and s.direction == "z"]
    for axle in ("axle1", "axle2", "axle3", "axle4"):
        chans = tuple(s.name for s in acc_z if s.body == axle)
        if chans:
            out.append(Analysis(f"{axle}_bounce", chans, 20, "axle_bounce", axle))
    for bogie in ("bogie1", "bogie2"):
        if bogie in vz:
            out.append(Analysis(f"{bogie}_bounce", (vz[bogie].name,), 50, "bogie_bounce", bogie))
        else:
            chans = tuple(s.name for s in acc_z if s.body == bogie)[:1]
            if chans:
                out.append(Analysis(f"{bogie}_bounce", chans, 50, "bogie_bounce", bogie))
        gyro = [s.name for s in meta.sensors if s.body == bogie and s.quantity == "angular_velocity"
                and s.direction == "pitch"]
        if gyro:
            out.append(Analysis(f"{bogie}_pitch", (gyro[0],), 50, "bogie_pitch", bogie))
    system = tuple(s.name for s in acc_z if s.body.startswith(("axle", "bogie", "carbody")))
    if len(system) > 1:
        out.append(Analysis("system", system, 20, "system"))
    return tuple(out)


@dataclass(frozen=True)
class Segment:
    run_id: str
    start: float  # [m]
    end: float  # [m]


@dataclass(frozen=True)
class SegmentOutcome:
    segment: Segment
    used: bool
    reason: str = ""
    mean_speed: float = float("nan")  # [m/s]


@dataclass(frozen=True)
class FDDResult:
    """Summed FDD of one analysis. ``singular_values`` is (n_channels, n_freq), descending."""

    analysis: Analysis
    frequency: np.ndarray  # [Hz]
    singular_values: np.ndarray
    csd: np.ndarray  # (n_freq, n_ch, n_ch), summed normalised CSD
    n_used: int
    speeds: np.ndarray  # [m/s] mean speed of each used segment
    csd_parts: dict = field(default_factory=dict)  # run id -> that run's share of the sum (jackknife)


@dataclass(frozen=True)
class SegmentalFDD:
    settings: FDDSettings
    results: dict[str, FDDResult]
    outcomes: tuple[SegmentOutcome, ...] = field(repr=False)


def distance_axis(distance, speed, time, *, blend: float = 60.0) -> np.ndarray:
    """Distance [m] along the line, complementary-filtered: over less than ``blend``
    seconds the increments come from the speed column (GPS Doppler: precise over metres),
    over longer times the position follows the distance column (GPS fixes: right on
    average but wandering by metres), so a biased speed cannot drift away. With only
    one of the two columns, that one."""
    if speed is None:
        return distance
    v = speed.copy()
    bad = ~np.isfinite(v)
    if bad.any():
        v[bad] = np.interp(np.flatnonzero(bad), np.flatnonzero(~bad), v[~bad])
    d = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(time))])
    if distance is None:
        return d
    n = max(1, int(round(blend / float(np.median(np.diff(time))))))
    correction = scipy.ndimage.uniform_filter1d(distance - d, size=min(n, d.size), mode="nearest")
    return d + correction


def plan_segments(campaign: Campaign, n_needed: int, settings: FDDSettings) -> list[Segment]:
    """``n_needed`` random segments over all runs, proportional to run length, seeded.

    An analysis summing N FDDs uses the first N of them, so every analysis sees a random
    draw over all runs."""
    rng = np.random.default_rng(settings.seed)
    ranges = []
    for path in campaign.run_paths:
        cols = campaign.run_summary(path)
        d = distance_axis(cols.get("distance"), cols.get("speed"), cols["time"])
        d = d[np.isfinite(d)]
        if d.size and d[-1] - d[0] > settings.segment_length:
            ranges.append((path.stem, float(d[0]), float(d[-1])))
    if not ranges:
        return []
    lengths = np.array([b - a - settings.segment_length for _, a, b in ranges])
    which = rng.choice(len(ranges), size=n_needed, p=lengths / lengths.sum())
    out = []
    for k in which:
        run_id, a, b = ranges[k]
        start = rng.uniform(a, b - settings.segment_length)
        out.append(Segment(run_id, float(start), float(start + settings.segment_length)))
    return out


def channel_matrix(run: Run, names: tuple[str, ...], derived: dict, i0: int, i1: int, d: np.ndarray):
    """(n_ch, N) SI data and validity for declared or derived channels over samples [i0, i1);
    ``d`` is the run's distance axis [m]."""
    data, ok = [], np.ones(i1 - i0, bool)
    for name in names:
        x, v = derived[name].evaluate(run, i0, i1, d) if name in derived else _raw(run, name, i0, i1)
        data.append(x)
        ok &= v
    return np.vstack(data), ok


def welch_frames(x: np.ndarray, fs: float, settings: FDDSettings) -> tuple[np.ndarray, np.ndarray, float]:
    """Windowed FFT frames (n_win, n_ch, n_freq) of the rows of x, their frequencies [Hz]
    and the one-sided density scale that turns X_i X_j^* into a CSD [units^2/Hz]."""
    nper = int(round(settings.welch_s * fs))
    if x.shape[1] < nper:
        raise ValueError(f"segment of {x.shape[1]} samples is shorter than one Welch window ({nper})")
    hop = max(1, int(round(nper * (1 - settings.overlap))))
    nfft = 1 << (nper * settings.nfft_factor - 1).bit_length()
    win = scipy.signal.windows.hann(nper, sym=False)
    starts = np.arange(0, x.shape[1] - nper + 1, hop)
    frames = np.stack([x[:, s:s + nper] for s in starts])  # (n_win, n_ch, nper)
    frames = frames - frames.mean(axis=2, keepdims=True)
    X = np.fft.rfft(frames * win, n=nfft, axis=2)
    return X, np.fft.rfftfreq(nfft, 1 / fs), 2.0 / (fs * np.sum(win**2))


def csd_from_frames(X: np.ndarray, scale: float, rows=None, *, full_spectrum: bool = True) -> np.ndarray:
    """Welch CSD matrix (n_freq, n_ch, n_ch) from :func:`welch_frames` output (optionally of
    some rows). With ``full_spectrum`` the first and last bins are DC and Nyquist, which a
    one-sided density does not double; pass False for a slice that excludes both."""
    if rows is not None:
        X = X[:, rows]
    G = np.einsum("wif,wjf->fij", X, np.conj(X)) * (scale / X.shape[0])
    if full_spectrum:
        G[0] /= 2
        G[-1] /= 2
    return G


def segment_csd(x: np.ndarray, fs: float, settings: FDDSettings) -> tuple[np.ndarray, np.ndarray]:
    """Welch CSD matrix (n_freq, n_ch, n_ch) of the rows of x [units^2/Hz], one-sided."""
    X, f, scale = welch_frames(x, fs, settings)
    return f, csd_from_frames(X, scale)


def _prepare_segment(run: Run, d: np.ndarray, seg: Segment, names, derived, settings: FDDSettings,
                     run_rate: float):
    """Band-passed, resampled data of channels ``names`` over a segment, or None and why."""
    i0, i1 = int(np.searchsorted(d, seg.start)), int(np.searchsorted(d, seg.end))
    if i1 - i0 < 10:
        return None, "segment outside the run's distance range"
    block = next(((a, b) for a, b in run.blocks if a <= i0 < b), None)
    if block is None or i1 > block[1]:
        return None, "segment crosses a gap in the recording"
    fs = 1.0 / float(np.median(np.diff(run.time[i0:i1])))
    if abs(fs / run_rate - 1) < 1e-6:
        fs = run_rate  # the declared rate, exactly
    padn = int(settings.pad * fs)
    p0, p1 = max(block[0], i0 - padn), min(block[1], i1 + padn)
    x, ok = channel_matrix(run, names, derived, p0, p1, d)
    if not ok[i0 - p0:i1 - p0].all():
        return None, "missing or clipped samples inside the segment"
    # padding only from valid data: trim the padding at the first invalid sample
    bad = np.flatnonzero(~ok)
    lo = bad[bad < i0 - p0].max() + 1 if (bad < i0 - p0).any() else 0
    hi = bad[bad >= i1 - p0].min() if (bad >= i1 - p0).any() else p1 - p0
    x = x[:, lo:hi]
    t = run.time[p0 + lo:p0 + hi]
    frac = Fraction(settings.fs_analysis / fs).limit_denominator(1000)
    if not is_regular(t, fs) or abs(fs * frac / settings.fs_analysis - 1) > 1e-9:
        # Irregular sampling (the time column is authoritative), or a rate with no small
        # rational ratio to fs_analysis: spline the block onto a grid at a multiple of
        # fs_analysis near the recorded rate, so that every segment ends on exactly
        # fs_analysis and all share one frequency grid (their spectra are summed).
        ratio = max(1, round(fs / settings.fs_analysis))
        fs = settings.fs_analysis * ratio
        t, x = to_uniform_grid(t, x, fs, axis=1)
        frac = Fraction(1, ratio)
    x = x - x.mean(axis=1, keepdims=True)
    xf = bandpass(x, fs, settings.band, order=settings.order, axis=1)
    xr = scipy.signal.resample_poly(xf, frac.numerator, frac.denominator, axis=1) if frac != 1 else xf
    fs_a = settings.fs_analysis
    # the validated samples [i0, i1) by their times, on the resampled grid
    a = int(round((run.time[i0] - t[0]) * fs_a))
    b = min(xr.shape[1], int(round((run.time[i1 - 1] - t[0]) * fs_a)) + 1)
    speed = float((seg.end - seg.start) / (run.time[i1 - 1] - run.time[i0]))
    if a < 0 or b - a < int(round(settings.welch_s * fs_a)):
        return None, "segment shorter than one Welch window"
    return (xr[:, a:b], fs_a, speed), ""


def fdd_peaks(f: np.ndarray, sv1: np.ndarray, prominence: float, *, smooth_hz: float = 0.1,
              span: float = 1.5, ripple_factor: float = 5.0) -> list[tuple[float, float]]:
    """(frequency [Hz], prominence [decades]) of the peaks of a summed first singular value.

    The log spectrum is smoothed over ``smooth_hz``. A peak's prominence is measured
    within [f / span, f * span] (a damped mode is as wide as its frequency times its
    damping, and a broad rising trend is not a peak) and must exceed both
    ``prominence`` and ``ripple_factor`` times the spectrum's own ripple (robust spread
    of the log spectrum about its 1 Hz running mean), so the threshold follows how
    many FDDs were summed. A peak whose neighbourhood reaches past the analysed band is
    not reported: near the band edges a rising spectrum meets the band-pass filter's
    skirt and makes a maximum that is the filter's, not the vehicle's.
    """
    df = f[1] - f[0]
    y = np.log10(np.maximum(sv1, 1e-300))
    ys = scipy.ndimage.uniform_filter1d(y, max(1, int(round(smooth_hz / df))), mode="nearest")
    trend = scipy.ndimage.uniform_filter1d(y, max(3, int(round(1.0 / df))), mode="nearest")
    ripple = 1.4826 * float(np.median(np.abs(ys - trend - np.median(ys - trend))))
    threshold = max(prominence, ripple_factor * ripple)
    out = []
    for i in scipy.signal.find_peaks(ys)[0]:
        if f[i] / span < f[0] or f[i] * span > f[-1]:
            continue
        lo = int(np.searchsorted(f, f[i] / span))
        hi = int(np.searchsorted(f, f[i] * span))
        left, right = ys[lo:i + 1], ys[i:hi]
        if left.max() > ys[i] or right.max() > ys[i] or lo >= i or hi <= i + 1:
            continue  # not the highest point of its neighbourhood, or at the band edge
        prom = ys[i] - max(left.min(), right.min())
        if prom >= threshold:
            out.append((float(f[i] + parabolic_shift(y, int(i)) * df), float(prom)))
    return out


class _Sum:
    """Running sums of one analysis: singular values and CSD matrices over segments, the
    CSD also per run (journey), for delete-one-journey jackknife estimates of spread."""

    def __init__(self, analysis: Analysis):
        self.analysis = analysis
        self.sv = None
        self.G = None
        self.parts: dict = {}
        self.speeds: list[float] = []

    def add(self, G: np.ndarray, speed: float, run_id: str) -> None:
        sv = np.linalg.svd(G, compute_uv=False, hermitian=True).T  # (n_ch, n_f)
        self.sv = sv if self.sv is None else self.sv + sv
        self.G = G.copy() if self.G is None else self.G + G
        self.parts[run_id] = G.copy() if run_id not in self.parts else self.parts[run_id] + G
        self.speeds.append(speed)


class SegmentalFDDAccumulator:
    """The streaming core of :func:`segmental_fdd`: feed runs in any order, one at a time."""

    def __init__(self, meta: CampaignMeta, analyses: tuple[Analysis, ...], plan: list[Segment],
                 settings: FDDSettings):
        self.meta, self.analyses, self.settings = meta, analyses, settings
        self.derived = derived_channels(meta)
        self.union = tuple(dict.fromkeys(c for a in analyses for c in a.channels))
        self.rows = {a.name: [self.union.index(c) for c in a.channels] for a in analyses}
        self.by_run: dict[str, list[tuple[int, Segment]]] = {}
        for k, seg in enumerate(plan):
            self.by_run.setdefault(seg.run_id, []).append((k, seg))
        self.sums = {a.name: _Sum(a) for a in analyses}
        self.outcomes: dict[int, SegmentOutcome] = {}
        self.freq = None
        self.rng = np.random.default_rng(settings.seed + 1)

    def wants(self, run_id: str) -> bool:
        return run_id in self.by_run

    def add_run(self, run: Run) -> int:
        """Process the planned segments of this run; returns how many were used."""
        st = self.settings
        run = regular_run(run, self.meta.sampling_rate)
        d = distance_axis(run.distance, run.speed, run.time)
        used = 0
        for k, seg in self.by_run.get(run.run_id, []):
            prep, why = _prepare_segment(run, d, seg, self.union, self.derived, st, self.meta.sampling_rate)
            tries = 0
            while prep is None and tries < st.redraws and d[-1] - d[0] > st.segment_length:
                tries += 1  # a gap or bad samples: draw another segment from the same run
                start = float(self.rng.uniform(d[0], d[-1] - st.segment_length))
                seg = Segment(run.run_id, start, start + st.segment_length)
                prep, why = _prepare_segment(run, d, seg, self.union, self.derived, st, self.meta.sampling_rate)
            if prep is None:
                self.outcomes[k] = SegmentOutcome(seg, False, why)
                continue
            x, fs_a, speed = prep
            X, f, scale = welch_frames(x, fs_a, st)
            band = (f >= st.band[0]) & (f <= st.band[1])
            self.freq = f[band]
            for a in self.analyses:
                if k >= a.n_fdds:
                    continue
                G = csd_from_frames(X[:, :, band], scale, self.rows[a.name], full_spectrum=False)
                if st.normalise:
                    G = G / (np.real(np.trace(G, axis1=1, axis2=2)).sum() * (f[1] - f[0]))
                self.sums[a.name].add(G, speed, run.run_id)
            self.outcomes[k] = SegmentOutcome(seg, True, f"redrawn {tries} times" if tries else "", speed)
            used += 1
        return used

    def result(self) -> SegmentalFDD:
        results = {}
        for a in self.analyses:
            s = self.sums[a.name]
            if s.sv is None:
                continue
            results[a.name] = FDDResult(a, self.freq, s.sv, s.G, len(s.speeds), np.array(s.speeds), dict(s.parts))
        return SegmentalFDD(self.settings, results, tuple(self.outcomes[k] for k in sorted(self.outcomes)))


def segmental_fdd(campaign: Campaign, analyses: tuple[Analysis, ...] | None = None, *,
                  settings: FDDSettings = FDDSettings(), progress=None) -> SegmentalFDD:
    """Segmental FDD of a campaign, one run in memory at a time."""
    analyses = plan_analyses(campaign.meta) if analyses is None else analyses
    plan = plan_segments(campaign, max(a.n_fdds for a in analyses), settings)
    acc = SegmentalFDDAccumulator(campaign.meta, analyses, plan, settings)
    for path in campaign.run_paths:
        if acc.wants(path.stem):
            n = acc.add_run(campaign.read_run(path.stem))
            if progress:
                progress(f"FDD: {path.stem}, {n} segments")
    return acc.result()
