"""Track flexibility from the axle boxes' spectra at different speeds.

On a rigid rail a wheelset follows the rail's level, so its vertical acceleration PSD at
speed v is

    P(f; v) = (2 pi f)^4 S(kappa) / v,   kappa = f / v,

with S the level's wavenumber spectrum: the spectra of all speeds *collapse* onto one
S(kappa). On a flexible track the level is the irregularity at the wheel-rail contact, and
under the contact rail and sleepers (mass m_t) rest on the track's stiffness k and damping
(:class:`~calibration.models.car2d.CarExtras`' ``track_stiffness``). The wheelset then moves

    |T(f)|^2 = |Z_t / (Z_t + Z_w)|^2,   Z_t = m_t (w_t^2 - w^2 + 2 i zeta w_t w),

Z_w the vehicle's dynamic stiffness at the wheelset
(:func:`~calibration.models.car2d.wheelset_dynamic_stiffness`, from the baseline's
parameters) and f_t = w_t / 2 pi the track's own frequency. Above it T falls towards
m_t / (m_t + m_w), with a dip near f_t on a lightly damped track. T is fixed in frequency,
so the collapse fails in a way that moves through the wavenumber spectrum with speed.

The model here fits log S(kappa) as a piecewise-linear function of log kappa (knots every
``knot_decades``) by weighted linear least squares, with T = 1 (baseline) or with
(f_t, zeta, m_t / m_w) and the primary suspension's damping searched on a grid and
refined; the error is the mean squared log10 misfit. The primary damping is searched
because Z_w depends on it around the track's resonance and a baseline fitted to the bogie
and carbody seldom determines it (it is often a default), and a wrong one moves the
stiffness found (docs/methods/diagnosis-in-service.md). Both axle-box means are fitted
with one S (they run over the same rail). Lines fixed in wavenumber (sleepers, welds)
collapse either way.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
import scipy.optimize

from ...models.car2d import wheelset_dynamic_stiffness
from ...models.parameters import CarParameters

from .records import Statistics

CHANNELS = ("axle1_mean", "axle2_mean")
#: Variance of log10 of a mean of K periodogram bins is about this / K: a bin of a Gaussian
#: signal is exponentially distributed, and var(ln X) of a mean of K of them is 1 / K for
#: large K, i.e. 1 / (K ln(10)^2) in log10.
LOG10_BIN_VARIANCE = 0.1886


@dataclass(frozen=True, kw_only=True)
class TrackSettings:
    """The track fit's search: knot spacing of log S(kappa) and the ranges of the track's
    own frequency, its damping ratio and its mass over the wheelset's."""

    knot_decades: float = 0.02  # fine enough to follow lines fixed in wavenumber (sleepers, welds)
    f_t_range: tuple[float, float] = (8.0, 150.0)  # [Hz] the track mass's own frequency on its stiffness
    zeta_range: tuple[float, float] = (0.03, 0.8)  # its damping ratio
    mass_ratio_range: tuple[float, float] = (0.05, 1.5)  # track mass / wheelset mass
    primary_damping_range: tuple[float, float] = (0.02, 0.5)  # c_p / (2 sqrt(k_p m_w)), the wheelset's on its primary
    band: tuple[float, float] = (2.0, 60.0)  # [Hz]: below, the axle boxes' SNR is poor

    def __post_init__(self):
        if not self.knot_decades > 0:
            raise ValueError(f"TrackSettings.knot_decades must be positive, got {self.knot_decades}")
        for name in ("f_t_range", "zeta_range", "mass_ratio_range", "primary_damping_range", "band"):
            lo, hi = getattr(self, name)
            if not 0 < lo < hi:
                raise ValueError(f"TrackSettings.{name} must be (low, high) with 0 < low < high, got {(lo, hi)}")


def transmissibility2(f: np.ndarray, z_w: np.ndarray, f_t: float, zeta: float, mass: float) -> np.ndarray:
    """|T(f)|^2 of a wheelset of dynamic stiffness ``z_w`` [N/m] (complex, at ``f`` [Hz]) on a
    track of ``mass`` [kg] with its own frequency ``f_t`` [Hz] and damping ratio ``zeta``,
    the level being the irregularity at the contact (the module's docstring)."""
    w, wt = 2 * np.pi * f, 2 * np.pi * f_t
    z_t = mass * (wt * wt - w * w + 2j * zeta * wt * w)
    return np.abs(z_t / (z_t + z_w)) ** 2


