"""Track flexibility from the axle boxes' spectra at different speeds.

On a rigid rail a wheelset follows the rail's level, so its vertical acceleration PSD at
speed v is

    P(f; v) = (2 pi f)^4 S(kappa) / v,   kappa = f / v,

with S the level's wavenumber spectrum: the spectra of all speeds *collapse* onto one
S(kappa). A wheelset on a flexible track (rail pads, sleepers, ballast: the level being the
support's geometry) moves with the transmissibility of its mass on the track spring,

    |T(f)|^2 = (1 + (2 zeta r)^2) / ((1 - r^2)^2 + (2 zeta r)^2),   r = f / f_t,

fixed in frequency, so the collapse fails in a way that moves through the wavenumber
spectrum with speed. The model here fits log S(kappa) as a piecewise-linear function of
log kappa (knots every ``knot_decades``) by weighted linear least squares, with T = 1
(baseline) or with (f_t, zeta) searched on a grid and refined; the error is the mean
squared log10 misfit. Both axle-box means are fitted with one S (they run over the same
rail). Lines fixed in wavenumber (sleepers, welds) collapse either way.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.optimize

from .records import Statistics

CHANNELS = ("axle1_mean", "axle2_mean")
#: Variance of log10 of a mean of K periodogram bins is about this / K: a bin of a Gaussian
#: signal is exponentially distributed, and var(ln X) of a mean of K of them is 1 / K for
#: large K, i.e. 1 / (K ln(10)^2) in log10.
LOG10_BIN_VARIANCE = 0.1886


@dataclass(frozen=True, kw_only=True)
class TrackSettings:
    """The track fit's search: knot spacing of log S(kappa) and the ranges of the track's
    resonance and damping."""

    knot_decades: float = 0.02  # fine enough to follow lines fixed in wavenumber (sleepers, welds)
    f_t_range: tuple[float, float] = (8.0, 100.0)  # [Hz] track resonance searched
    zeta_range: tuple[float, float] = (0.03, 0.6)  # damping ratio searched
    band: tuple[float, float] = (2.0, 60.0)  # [Hz]: below, the axle boxes' SNR is poor

    def __post_init__(self):
        if not self.knot_decades > 0:
            raise ValueError(f"TrackSettings.knot_decades must be positive, got {self.knot_decades}")
        for name in ("f_t_range", "zeta_range", "band"):
            lo, hi = getattr(self, name)
            if not 0 < lo < hi:
                raise ValueError(f"TrackSettings.{name} must be (low, high) with 0 < low < high, got {(lo, hi)}")


def transmissibility2(f: np.ndarray, f_t: float, zeta: float) -> np.ndarray:
    """|T(f)|^2 of a mass on a track of resonance ``f_t`` [Hz] and damping ratio ``zeta``."""
    r = f / f_t
    return (1 + (2 * zeta * r) ** 2) / ((1 - r * r) ** 2 + (2 * zeta * r) ** 2)


@dataclass(frozen=True)
class _Data:
    y: np.ndarray  # log10 of (P v / (2 pi f)^4)
    w: np.ndarray
    var: np.ndarray  # sampling variance of y (a sum of K periodogram bins: LOG10_BIN_VARIANCE / K)
    logk: np.ndarray
    f: np.ndarray
    channel: np.ndarray  # 0 / 1


def _collect(stats: Statistics, keys, settings: TrackSettings) -> _Data:
    f = stats.centres
    bw = np.diff(stats.edges)
    sel = (f >= settings.band[0]) & (f <= settings.band[1])
    ys, ws, ks, fs, cs, vs = [], [], [], [], [], []
    nbins = np.diff(stats.edges) * stats.segment_s  # periodogram bins per band and segment
    for key in stats.ordered(keys):
        v = key[1] + 0.5 * _bin_width(stats)
        for c, name in enumerate(CHANNELS):
            i = stats.channels.index(name)
            P = stats.S[key][:, i, i].real / stats.seconds[key] / bw
            ok = sel & (P > 0)
            ys.append(np.log10(P[ok] * v / (2 * np.pi * f[ok]) ** 4))
            ws.append(np.full(ok.sum(), stats.seconds[key]))
            ks.append(np.log10(f[ok] / v))
            fs.append(f[ok])
            cs.append(np.full(ok.sum(), c))
            vs.append(LOG10_BIN_VARIANCE / np.maximum(nbins[ok] * stats.seconds[key] / stats.segment_s, 1.0))
    y, w, k, f_, c_, var = (np.concatenate(a) for a in (ys, ws, ks, fs, cs, vs))
    return _Data(y, w, var, k, f_, c_)


def _bin_width(stats: Statistics) -> float:
    """The speed bins' width [m/s] as their spacing shows it (2.5 with one bin)."""
    bins = stats.speed_bins
    return float(np.min(np.diff(bins))) if len(bins) > 1 else 2.5


