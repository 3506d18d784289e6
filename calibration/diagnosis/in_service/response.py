"""The response part of the diagnosis: the 2D car (and its extensions) driven by the
measured rail input, fitted to the measured responses by their residual energy.

For a linear model with frequency response G (rail accelerations -> responses) the
residual r = y - G u has, in each band, the cross-spectrum

    S_rr = S_yy - G S_uy - S_yu G^H + G S_uu G^H,

a quadratic form in the band sums of :mod:`.records`. A model is
scored by each response channel's *normalised residual power* (NRP: residual mean square
over the channel's mean square, in the analysis band), and fitted by minimising the
residual power summed over bands and channels, each channel normalised by its power.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.ndimage
import scipy.optimize

from ...models.car2d import CarExtras, Output, build_car, dynamic_stiffness, output_rows
from ...models.parameters import CarParameters
from .amplitude import (CONSISTENT, FRICTION, RELINEARISE, AmplitudeClasses, amplitude_classes, halfway,
                        relinearised)
from .records import Layout, Statistics

#: baseline parameters the response fit adjusts (geometry is known; m_w does not enter a
#: car whose wheelsets follow the rail)
FIT_NAMES = ("m_v", "J_v", "m_b", "J_b", "k_p", "c_p", "k_s", "c_s")
#: A journey's load against the mean, as a fraction of the carbody's mass: the seed's Table 5
#: payload ranges (passengers, luggage, fuel, water, waste) span about +-8 % of an intercity
#: car's mass; a crush-loaded commuter car reaches +-20 %.
LOAD_RANGE = 0.25


@dataclass(frozen=True)
class SensorModel:
    """Where the sensors really are and how they read: ``dx`` [m] added to every bogie
    accelerometer's declared x, ``gyro_gain`` multiplying every pitch gyro, and ``floor``:
    (name, dx [m], gain) of carbody floor accelerometers, each off its declared x by its
    own dx and reading gain x the acceleration there."""

    dx: float = 0.0
    gyro_gain: float = 1.0
    floor: tuple[tuple[str, float, float], ...] = ()

    def floor_json(self) -> dict:
        """{sensor: {"dx_m", "gain"}} of the floor accelerometers a finding moved."""
        return {n: {"dx_m": dx, "gain": g} for n, dx, g in self.floor}


def model_outputs(lay: Layout, sensors: SensorModel) -> tuple[list[Output], np.ndarray]:
    floor = {n: (dx, g) for n, dx, g in sensors.floor}
    outs, gains = [], []
    for o in lay.responses:
        gain = sensors.gyro_gain if o.kind == "pitch_rate" else 1.0
        if o.kind == "acceleration" and o.body.startswith("bogie"):
            o = replace(o, x=o.x + sensors.dx)
        elif o.kind == "acceleration" and o.name in floor:
            dx, gain = floor[o.name]
            o = replace(o, x=o.x + dx)
        outs.append(o)
        gains.append(gain)
    return outs, np.array(gains)


def on_car(extras: CarExtras, lay: Layout) -> CarExtras:
    """``extras`` on the campaign's carbody (its length shapes a bending)."""
    return extras if extras.carbody_length == lay.length else replace(extras, carbody_length=lay.length)


def loaded(p: CarParameters, extras: CarExtras, load: float) -> tuple[CarParameters, CarExtras]:
    """The car carrying ``load`` x its carbody's mass more (a negative load: less), spread
    like the carbody's own mass: m_v, J_v and a bending's modal mass grow by (1 + load), so
    the bending's frequency falls by its square root; the levelling valves raise the air
    springs' pressure with the load they carry, and their stiffness with it (k_s x (1 +
    load): the gauge pressure of an intercity air spring is six times the atmosphere's, so
    this overstates the rise by a seventh of itself)."""
    if load == 0.0:
        return p, extras
    s = 1.0 + load
    p = p.replace(m_v=p.m_v * s, J_v=p.J_v * s, k_s=p.k_s * s)
    if extras.bending_hz is not None:
        extras = replace(extras, bending_hz=extras.bending_hz / np.sqrt(s))
    return p, extras