@dataclass(frozen=True)
class _Data:
    y: np.ndarray  # log10 of (P v / (2 pi f)^4)
    w: np.ndarray
    var: np.ndarray  # sampling variance of y (a sum of K periodogram bins: LOG10_BIN_VARIANCE / K)
    logk: np.ndarray
    f: np.ndarray
    channel: np.ndarray  # 0 / 1
    cell: np.ndarray  # each point's (channel, frequency) cell: T is a function of the cell alone
    cell_f: np.ndarray  # [Hz] the cells' frequencies
    cell_channel: np.ndarray
    vehicle: CarParameters | None  # the wheelsets' vehicle; None: a rigid rail only
    z_w: np.ndarray | None  # its dynamic stiffness at each cell's wheelset [N/m]


def _z_w(d: _Data, c_p: float) -> np.ndarray:
    """The vehicle's dynamic stiffness at each cell's wheelset with primary damping ``c_p``
    [N s/m] (axle-box channel c is on wheelset c + 1)."""
    z_w = np.zeros(d.cell_f.size, complex)
    vehicle = replace(d.vehicle, c_p=float(c_p))
    for c in range(len(CHANNELS)):
        m = d.cell_channel == c
        z_w[m] = wheelset_dynamic_stiffness(vehicle, d.cell_f[m], c + 1)
    return z_w


def _collect(stats: Statistics, keys, settings: TrackSettings, vehicle: CarParameters | None = None) -> _Data:
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
    cells, cell = np.unique(np.stack([c_, f_]), axis=1, return_inverse=True)
    d = _Data(y, w, var, k, f_, c_, cell.ravel(), cells[1], cells[0].astype(int), vehicle, None)
    return d if vehicle is None else replace(d, z_w=_z_w(d, vehicle.c_p))


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
        self.reg = 1e-9 * diag.mean()
        diag += self.reg
        self.ab = np.zeros((3, n))
        self.ab[0, 1:], self.ab[1], self.ab[2, :-1] = off, diag, off
        self.wsum = float(np.sum(w))
        # sums over each (channel, frequency) cell, so that a fit through a transmissibility,
        # a function of the cell, costs a solve over knots and cells, not over every point
        m = d.cell_f.size
        self.cell_rhs = np.zeros((n, m))
        np.add.at(self.cell_rhs, (i, d.cell), w * (1 - t))
        np.add.at(self.cell_rhs, (i + 1, d.cell), w * t)
        self.cell_w = np.bincount(d.cell, w, m)
        self.cell_wy = np.bincount(d.cell, w * d.y, m)
        self.wyy = float(np.sum(w * d.y * d.y))
        self.rhs_y = np.bincount(i, w * d.y * (1 - t), n) + np.bincount(i + 1, w * d.y * t, n)

    def solve(self, y: np.ndarray):
        n, w, i, t = self.knots.size, self.d.w, self.i, self.t
        rhs = np.bincount(i, w * y * (1 - t), n) + np.bincount(i + 1, w * y * t, n)
        coef = scipy.linalg.solve_banded((1, 1), self.ab, rhs)
        r = coef[i] * (1 - t) + coef[i + 1] * t - y
        return coef, float(np.sum(w * r * r) / self.wsum)

    def solve_cells(self, offset: np.ndarray):
        """:meth:`solve` of the data less ``offset`` per cell, from the cells' sums: the misfit
        is sum w y'^2 - coef . rhs less the regularisation's share (the normal equations
        hold at the solution), y' = y - offset."""
        rhs = self.rhs_y - self.cell_rhs @ offset
        coef = scipy.linalg.solve_banded((1, 1), self.ab, rhs)
        wyy = self.wyy - 2 * self.cell_wy @ offset + self.cell_w @ (offset * offset)
        return coef, float(max(wyy - coef @ rhs - self.reg * (coef @ coef), 0.0) / self.wsum)