def _hats(logk: np.ndarray, knots: np.ndarray):
    """Piecewise-linear (hat) basis on ``knots``: each point weighs knot i by 1 - t and
    knot i + 1 by t. Returns (i, t)."""
    x = np.clip(logk, knots[0], knots[-1])
    i = np.clip(np.searchsorted(knots, x) - 1, 0, knots.size - 2)
    return i, (x - knots[i]) / (knots[i + 1] - knots[i])


def _evaluate(coef: np.ndarray, logk: np.ndarray, knots: np.ndarray) -> np.ndarray:
    i, t = _hats(logk, knots)
    return coef[i] * (1 - t) + coef[i + 1] * t


class _Normal:
    """Weighted least squares of hat-basis coefficients: the normal matrix is tridiagonal
    and does not depend on the data values, so it is formed once per data set and each
    fit is one banded solve."""

    def __init__(self, d: _Data, knots: np.ndarray):
        self.d, self.knots = d, knots
        self.i, self.t = _hats(d.logk, knots)
        n, w, i, t = knots.size, d.w, self.i, self.t
        diag = np.bincount(i, w * (1 - t) ** 2, n) + np.bincount(i + 1, w * t * t, n)
        off = np.bincount(i, w * (1 - t) * t, n)[:-1]
        diag += 1e-9 * diag.mean()
        self.ab = np.zeros((3, n))
        self.ab[0, 1:], self.ab[1], self.ab[2, :-1] = off, diag, off
        self.wsum = float(np.sum(w))

    def solve(self, y: np.ndarray):
        n, w, i, t = self.knots.size, self.d.w, self.i, self.t
        rhs = np.bincount(i, w * y * (1 - t), n) + np.bincount(i + 1, w * y * t, n)
        coef = scipy.linalg.solve_banded((1, 1), self.ab, rhs)
        r = coef[i] * (1 - t) + coef[i + 1] * t - y
        return coef, float(np.sum(w * r * r) / self.wsum)


@dataclass(frozen=True)
class TrackFit:
    """The axle boxes' common level spectrum log10 S(kappa) on ``knots`` (log10 kappa, kappa
    in 1/m), on a rigid rail or through a track of resonance ``f_t`` and damping ``zeta``."""

    f_t: float | None  # [Hz]; None: rigid (baseline)
    zeta: float | None
    knots: np.ndarray
    coef: np.ndarray
    error_train: float

    def to_json(self) -> dict:
        return {"track_resonance_hz": self.f_t, "damping_ratio": self.zeta}


def _solve(ne: _Normal, f_t, zeta):
    d = ne.d
    y = d.y if f_t is None else d.y - np.log10(transmissibility2(d.f, f_t, zeta))
    return ne.solve(y)


def fit_track(stats: Statistics, train_keys, *, flexible: bool,
              settings: TrackSettings = TrackSettings()) -> TrackFit:
    """The level spectrum fitted to the axle boxes' spectra of ``train_keys``, rigid or
    (``flexible``) with the track resonance and damping searched on a grid and refined."""
    d = _collect(stats, train_keys, settings)
    knots = np.arange(d.logk.min(), d.logk.max() + settings.knot_decades, settings.knot_decades)
    ne = _Normal(d, knots)
    if not flexible:
        coef, err = _solve(ne, None, None)
        return TrackFit(None, None, knots, coef, err)
    lf = np.log(settings.f_t_range)
    lz = np.log(settings.zeta_range)
    best = None
    for a in np.linspace(lf[0], lf[1], 40):
        for b in np.linspace(lz[0], lz[1], 8):
            _, err = _solve(ne, np.exp(a), np.exp(b))
            if best is None or err < best[0]:
                best = (err, a, b)
    sol = scipy.optimize.minimize(lambda x: _solve(ne, np.exp(x[0]), np.exp(x[1]))[1], best[1:],
                                  method="L-BFGS-B", bounds=[tuple(lf), tuple(lz)])
    f_t, zeta = float(np.exp(sol.x[0])), float(np.exp(sol.x[1]))
    coef, err = _solve(ne, f_t, zeta)
    return TrackFit(f_t, zeta, knots, coef, err)


