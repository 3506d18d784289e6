"""The response part of the diagnosis: the 2D car (and its extensions) driven by the
measured rail input, fitted to the measured responses by their residual energy.

For a linear model with frequency response G (rail accelerations -> responses) the
residual r = y - G u has, in each band, the cross-spectrum

    S_rr = S_yy - G S_uy - S_yu G^H + G S_uu G^H,

a quadratic form in the band sums of :mod:`.records`. A model is
scored by each response channel's *normalised residual power* (NRP: residual mean square
over the channel's mean square, in the analysis band), and fitted by least squares on
the square roots of the per-band residual powers, each channel normalised by its power.
"""
from __future__ import annotations

from collections.abc import Mapping

from dataclasses import dataclass, replace

import numpy as np
import scipy.ndimage
import scipy.optimize

from ...models.car2d import CarExtras, Output, build_car, frequency_response
from ...models.parameters import CarParameters
from .records import Layout, Statistics

#: baseline parameters the response fit adjusts (geometry is known; m_w does not enter a
#: car whose wheelsets follow the rail)
FIT_NAMES = ("m_v", "J_v", "m_b", "J_b", "k_p", "c_p", "k_s", "c_s")


@dataclass(frozen=True)
class SensorModel:
    """Where the bogie sensors really are and how the gyros read: ``dx`` [m] added to every
    bogie accelerometer's declared x, ``gyro_gain`` multiplying every pitch gyro."""

    dx: float = 0.0
    gyro_gain: float = 1.0


def model_outputs(lay: Layout, sensors: SensorModel) -> tuple[list[Output], np.ndarray]:
    outs, gains = [], []
    for o in lay.responses:
        if o.kind == "acceleration" and o.body.startswith("bogie"):
            outs.append(replace(o, x=o.x + sensors.dx))
        else:
            outs.append(o)
        gains.append(sensors.gyro_gain if o.kind == "pitch_rate" else 1.0)
    return outs, np.array(gains)


def on_car(extras: CarExtras, lay: Layout) -> CarExtras:
    """``extras`` on the campaign's carbody (its length shapes a bending)."""
    return extras if extras.carbody_length == lay.length else replace(extras, carbody_length=lay.length)


def transfer(p: CarParameters, extras: CarExtras, sensors: SensorModel, lay: Layout,
             f: np.ndarray) -> np.ndarray:
    """(n_band, n_response, 4): responses per unit rail acceleration under wheelsets 1-4."""
    outs, gains = model_outputs(lay, sensors)
    H = frequency_response(build_car(p, extras=on_car(extras, lay)), outs, f)
    w2 = (2 * np.pi * f) ** 2
    return -H / w2[:, None, None] * gains[None, :, None]