@dataclass(frozen=True)
class TrackFit:
    """The axle boxes' common level spectrum log10 S(kappa) on ``knots`` (log10 kappa, kappa
    in 1/m), on a rigid rail or through a track of own frequency ``f_t``, damping ratio
    ``zeta`` and ``mass`` under the wheelsets of ``vehicle`` (its primary damping the one
    found)."""

    f_t: float | None  # [Hz]; None: rigid (baseline)
    zeta: float | None
    knots: np.ndarray
    coef: np.ndarray
    error_train: float
    mass: float | None = None  # [kg] per wheelset
    vehicle: CarParameters | None = None

    @property
    def stiffness(self) -> float | None:
        """[N/m] per wheelset: the track mass on it has the frequency f_t."""
        return None if self.f_t is None else float((2 * np.pi * self.f_t) ** 2 * self.mass)

    def to_json(self) -> dict:
        return {"track_frequency_hz": self.f_t, "damping_ratio": self.zeta, "track_mass_kg": self.mass,
                "primary_damping_n_s_per_m": None if self.vehicle is None else self.vehicle.c_p}


def _log_t2_cells(d: _Data, f_t, zeta, mass, z_w=None) -> np.ndarray:
    return np.log10(transmissibility2(d.cell_f, d.z_w if z_w is None else z_w, f_t, zeta, mass))


def _log_t2(d: _Data, f_t, zeta, mass, z_w=None) -> np.ndarray:
    """log10 |T|^2 at each point."""
    return _log_t2_cells(d, f_t, zeta, mass, z_w)[d.cell]


def _solve(ne: _Normal, f_t, zeta, mass, z_w=None):
    if f_t is None:
        return ne.solve(ne.d.y)
    return ne.solve_cells(_log_t2_cells(ne.d, f_t, zeta, mass, z_w))


def search_ranges(vehicle: CarParameters, settings: TrackSettings) -> dict[str, tuple[float, float]]:
    """The physical ranges the flexible track is searched over under ``vehicle``: its own
    frequency [Hz], damping ratio, mass [kg] (``settings.mass_ratio_range`` of the
    wheelset's) and the primary damping [N s/m] (``settings.primary_damping_range`` of the
    wheelset's critical damping on its primary spring), keyed as :meth:`TrackFit.to_json`."""
    critical = 2 * np.sqrt(vehicle.k_p * vehicle.m_w)
    return {"track_frequency_hz": settings.f_t_range, "damping_ratio": settings.zeta_range,
            "track_mass_kg": tuple(float(vehicle.m_w * r) for r in settings.mass_ratio_range),
            "primary_damping_n_s_per_m": tuple(float(critical * r) for r in settings.primary_damping_range)}


def fit_track(stats: Statistics, train_keys, *, flexible: bool, settings: TrackSettings = TrackSettings(),
              vehicle: CarParameters | None = None) -> TrackFit:
    """The level spectrum fitted to the axle boxes' spectra of ``train_keys``, rigid or
    (``flexible``, under ``vehicle``'s wheelsets) with the track's own frequency, damping
    ratio and mass and the primary damping searched on a grid and refined."""
    if flexible and vehicle is None:
        raise ValueError("a flexible track is fitted under a vehicle: give its parameters")
    d = _collect(stats, train_keys, settings, vehicle if flexible else None)
    knots = np.arange(d.logk.min(), d.logk.max() + settings.knot_decades, settings.knot_decades)
    ne = _Normal(d, knots)
    if not flexible:
        coef, err = _solve(ne, None, None, None)
        return TrackFit(None, None, knots, coef, err)
    bounds = [tuple(np.log(r)) for r in search_ranges(vehicle, settings).values()]
    start, best = None, np.inf
    for lc in np.linspace(*bounds[3], 4):  # the track's grid at a few primary dampings
        z_w = _z_w(d, np.exp(lc))
        for x in itertools.product(*(np.linspace(lo, hi, n) for (lo, hi), n in zip(bounds[:3], (30, 6, 6)))):
            err = _solve(ne, *np.exp(x), z_w)[1]
            if err < best:
                start, best = np.array([*x, lc]), err

    def error(x):
        return _solve(ne, *np.exp(x[:3]), _z_w(d, np.exp(x[3])))[1]

    sol = scipy.optimize.minimize(error, start, method="L-BFGS-B", bounds=bounds)
    x = sol.x if sol.fun <= best else start
    f_t, zeta, mass, c_p = (float(v) for v in np.exp(x))
    found = replace(vehicle, c_p=c_p)
    coef, err = _solve(ne, f_t, zeta, mass, _z_w(d, c_p))
    return TrackFit(f_t, zeta, knots, coef, err, mass, found)