def track_error(stats: Statistics, keys, fit: TrackFit, settings: TrackSettings = TrackSettings()) -> np.ndarray:
    """Mean squared log10 misfit per axle-box channel over ``keys`` with S from ``fit``, less
    the spectra's own sampling variance (so a perfect model scores about 0). A constant
    offset of log S per channel is refitted (the held-out runs' rail is the same line,
    but its level spectrum is estimated, not known)."""
    d = _collect(stats, keys, settings)
    y = d.y if fit.f_t is None else d.y - np.log10(transmissibility2(d.f, fit.f_t, fit.zeta))
    r = _evaluate(fit.coef, d.logk, fit.knots) - y
    seen = (d.logk >= fit.knots[0]) & (d.logk <= fit.knots[-1])  # no extrapolation in wavenumber
    out = []
    for c in range(len(CHANNELS)):
        m = (d.channel == c) & seen
        rc = r[m] - np.average(r[m], weights=d.w[m])
        out.append(float(np.sum(d.w[m] * (rc * rc - d.var[m])) / np.sum(d.w[m])))
    return np.array(out)


def speed_folds(stats: Statistics, keys) -> list[tuple[set, set]]:
    """Folds over speed: the speed bins in three contiguous groups of about equal data
    (low, middle, high; two with two bins), each predicted from the others. A
    speed-dependent model claims exactly this: what the axle boxes see at speeds it was not
    fitted at. Each fold is fitted on two groups, so it spans a share of the speed range
    wide enough to tell a resonance fixed in frequency from the rail's spectrum (a half of
    the speeds can be too narrow to). Falls back to [] with one speed bin."""
    keys = set(keys)
    bins = sorted({k[1] for k in keys})
    if len(bins) < 2:
        return []
    n = min(3, len(bins))
    secs = np.array([stats.seconds_of({k for k in keys if k[1] == b}) for b in bins])
    share = np.cumsum(secs) / secs.sum()
    group = np.minimum((share - 0.5 * secs / secs.sum()) * n, n - 1).astype(int)  # by each bin's data midpoint
    group_of = dict(zip(bins, group))
    folds = []
    for g in range(n):
        held = {k for k in keys if group_of[k[1]] == g}
        if held and held != keys:
            folds.append((keys - held, held))
    return folds


def track_cross_validation(stats: Statistics, keys, settings: TrackSettings = TrackSettings()):
    """(rigid error, flexible error) per channel, summed over the speed folds."""
    before, after = 0.0, 0.0
    for fit_keys, test_keys in speed_folds(stats, keys):
        rigid = fit_track(stats, fit_keys, flexible=False, settings=settings)
        flexible = fit_track(stats, fit_keys, flexible=True, settings=settings)
        before = before + track_error(stats, test_keys, rigid, settings)
        after = after + track_error(stats, test_keys, flexible, settings)
    return np.atleast_1d(before), np.atleast_1d(after)


def collapse_shift(stats: Statistics, keys, settings: TrackSettings = TrackSettings()):
    """What a track would do to the rigid rail's collapse held out by speed: a function of
    (f_t [Hz], zeta) giving, per axle-box channel, the increase of the rigid model's
    held-out misfit (:func:`speed_folds`, :func:`track_error`) if the spectra carried that
    track's transmissibility, and that increase's sampling standard deviation; and the
    rigid model's measured held-out misfit per channel (summed over the folds, as
    :func:`track_cross_validation` does). The data are collected and the normal matrices
    formed once, so each call is a few banded solves. None with one speed bin."""
    folds, floor = [], np.zeros(len(CHANNELS))
    for fit_keys, test_keys in speed_folds(stats, keys):
        d, t = _collect(stats, fit_keys, settings), _collect(stats, test_keys, settings)
        knots = np.arange(d.logk.min(), d.logk.max() + settings.knot_decades, settings.knot_decades)
        ne = _Normal(d, knots)
        coef, _ = ne.solve(d.y)
        seen = (t.logk >= knots[0]) & (t.logk <= knots[-1])
        folds.append((ne, d, t, knots, _evaluate(coef, t.logk, knots) - t.y, seen))
        floor += track_error(stats, test_keys, TrackFit(None, None, knots, coef, 0.0), settings)

    def shift(f_t: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
        up, var = np.zeros(len(CHANNELS)), np.zeros(len(CHANNELS))
        for ne, d, t, knots, r0, seen in folds:
            coef, _ = ne.solve(d.y + np.log10(transmissibility2(d.f, f_t, zeta)))
            r = _evaluate(coef, t.logk, knots) - t.y - np.log10(transmissibility2(t.f, f_t, zeta))
            for c in range(len(CHANNELS)):
                m = (t.channel == c) & seen
                w = t.w[m] / np.sum(t.w[m])
                a, b = r0[m] - np.sum(w * r0[m]), r[m] - np.sum(w * r[m])
                up[c] += np.sum(w * (b * b - a * a))
                # the shift's cross term with the spectra's sampling scatter (variance t.var)
                var[c] += np.sum(w * w * 4 * (b - a) ** 2 * t.var[m])
        return up, np.sqrt(var)

    return (floor, shift) if folds else None