def _system(p: CarParameters, extras: CarExtras, sensors: SensorModel, lay: Layout, w: np.ndarray) -> tuple:
    """(K, M, C, B_k, B_c, rows, scale): the car's matrices (:func:`~calibration.models.car2d.build_car`),
    its output rows and the factor (n_freq, n_response) taking rows @ q per unit rail level
    to the sensors' reading per unit rail acceleration at angular frequencies ``w``."""
    outs, gains = model_outputs(lay, sensors)
    asm = build_car(p, extras=on_car(extras, lay))
    rows, power = output_rows(asm, outs)
    scale = -(1j * w[:, None]) ** power[None, :] / (w * w)[:, None] * gains[None, :]
    return asm.K, asm.M, asm.C, asm.B_k, asm.B_c, rows, scale


def transfer(p: CarParameters, extras: CarExtras, sensors: SensorModel, lay: Layout,
             f: np.ndarray) -> np.ndarray:
    """(n_band, n_response, 4): responses per unit rail acceleration under wheelsets 1-4."""
    w = 2 * np.pi * np.asarray(f, float)
    system = _system(p, extras, sensors, lay, w)
    rows, scale = system[5:]
    return scale[:, :, None] * (rows @ np.linalg.solve(*dynamic_stiffness(*system[:5], w)))