def residual_power(G: np.ndarray, S: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    """Residual power per band and response channel, (n_band, n_out), from band sums S."""
    Suu = S[:, :n_in, :n_in]
    Syu = S[:, n_in:n_in + n_out, :n_in]
    Syy = np.einsum("kii->ki", S[:, n_in:n_in + n_out, n_in:n_in + n_out]).real
    GSuy = np.einsum("kij,kji->ki", G, Syu.conj().transpose(0, 2, 1)).real  # diag(G S_uy)
    GSG = np.einsum("kij,kjl,kil->ki", G, Suu, G.conj()).real
    return np.maximum(Syy - 2 * GSuy + GSG, 0.0)


def residual_cross_spectrum(G: np.ndarray, S: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    """Residual cross-spectra between response channels per band, (n_band, n_out, n_out)."""
    Suu = S[:, :n_in, :n_in]
    Syu = S[:, n_in:n_in + n_out, :n_in]
    Syy = S[:, n_in:n_in + n_out, n_in:n_in + n_out]
    GSuy = np.einsum("kij,klj->kil", G, Syu.conj())  # G S_uy
    return Syy - GSuy - GSuy.conj().transpose(0, 2, 1) + np.einsum("kij,kjl,kml->kim", G, Suu, G.conj())


def channel_power(S: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    return np.einsum("kii->ki", S[:, n_in:n_in + n_out, n_in:n_in + n_out]).real


@dataclass(frozen=True)
class ResponseFit:
    """A car (and extension) fitted to the responses: the model, its extension parameter
    values, its training NRP per response channel."""

    parameters: CarParameters
    extras: CarExtras
    sensors: SensorModel
    values: dict  # extension parameter values (SI units, as named)
    nrp_train: np.ndarray  # per response channel
    at_bounds: tuple  # names of parameters within 1 % of a bound (fraction of the log range)
    evaluations: int


@dataclass(frozen=True)
class ParamRange:
    """A fitted parameter's search range [low, high] (in the parameter's unit), searched in
    log space when ``log`` (then 0 < low)."""

    name: str
    low: float
    high: float
    log: bool = True

    def __post_init__(self):
        if not self.low < self.high:
            raise ValueError(f"ParamRange {self.name!r}: low must be below high, got ({self.low}, {self.high})")
        if self.log and not self.low > 0:
            raise ValueError(f"ParamRange {self.name!r}: a log range needs low > 0, got {self.low}")


class _Problem:
    """Least squares on the square roots of per-band residual powers, each channel
    normalised by its training power; parameters in log space (or linear) within bounds."""

    def __init__(self, stats: Statistics, lay: Layout, train_keys, base: CarParameters, bounds: dict,
                 ext_params: tuple, make):
        self.lay, self.base, self.bounds = lay, base, dict(bounds)
        self.S, _ = stats.total(lambda k: k in train_keys)
        self.f = stats.centres
        self.n_out = len(lay.responses)
        power = channel_power(self.S, 4, self.n_out)
        self.norm = 1.0 / np.maximum(power.sum(axis=0), 1e-300)
        self.ranges = [ParamRange(n, lo, hi) for n, (lo, hi) in self.bounds.items()] + list(ext_params)
        self.lo = np.array([np.log(r.low) if r.log else r.low for r in self.ranges])
        self.hi = np.array([np.log(r.high) if r.log else r.high for r in self.ranges])
        self.make = make or (lambda v: (CarExtras(), SensorModel()))
        self.nb = len(self.bounds)
        self.count = 0

    def unpack(self, x):
        vals = {r.name: float(np.exp(xi) if r.log else xi) for r, xi in zip(self.ranges, x)}
        p = self.base.replace(**{k: vals[k] for k in self.bounds})
        extras, sensors = self.make({r.name: vals[r.name] for r in self.ranges[self.nb:]})
        return p, on_car(extras, self.lay), sensors, vals

    def resid(self, x):
        self.count += 1
        p, extras, sensors, _ = self.unpack(x)
        G = transfer(p, extras, sensors, self.lay, self.f)
        return np.sqrt(residual_power(G, self.S, 4, self.n_out) * self.norm[None, :]).ravel()

    def x_of(self, values):
        return np.array([np.clip(np.log(values[r.name]) if r.log else values[r.name], self.lo[i], self.hi[i])
                         for i, r in enumerate(self.ranges)])

    def solve(self, x0, free):
        """Least squares over the parameters where ``free`` is True, the rest held at x0."""
        free = np.asarray(free, bool)

        def f(xf):
            x = x0.copy()
            x[free] = xf
            return self.resid(x)

        lo, hi = self.lo[free], self.hi[free]
        sol = scipy.optimize.least_squares(f, x0[free], bounds=(lo, hi), x_scale=np.maximum(hi - lo, 1e-9) / 4,
                                           diff_step=1e-4, ftol=1e-7, xtol=1e-7, max_nfev=60,
                                           tr_solver="lsmr" if free.sum() > 1 else "exact")
        x = x0.copy()
        x[free] = sol.x
        return x, float(sol.cost)


def fit_response(stats: Statistics, lay: Layout, train_keys, base: CarParameters, bounds: dict, *,
                 ext_params: tuple[ParamRange, ...] = (), make=None, starts: int = 6,
                 known: Mapping[str, float] | None = None, rng: np.random.Generator | None = None) -> ResponseFit:
    """Fit the baseline parameters in ``bounds`` ({name: (low, high)}) and the extension
    parameters ``ext_params`` (``make(values) -> (CarExtras, SensorModel)``) to the training
    statistics. Without an extension: one least-squares fit from ``base``. With one: a
    global stage (``starts`` starts of the extension parameters, a Latin hypercube over
    their box, baseline held at ``base``), then the best refined jointly with the baseline.
    ``known``: extension parameters already fitted (an extension found before this one),
    which start at these values and take no part in the global stage."""
    rng = np.random.default_rng(0) if rng is None else rng
    known = dict(known or {})
    pr = _Problem(stats, lay, train_keys, base, bounds, ext_params, make)
    nb, n = pr.nb, len(pr.ranges)
    mid = {r.name: (np.sqrt(r.low * r.high) if r.log else 0.5 * (r.low + r.high)) for r in ext_params}
    x_base = pr.x_of({**base.as_dict(), **mid, **known})
    searched = np.array([i >= nb and r.name not in known for i, r in enumerate(pr.ranges)])
    if searched.any():
        k = int(searched.sum())
        u = (rng.permuted(np.tile(np.arange(starts), (k, 1)), axis=1).T + rng.uniform(size=(starts, k))) / starts
        best = None
        for row in u:
            x0 = x_base.copy()
            x0[searched] = pr.lo[searched] + row * (pr.hi[searched] - pr.lo[searched])
            x, cost = pr.solve(x0, searched)
            if best is None or cost < best[1]:
                best = (x, cost)
        x_base = best[0]
    x, _ = pr.solve(x_base, np.ones(n, bool))
    p, extras, sensors, vals = pr.unpack(x)
    G = transfer(p, extras, sensors, lay, pr.f)
    nrp = residual_power(G, pr.S, 4, pr.n_out).sum(axis=0) * pr.norm
    span = pr.hi - pr.lo
    at = tuple(r.name for i, r in enumerate(pr.ranges)
               if span[i] > 0 and min(x[i] - pr.lo[i], pr.hi[i] - x[i]) < 0.01 * span[i])
    return ResponseFit(p, extras, sensors, {r.name: vals[r.name] for r in pr.ranges[nb:]}, nrp, at, pr.count)


def response_nrp(stats: Statistics, lay: Layout, keys, p: CarParameters, extras: CarExtras,
                 sensors: SensorModel, by_band: bool = False):
    """NRP per response channel over the statistics ``keys`` (or the per-band residual and
    channel powers with ``by_band``)."""
    n_in, n_out = 4, len(lay.responses)
    S, _ = stats.total(lambda k: k in keys)
    G = transfer(p, extras, sensors, lay, stats.centres)
    R = residual_power(G, S, n_in, n_out)
    P = channel_power(S, n_in, n_out)
    if by_band:
        return R, P
    return R.sum(axis=0) / np.maximum(P.sum(axis=0), 1e-300)


def residuals_by_cell(stats: Statistics, lay: Layout, keys, p: CarParameters, extras: CarExtras,
                      sensors: SensorModel) -> dict:
    """Per-band residual power (n_band, n_response) of each statistics cell in ``keys``,
    from one evaluation of the model's transfer."""
    G = transfer(p, extras, sensors, lay, stats.centres)
    return {k: residual_power(G, stats.S[k], 4, len(lay.responses)) for k in keys}


def input_coherence(stats: Statistics, lay: Layout, keys, p, extras, sensors) -> np.ndarray:
    """Multiple coherence of each response's residual with the inputs, per band: near 0 when
    the model explains everything the rail input causes (n_band, n_out)."""
    n_in, n_out = 4, len(lay.responses)
    S, _ = stats.total(lambda k: k in keys)
    G = transfer(p, extras, sensors, lay, stats.centres)
    Suu = S[:, :n_in, :n_in]
    Syu = S[:, n_in:n_in + n_out, :n_in]
    Sru = Syu - np.einsum("kij,kjl->kil", G, Suu)
    R = residual_power(G, S, n_in, n_out)
    Suu_inv = np.linalg.pinv(Suu, rcond=1e-8, hermitian=True)
    num = np.einsum("kij,kjl,kil->ki", Sru, Suu_inv, Sru.conj()).real
    raw = np.clip(num / np.maximum(R, 1e-300), 0.0, 1.0)
    # An estimate from n averages of a residual independent of p inputs reads about p / n;
    # remove that bias (n = periodogram bins in the band x windows).
    seconds = stats.seconds_of(keys)
    bias = np.minimum(n_in / np.maximum(np.diff(stats.edges) * seconds, 1.0), 0.99)[:, None]
    return np.clip((raw - bias) / (1 - bias), 0.0, 1.0)


def input_noise_power(stats: Statistics, lay: Layout, keys, p, extras, sensors) -> np.ndarray:
    """Residual power per band and response that the rail input's own measurement noise
    puts into a perfect model's prediction (errors in variables), (n_band, n_out).

    The consistency channel is the difference of two wheelsets' axle-box means, so on
    round wheels its power is twice one mean's noise; a running median over bands keeps a
    wheel line out of the estimate. The four inputs are taken as carrying that noise
    independently (inputs 3 and 4 carry 1's and 2's, delayed)."""
    S, _ = stats.total(lambda k: k in keys)
    i = stats.channels.index("consistency")
    noise = scipy.ndimage.median_filter(S[:, i, i].real / 2, size=15, mode="nearest")
    G = transfer(p, extras, sensors, lay, stats.centres)
    return np.sum(np.abs(G) ** 2, axis=2) * noise[:, None]