def track_error(stats: Statistics, keys, fit: TrackFit, settings: TrackSettings = TrackSettings()) -> np.ndarray:
    """Mean squared log10 misfit per axle-box channel over ``keys`` with S from ``fit``, less
    the spectra's own sampling variance (so a perfect model scores about 0). A constant
    offset of log S per channel is refitted (the held-out runs' rail is the same line,
    but its level spectrum is estimated, not known)."""
    d = _collect(stats, keys, settings, fit.vehicle if fit.f_t is not None else None)
    y = d.y if fit.f_t is None else d.y - _log_t2(d, fit.f_t, fit.zeta, fit.mass)
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


def track_cross_validation(stats: Statistics, keys, settings: TrackSettings = TrackSettings(), *,
                           vehicle: CarParameters):
    """(rigid error, flexible error) per channel, summed over the speed folds, and each
    fold's flexible fit (how far the track's parameters move between speed ranges)."""
    before, after, fits = 0.0, 0.0, []
    for fit_keys, test_keys in speed_folds(stats, keys):
        rigid = fit_track(stats, fit_keys, flexible=False, settings=settings)
        flexible = fit_track(stats, fit_keys, flexible=True, settings=settings, vehicle=vehicle)
        before = before + track_error(stats, test_keys, rigid, settings)
        after = after + track_error(stats, test_keys, flexible, settings)
        fits.append(flexible)
    return np.atleast_1d(before), np.atleast_1d(after), fits


def collapse_shift(stats: Statistics, keys, settings: TrackSettings = TrackSettings(), *,
                   vehicle: CarParameters):
    """What a track would do to the rigid rail's collapse held out by speed: a function of
    (f_t [Hz], zeta, mass [kg]) giving, per axle-box channel, the increase of the rigid
    model's held-out misfit (:func:`speed_folds`, :func:`track_error`) if the spectra
    carried that track's transmissibility under ``vehicle``'s wheelsets, and that
    increase's sampling standard deviation; and the rigid model's measured held-out misfit
    per channel (summed over the folds, as :func:`track_cross_validation` does). The data
    are collected and the normal matrices formed once, so each call is a few banded solves.
    None with one speed bin."""
    folds, floor = [], np.zeros(len(CHANNELS))
    for fit_keys, test_keys in speed_folds(stats, keys):
        d, t = _collect(stats, fit_keys, settings, vehicle), _collect(stats, test_keys, settings, vehicle)
        knots = np.arange(d.logk.min(), d.logk.max() + settings.knot_decades, settings.knot_decades)
        ne = _Normal(d, knots)
        coef, _ = ne.solve(d.y)
        seen = (t.logk >= knots[0]) & (t.logk <= knots[-1])
        folds.append((ne, d, t, knots, _evaluate(coef, t.logk, knots) - t.y, seen))
        floor += track_error(stats, test_keys, TrackFit(None, None, knots, coef, 0.0), settings)

    def shift(f_t: float, zeta: float, mass: float) -> tuple[np.ndarray, np.ndarray]:
        up, var = np.zeros(len(CHANNELS)), np.zeros(len(CHANNELS))
        for ne, d, t, knots, r0, seen in folds:
            coef, _ = ne.solve_cells(-_log_t2_cells(d, f_t, zeta, mass))
            r = _evaluate(coef, t.logk, knots) - t.y - _log_t2(t, f_t, zeta, mass)
            for c in range(len(CHANNELS)):
                m = (t.channel == c) & seen
                w = t.w[m] / np.sum(t.w[m])
                a, b = r0[m] - np.sum(w * r0[m]), r[m] - np.sum(w * r[m])
                up[c] += np.sum(w * (b * b - a * a))
                # the shift's cross term with the spectra's sampling scatter (variance t.var)
                var[c] += np.sum(w * w * 4 * (b - a) ** 2 * t.var[m])
        return up, np.sqrt(var)

    return (floor, shift) if folds else None