def residual_power(G: np.ndarray, S: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    """Residual power per band and response channel, (n_band, n_out), from band sums S."""
    return np.maximum(_raw_residual_power(G, S, n_in, n_out), 0.0)


def _raw_residual_power(G: np.ndarray, S: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    """:func:`residual_power` before round-off below zero is clipped."""
    Suu = S[:, :n_in, :n_in]
    Syu = S[:, n_in:n_in + n_out, :n_in]
    Syy = np.einsum("kii->ki", S[:, n_in:n_in + n_out, n_in:n_in + n_out]).real
    # diag(G S_uy) and diag(G S_uu G^H), as row sums of elementwise products (matmul: a
    # three-operand einsum is several times slower, and this runs at every step of a fit)
    GSuy = (G * Syu.conj()).sum(axis=2).real
    GSG = ((G @ Suu) * G.conj()).sum(axis=2).real
    return Syy - 2 * GSuy + GSG


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
    # statistics cell -> the load it was measured at (:func:`loaded`; absent: 0), when the
    # fit has a load per journey
    loads: Mapping = field(default_factory=dict)
    # statistics cell -> (dc_s, dc_p) [N s/m], the damping its amplitude adds to the fitted
    # car's (absent: none), when the fit has friction (:mod:`.amplitude`)
    damping: Mapping = field(default_factory=dict)

    def groups(self, keys) -> dict[tuple, list]:
        """``keys`` by the (load, added damping) their cells were measured at."""
        out: dict[tuple, list] = {}
        for k in keys:
            out.setdefault((float(self.loads.get(k, 0.0)), tuple(self.damping.get(k, (0.0, 0.0)))), []).append(k)
        return out

    def transfer(self, lay: Layout, f: np.ndarray, state: tuple = (0.0, (0.0, 0.0))) -> np.ndarray:
        """The fitted model's transfer (:func:`transfer`) at a cell's ``state``: its load and
        the (secondary, primary) damping its amplitude adds."""
        load, (dc_s, dc_p) = state
        p, extras = loaded(self.parameters, self.extras, load)
        if dc_s or dc_p:
            p = p.replace(c_s=p.c_s + dc_s, c_p=p.c_p + dc_p)
        return transfer(p, extras, self.sensors, lay, f)

    def per_group(self, stats: Statistics, lay: Layout, keys):
        """(transfer, band sums, cells) for each cell state among ``keys``."""
        for state, ks in sorted(self.groups(keys).items()):
            S, _ = stats.total(lambda k, ks=set(ks): k in ks)
            yield self.transfer(lay, stats.centres, state), S, ks


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


def _load_name(run: str) -> str:
    return f"load:{run}"


class ResponseProblem:
    """The response fit's cost, the residual power summed over bands and channels, each
    channel normalised by its training power, with its gradient; parameters in log space
    (or linear) within bounds.
    ``per_run``: each training run but the first carries a load (:func:`loaded`) of its own,
    the first the fit's reference. ``amplitude``: with friction parameters among
    ``ext_params`` (:data:`.amplitude.FRICTION`), each amplitude class of the training cells
    carries the damping the friction adds at its amplitude. Each (run, class) is one car."""

    def __init__(self, stats: Statistics, lay: Layout, train_keys, base: CarParameters, bounds: dict,
                 ext_params: tuple, make, per_run: bool = False, amplitude: AmplitudeClasses | None = None):
        self.lay, self.base, self.bounds = lay, base, dict(bounds)
        self.S, _ = stats.total(lambda k: k in train_keys)
        self.f = stats.centres
        self.n_out = len(lay.responses)
        power = channel_power(self.S, 4, self.n_out)
        self.norm = 1.0 / np.maximum(power.sum(axis=0), 1e-300)
        runs = sorted({k[0] for k in train_keys})
        self.runs = runs if per_run else []
        self.amplitude = amplitude if any(r.name in FRICTION for r in ext_params) else None
        if self.amplitude is None and any(r.name in FRICTION for r in ext_params):
            raise ValueError("friction parameters need the cells' amplitude classes (amplitude=...)")
        cells: dict = {}
        for k in stats.ordered(train_keys):
            cells.setdefault((k[0] if self.runs else "", self.amplitude.of(k) if self.amplitude else -1), []).append(k)
        self.groups = [(run or None, None if cls < 0 else cls, stats.total(lambda k, ks=set(ks): k in ks)[0])
                       for (run, cls), ks in sorted(cells.items())]
        loads = [ParamRange(_load_name(r), -LOAD_RANGE, LOAD_RANGE, log=False) for r in self.runs[1:]]
        self.ranges = [ParamRange(n, lo, hi) for n, (lo, hi) in self.bounds.items()] + list(ext_params) + loads
        self.lo = np.array([np.log(r.low) if r.log else r.low for r in self.ranges])
        self.hi = np.array([np.log(r.high) if r.log else r.high for r in self.ranges])
        self.make = make or (lambda v: (CarExtras(), SensorModel()))
        self.nb = len(self.bounds)
        self.n_ext = len(ext_params)
        # a run's load parameter (its index in x) -> the groups it alone moves
        self.owner = {i: {g for g, (run, _, _) in enumerate(self.groups) if run == r.name[len("load:"):]}
                      for i, r in enumerate(self.ranges) if r.name.startswith("load:")}
        self.count = 0

    def unpack(self, x):
        vals = {r.name: float(np.exp(xi) if r.log else xi) for r, xi in zip(self.ranges, x)}
        p = self.base.replace(**{k: vals[k] for k in self.bounds})
        extras, sensors = self.make({r.name: vals[r.name] for r in self.ranges[self.nb:self.nb + self.n_ext]})
        return p, on_car(extras, self.lay), sensors, vals

    def run_loads(self, vals) -> dict:
        return {r: vals.get(_load_name(r), 0.0) for r in self.runs}

    def cars(self, x) -> list[tuple]:
        """(parameters, extras, sensors, training band sums) of each group: one, or one per
        training run with ``per_run``, and per amplitude class with friction."""
        p, extras, sensors, vals = self.unpack(x)
        loads = self.run_loads(vals)
        out = []
        for run, cls, S in self.groups:
            pp, ee = loaded(p, extras, loads[run]) if run is not None else (p, extras)
            if cls is not None:
                dc_s, dc_p = self.amplitude.added(vals, self.amplitude.sigma[cls])
                pp = pp.replace(c_s=pp.c_s + dc_s, c_p=pp.c_p + dc_p)
            out.append((pp, ee, sensors, S))
        return out

    def residual_power(self, x) -> np.ndarray:
        """Training residual power per band and channel, (n_band, n_out)."""
        return sum(residual_power(transfer(p, extras, sensors, self.lay, self.f), S, 4, self.n_out)
                   for p, extras, sensors, S in self.cars(x))

    def cost(self, x, free) -> tuple[float, np.ndarray]:
        """(cost, its gradient over x[free]): the cost is half the training residual power
        summed over bands and channels, each channel normalised by its training power.

        The car's matrices are cheap to assemble, its frequency response is not: the
        matrices are differenced (forward, a step of 1e-6 of the parameter's log or value)
        and the response's derivative follows from them exactly, dq = D^-1 (dF - dD q), one
        inverse per load group for all parameters. Each load group's matrices depend on the
        common parameters and its own load only."""
        self.count += 1
        w = 2 * np.pi * self.f
        idx = np.flatnonzero(free)
        steps = 1e-6 * np.maximum(1.0, np.abs(x[idx]))
        steps = np.where(x[idx] + steps > self.hi[idx], -steps, steps)
        groups = self.cars(x)
        owner = self.owner
        shifted = []
        for i, h in zip(idx, steps):
            xs = x.copy()
            xs[i] += h
            cars = self.cars(xs)
            shifted.append([None if i in owner and g not in owner[i] else _system(*cars[g][:3], self.lay, w)
                            for g in range(len(groups))])
        cost, grad = 0.0, np.zeros(idx.size)
        for g, (p, extras, sensors, S) in enumerate(groups):
            system = _system(p, extras, sensors, self.lay, w)
            D, F = dynamic_stiffness(*system[:5], w)
            Dinv = np.linalg.inv(D)
            Hq = Dinv @ F
            rows, scale = system[5:]
            RH = rows @ Hq
            G = scale[:, :, None] * RH
            raw = _raw_residual_power(G, S, 4, self.n_out)
            cost += 0.5 * float((np.maximum(raw, 0.0) * self.norm).sum())
            on = [j for j in range(idx.size) if shifted[j][g] is not None]
            if not on:
                continue
            # each matrix's difference quotient, stacked over the parameters
            d = [np.stack([(shifted[j][g][m] - system[m]) / steps[j] for j in on]) for m in range(7)]
            dK, dM, dC, dBk, dBc, drows, dscale = d
            # dR_ki = 2 Re sum_j dG_kij W_kij, the derivative of S_yy - 2 Re diag(G S_uy) +
            # diag(G S_uu G^H), with W = (G S_uu^T - S_yu)^* and dG = dscale RH + scale (drows q
            # + rows D^-1 (dB_k + i w dB_c - (dK - w^2 dM + i w dC) q)); the sums over DOFs are
            # contracted first, so each matrix's part is one product with its parameters' stack
            weight = np.where(raw > 0, self.norm[None, :], 0.0)  # d cost / dR (0 where R is clipped)
            W = (G.conj() @ S[:, :4, :4].transpose(0, 2, 1) - S[:, 4:4 + self.n_out, :4].conj()) * weight[:, :, None]
            P = rows @ Dinv  # (n_f, n_out, n_dof)
            B = W @ Hq.transpose(0, 2, 1)  # (n_f, n_out, n_dof): sum_j W_ij q_nj
            sP = scale[:, :, None] * P
            A = (sP[:, :, :, None] * W[:, :, None, :]).sum(axis=1).reshape(self.f.size, -1)  # (n_f, n_dof x n_in)
            E = (sP[:, :, :, None] * B[:, :, None, :]).sum(axis=1).reshape(self.f.size, -1)  # (n_f, n_dof x n_dof)
            jw, w2 = 1j * w[:, None], (w * w)[:, None]
            flat = lambda m: m.reshape(len(on), -1).T  # noqa: E731
            inner = (A @ flat(dBk) + jw * (A @ flat(dBc)) - E @ flat(dK) + w2 * (E @ flat(dM))
                     - jw * (E @ flat(dC))).sum(axis=0)
            inner += np.einsum("pin,ki,kin->p", drows, scale, B)
            inner += np.einsum("kip,ki->p", np.moveaxis(dscale, 0, -1), (RH * W).sum(axis=2))
            grad[on] += inner.real  # 0.5 x 2 Re
        return cost, grad

    def x_of(self, values):
        return np.array([np.clip(np.log(values[r.name]) if r.log else values[r.name], self.lo[i], self.hi[i])
                         for i, r in enumerate(self.ranges)])

    def solve(self, x0, free):
        """Minimise the cost over the parameters where ``free`` is True, the rest held at
        x0: L-BFGS-B within the bounds, on parameters scaled to a quarter of their range.
        (The cost is a large-residual least squares, where Gauss-Newton steps converge
        slowly: a thousand evaluations against a few dozen.)"""
        free = np.asarray(free, bool)
        lo, hi = self.lo[free], self.hi[free]
        sc = np.maximum(hi - lo, 1e-9) / 4

        def fg(z):
            x = x0.copy()
            x[free] = x0[free] + z * sc
            c, g = self.cost(x, free)
            return c, g * sc

        sol = scipy.optimize.minimize(fg, np.zeros(int(free.sum())), jac=True, method="L-BFGS-B",
                                      bounds=list(zip((lo - x0[free]) / sc, (hi - x0[free]) / sc)),
                                      options={"maxiter": 1000, "ftol": 1e-12, "gtol": 1e-9})
        x = x0.copy()
        x[free] = np.clip(x0[free] + sol.x * sc, lo, hi)
        return x, float(sol.fun)


def _cross_fitted_loads(stats: Statistics, lay: Layout, model: ResponseFit, keys) -> dict:
    """Held-out runs' loads, each half of a run's speed bins predicted at the load fitted
    on the other half (so that no cell is judged at a load fitted to it); a run with one
    speed bin is judged at the mean load, 0. Each cell is predicted with the damping its
    amplitude adds (``model.damping``), as it is judged."""
    by_run: dict = {}
    for k in sorted(keys):
        by_run.setdefault(k[0], []).append(k)
    n_out = len(lay.responses)
    out = {}
    for ks in by_run.values():
        if len(ks) < 2:
            out.update({k: 0.0 for k in ks})
            continue
        halves = (ks[0::2], ks[1::2])
        for fit_on, judge in (halves, halves[::-1]):
            S, _ = stats.total(lambda k, s=set(fit_on): k in s)
            norm = 1.0 / np.maximum(channel_power(S, 4, n_out).sum(axis=0), 1e-300)
            by_damping: dict = {}
            for k in fit_on:
                by_damping.setdefault(tuple(model.damping.get(k, (0.0, 0.0))), []).append(k)
            parts = [(d, stats.total(lambda k, s=set(ks): k in s)[0]) for d, ks in sorted(by_damping.items())]

            def cost(load):
                return float(sum((residual_power(model.transfer(lay, stats.centres, (load, d)), Sd, 4, n_out)
                                  * norm).sum() for d, Sd in parts))

            sol = scipy.optimize.minimize_scalar(cost, bounds=(-LOAD_RANGE, LOAD_RANGE), method="bounded",
                                                 options={"xatol": 1e-4})
            out.update({k: float(sol.x) for k in judge})
    return out


def fit_response(stats: Statistics, lay: Layout, train_keys, base: CarParameters, bounds: dict, *,
                 ext_params: tuple[ParamRange, ...] = (), make=None, starts: int = 6, screen: int = 0,
                 known: Mapping[str, float] | None = None, rng: np.random.Generator | None = None,
                 per_run: bool = False, heldout_keys=(), amplitude: AmplitudeClasses | None = None,
                 relinearise: bool = False) -> ResponseFit:
    """Fit the baseline parameters in ``bounds`` ({name: (low, high)}) and the extension
    parameters ``ext_params`` (``make(values) -> (CarExtras, SensorModel)``) to the training
    statistics. Without an extension: one fit from ``base``. With one: a
    global stage (``starts`` starts of the extension parameters, a Latin hypercube over
    their box, baseline held at ``base``), then the best refined jointly with the baseline.
    ``screen``: the hypercube has this many points (at least ``starts``), their costs are
    evaluated and the ``starts`` cheapest are the starts: a resonance's frequency has a
    basin about as wide as its bandwidth, narrower than a few starts' spacing over the box.
    ``known``: extension parameters already fitted (an extension found before this one),
    which start at these values and take no part in the global stage.
    ``per_run``: every run carries a load of its own (:func:`loaded`), fitted with the rest
    on the training runs and, for the runs of ``heldout_keys``, cross-fitted
    (:func:`_cross_fitted_loads`); the fitted car carries the training runs' mean load.
    ``amplitude``: the cells' amplitude classes, for friction among ``ext_params``; the
    fitted car carries the damping at the training cells' amplitude, each cell (training and
    held out) its class's difference from it; with ``relinearise`` the classes' amplitudes
    are made consistent with the friction fitted (:mod:`.amplitude`)."""
    rng = np.random.default_rng(0) if rng is None else rng
    known = dict(known or {})
    if amplitude is None and any(r.name in FRICTION for r in ext_params):
        amplitude = amplitude_classes(base, stats, train_keys, heldout_keys)
    pr = ResponseProblem(stats, lay, train_keys, base, bounds, ext_params, make, per_run, amplitude)
    nb, n = pr.nb, len(pr.ranges)
    mid = {r.name: (np.sqrt(r.low * r.high) if r.log else 0.5 * (r.low + r.high)) for r in pr.ranges[nb:]}
    x_base = pr.x_of({**base.as_dict(), **mid, **known})
    searched = np.array([nb <= i < nb + pr.n_ext and r.name not in known for i, r in enumerate(pr.ranges)])
    if searched.any():
        k, m = int(searched.sum()), max(screen, starts)
        u = (rng.permuted(np.tile(np.arange(m), (k, 1)), axis=1).T + rng.uniform(size=(m, k))) / m
        x0s = np.tile(x_base, (m, 1))
        x0s[:, searched] = pr.lo[searched] + u * (pr.hi[searched] - pr.lo[searched])
        if m > starts:
            held = np.zeros(n, bool)
            costs = np.array([pr.cost(x0, held)[0] for x0 in x0s])
            # costs equal but for round-off (points where the extension does nothing) keep the
            # hypercube's order, so the starts do not depend on the CPU
            costs = np.round(costs / max(costs.min(), 1e-300), 9)
            x0s = x0s[np.argsort(costs, kind="stable")[:starts]]
        best = None
        for x0 in x0s:
            x, cost = pr.solve(x0, searched)
            if best is None or cost < best[1]:
                best = (x, cost)
        x_base = best[0]
    x, _ = pr.solve(x_base, np.ones(n, bool))
    for _ in range(RELINEARISE if pr.amplitude is not None and relinearise else 0):
        p, extras, _, vals = pr.unpack(x)
        amplitude = halfway(pr.amplitude, relinearised(pr.amplitude, p, vals, stats, train_keys, extras=extras),
                            stats, train_keys)
        if np.allclose(amplitude.sigma, pr.amplitude.sigma, rtol=CONSISTENT, atol=0.0):
            break
        count = pr.count
        pr = ResponseProblem(stats, lay, train_keys, base, bounds, ext_params, make, per_run, amplitude)
        pr.count = count
        x, _ = pr.solve(x, np.ones(n, bool))
    p, extras, sensors, vals = pr.unpack(x)
    nrp = pr.residual_power(x).sum(axis=0) * pr.norm
    span = pr.hi - pr.lo
    at = tuple(r.name for i, r in enumerate(pr.ranges)
               if span[i] > 0 and min(x[i] - pr.lo[i], pr.hi[i] - x[i]) < 0.01 * span[i])
    values = {r.name: vals[r.name] for r in pr.ranges[nb:nb + pr.n_ext]}
    if pr.amplitude is not None:
        a = pr.amplitude
        dc_s, dc_p = a.added(vals, a.reference)
        p = p.replace(c_s=p.c_s + dc_s, c_p=p.c_p + dc_p)
        values["amplitude_reference_m_per_s"] = {"secondary": a.reference[0], "primary": a.reference[1]}
    fit = ResponseFit(p, extras, sensors, values, nrp, at, pr.count)
    if pr.amplitude is not None:
        fit = replace(fit, damping={k: pr.amplitude.relative(vals, k)
                                    for k in stats.ordered(set(train_keys) | set(heldout_keys))})
    if not per_run:
        return fit
    # the car at the training runs' mean load; each run's load against it
    runs = pr.run_loads(vals)
    mean = float(np.mean(list(runs.values())))
    p, extras = loaded(p, extras, mean)
    loads = {k: (1 + runs[k[0]]) / (1 + mean) - 1 for k in train_keys}
    fit = replace(fit, parameters=p, extras=extras, loads=loads)
    loads.update(_cross_fitted_loads(stats, lay, fit, heldout_keys))
    journeys = {}
    for k, load in loads.items():
        journeys.setdefault(k[0], []).append(load)
    journeys = {r: float(np.mean(v)) for r, v in sorted(journeys.items())}
    values.update({"load_spread": max(journeys.values()) - min(journeys.values()), "journey_loads": journeys})
    return replace(fit, values=values, loads=loads)


def response_nrp(stats: Statistics, lay: Layout, keys, fit: ResponseFit, by_band: bool = False):
    """NRP per response channel of the model ``fit`` over the statistics ``keys`` (or the
    per-band residual and channel powers with ``by_band``)."""
    n_in, n_out = 4, len(lay.responses)
    R = sum((residual_power(G, S, n_in, n_out) for G, S, _ in fit.per_group(stats, lay, keys)),
            np.zeros((stats.centres.size, n_out)))
    P = channel_power(stats.total(lambda k: k in keys)[0], n_in, n_out)
    if by_band:
        return R, P
    return R.sum(axis=0) / np.maximum(P.sum(axis=0), 1e-300)


def residuals_by_cell(stats: Statistics, lay: Layout, keys, fit: ResponseFit) -> dict:
    """Per-band residual power (n_band, n_response) of each statistics cell in ``keys``,
    from one evaluation of the model's transfer per cell state (load and added damping)."""
    out = {}
    for state, ks in fit.groups(keys).items():
        G = fit.transfer(lay, stats.centres, state)
        out.update({k: residual_power(G, stats.S[k], 4, len(lay.responses)) for k in ks})
    return out


def grouped_residual_cross_spectrum(stats: Statistics, lay: Layout, keys, fit: ResponseFit) -> np.ndarray:
    """:func:`residual_cross_spectrum` of ``fit`` summed over ``keys``."""
    return sum(residual_cross_spectrum(G, S, 4, len(lay.responses)) for G, S, _ in fit.per_group(stats, lay, keys))


def input_coherence(stats: Statistics, lay: Layout, keys, fit: ResponseFit) -> np.ndarray:
    """Multiple coherence of each response's residual with the inputs, per band: near 0 when
    the model explains everything the rail input causes (n_band, n_out)."""
    n_in, n_out = 4, len(lay.responses)
    S, _ = stats.total(lambda k: k in keys)
    Suu = S[:, :n_in, :n_in]
    Sru = np.zeros((S.shape[0], n_out, n_in), complex)
    R = np.zeros((S.shape[0], n_out))
    for G, Sg, _ in fit.per_group(stats, lay, keys):
        Sru += Sg[:, n_in:n_in + n_out, :n_in] - np.einsum("kij,kjl->kil", G, Sg[:, :n_in, :n_in])
        R += residual_power(G, Sg, n_in, n_out)
    Suu_inv = np.linalg.pinv(Suu, rcond=1e-8, hermitian=True)
    num = np.einsum("kij,kjl,kil->ki", Sru, Suu_inv, Sru.conj()).real
    raw = np.clip(num / np.maximum(R, 1e-300), 0.0, 1.0)
    # An estimate from n averages of a residual independent of p inputs reads about p / n;
    # remove that bias (n = periodogram bins in the band x windows).
    seconds = stats.seconds_of(keys)
    bias = np.minimum(n_in / np.maximum(np.diff(stats.edges) * seconds, 1.0), 0.99)[:, None]
    return np.clip((raw - bias) / (1 - bias), 0.0, 1.0)


def input_noise_power(stats: Statistics, lay: Layout, keys, fit: ResponseFit) -> np.ndarray:
    """Residual power per band and response that the rail input's own measurement noise
    puts into a perfect model's prediction (errors in variables), (n_band, n_out).

    The consistency channel is the difference of two wheelsets' axle-box means, so on
    round wheels its power is twice one mean's noise; a running median over bands keeps a
    wheel line out of the estimate. The four inputs are taken as carrying that noise
    independently (inputs 3 and 4 carry 1's and 2's, delayed)."""
    i = stats.channels.index("consistency")
    out = 0.0
    for G, S, _ in fit.per_group(stats, lay, keys):
        noise = scipy.ndimage.median_filter(S[:, i, i].real / 2, size=15, mode="nearest")
        out = out + np.sum(np.abs(G) ** 2, axis=2) * noise[:, None]
    return out
