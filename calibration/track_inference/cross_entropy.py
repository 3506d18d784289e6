"""The track's longitudinal level by Cross-Entropy over trial profiles: the seed's baseline
(section 7), after OBrien, Quirke, Bowe & Cantero, Structural Health Monitoring 17(6)
(2018) 1425-1440, and OBrien, Bowe, Quirke & Cantero, Proc. IMechE Part F 231(5) (2017)
518-534.

The inverse walks along the line window after window. In each window a population of
trial profiles under the leading bogie's wheelsets is drawn from independent normals, one
per profile node; the calibrated car runs over every trial; the elite (the trials whose
bogie responses, vertical accelerometer and pitch gyro, best match the measured ones) set
the next generation's mean and standard deviation; when the means stop moving, the
window's front part is kept and the next window starts from the car's state on it.

What the papers give (as the seed summarises them, with the 2017 paper's abstract): CE
over a population of trial elevations with an elite set, generations until convergence;
"ten elevations are found at a time ... half of these elevations are retained" before
the next optimisation; a rigid track; bogie sensors only. The seed's own CE (section 6.2:
population 500, elite 10 %, restarts after convergence) is followed where it applies.
What neither gives, and was chosen here (defaults in :class:`CESettings`):

* Profile: nodes every ``node_spacing`` (0.5 m), linear between nodes. A wheelset's rail
  rate is v times the profile's slope over one node spacing centred on it. On the car
  model's own response over a German low-disturbance profile (300 m) 0.5 m nodes gave a
  D1 correlation of 0.97 (0.955 on a second profile), 0.25 m nodes 0.93 in 1.3 times the
  time: CE loses more to the doubled dimension than the finer profile gains.
* Window: ``window`` (5 m) of new profile kept per window, ``lookahead`` (5 m) more
  searched with it: half retained, as in the 2017 paper. The lookahead must exceed the
  wheelbase 2 L_b so that both leading wheelsets have run over every kept node. The
  lookahead's means start the next window's search; nodes new to a window start at the
  last estimated level (a flat continuation; continuing the slope diverged).
* Measurements used in a window: every grid point from where wheelset 1 reaches the
  window's first node to where it reaches its last one.
* Wheelsets 3 and 4 (the trailing bogie) run over this method's own earlier estimate,
  or over the prior mean, 0, where there is none (the first 2 L_v metres of the pass).
  The first window's unknowns reach back under wheelset 2's starting position.
* Start: the car is in static equilibrium on each trial's profile at the first grid
  point; later windows start every trial from the state the car reached, at the window's
  first grid point, on the previous window's means (that state has seen one step's hold
  of the first node that the new window searches again; the mismatch is left).
* Offsets (gravity in the accelerometer, the gyro's offset and drift): each measured
  channel's running mean over ``trend_length`` (100 m) is taken out, and the simulated
  responses, which have no offset, are compared with what is left. Taking each channel's
  mean out per window instead (the least-squares offset of a window) also removes much of
  the response to wavelengths beyond the window: the D1 correlation was 0.63 against 0.77
  with the same search (0.25 m nodes, no restarts).
* Cost: the mean over the window's grid points and channels of the squared misfit, each
  channel divided by its measured (detrended) standard deviation over the whole pass.
* Sampling: normals truncated to ``height_limit`` (50 mm) about the window's starting
  mean, by the project's CE sampler (:func:`calibration.optimisers.cross_entropy.truncated_normal`).
* Update (Rubinstein & Kroese): mean = a * elite mean + (1 - a) * old mean, and likewise
  the standard deviation (the elite's own, about the elite mean), a = ``smoothing`` (0.7).
* Convergence: C_g = sum |mean_g - mean_g-1| / sum |mean_g| (the seed's eq. 2 sum of the
  changes of the means, made relative; the denominator is floored at 0.1 mm a node so
  that a flat track cannot stall it) below ``tolerance`` (1e-3).
* Restarts (the seed's section 6.2): on convergence the search restarts from the mean with
  the initial deviation (3 mm), ``restarts`` (2) times. The seed restarts until two
  consecutive converged means agree; here they keep differing by about 2 % (median over
  windows, 10-15 % at the 90th percentile) however often it restarts, the search's own
  noise along weakly determined profile shapes, so the count is fixed. Restarts matter:
  on the 300 m pass the D1 correlation was 0.90 without them, 0.97 with two.
  ``max_generations`` (300) caps a window's generations, restarts included.
* The kept profile is the window's final mean (the CE answer), not its best sample.
* Axle-box channels are ignored; ``gyro_gain`` scales the model's pitch rate, as in
  :func:`~calibration.track_inference.kalman.infer_pass`.

The population is simulated at once: states (n_x, population) stepped exactly over the
grid's time steps (first-order hold on the eight rail inputs,
:class:`~calibration.track_inference.kalman.CarStepper`). A trial's rail inputs are
linear in its node heights, so the map from nodes to each step's input term is formed
once per window and each generation costs one matrix product plus the state recursion.

As the seed reports, the shape comes out well and the elevation poorly. On the car model's
own response over 2.5 km (35 +- 3 m/s, sensor noise) the D1 correlation was 0.945 and
0.891 for two seeds of the search (RMSE 0.33 and 0.43 mm, true D1 rms 0.93 mm), the 3-6 m
band 0.999, the 12-25 m band 0.93 with its amplitude 73 % of the truth (first seed); the
level itself wanders, by 5-13 mm rms.

Output: a :class:`~calibration.track_inference.kalman.PassProfile` at wheelset 1's track
positions on the pass grid; ``std`` is the final elite's standard deviation of the node
(interpolated), the search's spread, not a posterior uncertainty; ``log_likelihood`` is
nan (CE has none); ``innovation_ratio`` holds, per channel, the mean squared residual of
the kept means over the channel's (detrended) variance: 1 would be nothing explained.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.ndimage

from .. import checks
from ..models.car2d import CarExtras
from ..models.parameters import CarParameters
from ..optimisers.cross_entropy import truncated_normal
from .kalman import CarStepper, PassProfile
from .passes import Pass

#: [m] floor per node of the convergence value's denominator (a flat track has sum |mean| ~ 0)
_MEAN_FLOOR = 1e-4


@dataclass(frozen=True)
class CESettings:
    """population: trial profiles per generation (the seed's 500); elite_fraction: the best
    share, which sets the next generation; window [m]: new profile kept per window;
    lookahead [m]: further profile searched with it; node_spacing [m] of the profile's
    nodes; initial_std [m] of a node's height; height_limit [m]: draws truncated to this
    about the window's starting mean; smoothing: weight of the elite statistics in each
    update (1: none); tolerance on the relative change of the means; restarts after the
    first convergence; max_generations per window, restarts included; trend_length [m]
    of the running mean taken out of each measured channel; seed of the random generator.
    The module docstring gives the reasons for the defaults."""

    population: int = 500
    elite_fraction: float = 0.10
    window: float = 5.0
    lookahead: float = 5.0
    node_spacing: float = 0.5
    initial_std: float = 0.003
    height_limit: float = 0.05
    smoothing: float = 0.7
    tolerance: float = 1e-3
    restarts: int = 2
    max_generations: int = 300
    trend_length: float = 100.0
    seed: int = 0

    def __post_init__(self):
        checks.whole(self, "population", minimum=10)
        checks.whole(self, "max_generations", minimum=1)
        checks.whole(self, "restarts", "seed", minimum=0)
        checks.positive(self, "elite_fraction", "window", "lookahead", "node_spacing", "initial_std",
                        "height_limit", "smoothing", "tolerance", "trend_length")
        checks.fraction(self, "elite_fraction")
        checks.fraction(self, "smoothing", closed=True)
        if round(self.population * self.elite_fraction) < 2:
            raise ValueError(f"CESettings.elite_fraction x population must give an elite of at least 2, got "
                             f"{self.elite_fraction} x {self.population}")
        for name in ("window", "lookahead"):
            n = getattr(self, name) / self.node_spacing
            if abs(n - round(n)) > 1e-6 * max(n, 1.0):
                raise ValueError(f"CESettings.{name} must be a whole number of node_spacing "
                                 f"({self.node_spacing:g} m), got {getattr(self, name)!r}")


def _weights(q: np.ndarray, q0: float, d: float, lo: int, n: int) -> np.ndarray:
    """(q.size, n): linear-interpolation weights of the positions ``q`` [m] over nodes
    lo..lo+n-1 (node i at q0 + i d)."""
    f = (q.ravel() - q0) / d - lo
    i = np.floor(f).astype(int)
    w = f - i
    if i.min() < 0 or i.max() > n:
        raise IndexError("profile position outside the window's nodes")
    out = np.zeros((f.size, n + 2))
    rows = np.arange(f.size)
    out[rows, i] = 1 - w
    out[rows, i + 1] += w
    if np.abs(out[:, n:]).max() > 1e-9:
        raise IndexError("profile position outside the window's nodes")
    return out[:, :n]


class _Window:
    """One window's fixed matrices: the map from its unknown node heights to the car's
    step-input terms and output feed-through, and the known profile's share of both."""

    def __init__(self, car: CarStepper, ps: Pass, k0: int, k1: int, nodes: np.ndarray, q0: float, d: float,
                 u0: int, u1: int, static_start: bool):
        ks = np.arange(k0, k1 + 1)
        lo = max(int(math.floor((ps.s[k0] + car.wheel_x[-1] - d - q0) / d)) - 1, 0)  # behind wheelset 4
        n = u1 - lo  # no wheelset reaches beyond the unknowns' last node
        q = ps.s[ks][:, None] + car.wheel_x[None, :]  # (n_k, 4) rail positions of the wheelsets
        lev = _weights(q, q0, d, lo, n).reshape(ks.size, 4, n)
        slope = (_weights(q + d / 2, q0, d, lo, n) - _weights(q - d / 2, q0, d, lo, n)).reshape(ks.size, 4, n) / d
        W = np.concatenate([lev, ps.v[ks][:, None, None] * slope], axis=1)  # (n_k, 8, n)
        unk = slice(u0 - lo, u1 - lo)
        known = np.r_[0:u0 - lo]
        Wu = W[:, :, unk]
        U_known = W[:, :, known] @ nodes[lo:u0] if known.size else np.zeros((ks.size, 8))
        nx, nu = car.nx, u1 - u0
        # the arrays run (step, ..., trial) so that each step's products are on contiguous blocks
        self.Phi = np.empty((ks.size - 1, nx, nx))
        self.H = np.empty((ks.size - 1, nx, nu))  # input term per step, over the unknowns
        self.h0 = np.empty((ks.size - 1, nx, 1))  # input term per step, from the known profile
        for i in range(ks.size - 1):
            self.Phi[i], Ga, Gb = car.step_matrices(ps.t[ks[i + 1]] - ps.t[ks[i]])
            self.H[i] = Ga @ Wu[i] + Gb @ Wu[i + 1]
            self.h0[i, :, 0] = Ga @ U_known[i] + Gb @ U_known[i + 1]
        self.DW = car.D @ Wu  # (n_k, n_ch, n_u) feed-through
        self.d0 = (U_known @ car.D.T)[:, :, None]
        self.C = car.C
        self.static = None
        if static_start:  # x = -A^-1 B [levels, 0]: static equilibrium on each trial's profile
            S = -np.linalg.solve(car.A, car.B[:, :4])
            self.static = (S @ Wu[0, :4], S @ U_known[0, :4])
        self.n_k, self.nx = ks.size, nx

    def simulate(self, theta: np.ndarray, x0: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """(outputs (n_k, n_ch, P), states (n_k, n_x, P)) for node heights ``theta`` (P, n_u)."""
        T = np.ascontiguousarray(theta.T)
        E = self.H @ T + self.h0
        X = np.empty((self.n_k, self.nx, T.shape[1]))
        if self.static is not None:
            X[0] = self.static[0] @ T + self.static[1][:, None]
        else:
            X[0] = x0[:, None]
        for i in range(self.n_k - 1):
            np.matmul(self.Phi[i], X[i], out=X[i + 1])
            X[i + 1] += E[i]
        return self.C @ X + self.DW @ T + self.d0, X


def _cost(Y: np.ndarray, Ym: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Mean squared misfit of each trial (the last axis), each channel divided by its
    measured standard deviation."""
    r = (Y - Ym[:, :, None]) / scale[:, None]
    return np.mean(r * r, axis=(0, 1))


def _search(win: _Window, Ym: np.ndarray, scale: np.ndarray, mu: np.ndarray, x0, settings: CESettings,
            rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, int]:
    """The window's converged mean, the final elite's standard deviation and the generations."""
    n_elite = int(round(settings.population * settings.elite_fraction))
    sd = np.full(mu.size, settings.initial_std)
    low, high = mu - settings.height_limit, mu + settings.height_limit
    a = settings.smoothing
    floor = _MEAN_FLOOR * mu.size
    g, runs = 0, 0
    for g in range(1, settings.max_generations + 1):
        theta = truncated_normal(rng, mu, sd, low, high, settings.population)
        Y, _ = win.simulate(theta, x0)
        elite = theta[np.argsort(_cost(Y, Ym, scale))[:n_elite]]
        new_mu = a * elite.mean(axis=0) + (1 - a) * mu
        sd = a * elite.std(axis=0) + (1 - a) * sd
        change = np.abs(new_mu - mu).sum() / max(np.abs(new_mu).sum(), floor)
        mu = new_mu
        if change < settings.tolerance:
            if runs == settings.restarts:
                break
            runs += 1
            sd = np.full(mu.size, settings.initial_std)
    return mu, sd, g


def infer_pass_ce(ps: Pass, p: CarParameters, settings: CESettings, *, extras: CarExtras | None = None,
                  gyro_gain: float = 1.0, progress=None) -> PassProfile:
    """The level under the pass's leading bogie by Cross-Entropy, window after window;
    ``progress`` (a callable taking a message) hears every 100 windows."""
    car = CarStepper(p, extras, ps.channels, gyro_gain)
    bogie = [c for c in ps.channels if c.kind != "axle"]
    if not bogie:
        raise ValueError(f"pass {ps.run_id}: no bogie accelerometer or gyro to infer the track from")
    K = ps.s.size
    step = (ps.s[-1] - ps.s[0]) / (K - 1) if K > 2 else 0.0
    if K < 3 or not np.allclose(np.diff(ps.s), step, rtol=1e-6, atol=0.0):
        raise ValueError(f"pass {ps.run_id}: needs a uniform distance grid of at least 3 points")
    if settings.window < step:
        raise ValueError(f"CESettings.window ({settings.window:g} m) is shorter than the pass's grid step "
                         f"({step:g} m)")
    xw = car.wheel_x
    if settings.lookahead <= xw[0] - xw[1]:
        raise ValueError(f"CESettings.lookahead ({settings.lookahead:g} m) must exceed the wheelbase "
                         f"({xw[0] - xw[1]:g} m) so that both leading wheelsets run over the kept profile")
    d = settings.node_spacing
    Y = np.column_stack([c.values for c in bogie])
    Y = Y - scipy.ndimage.uniform_filter1d(Y, max(int(round(settings.trend_length / step)), 1), axis=0,
                                           mode="reflect")
    var = Y.var(axis=0)
    scale = np.sqrt(np.where(var > 0, var, 1.0))
    # node i at q0 + i d, from behind wheelset 4 at the first grid point to beyond wheelset 1 at the last
    q0 = ps.s[0] + xw[0] + (math.floor((xw[-1] - xw[0] - d) / d) - 1) * d
    n_nodes = int(math.ceil((ps.s[-1] + xw[0] + d / 2 - q0) / d)) + 2
    nodes = np.zeros(n_nodes)  # the prior mean, 0, until estimated
    spread = np.full(n_nodes, np.nan)
    rng = np.random.default_rng(settings.seed)
    u0 = int(math.floor((ps.s[0] + xw[1] - d / 2 - q0) / d)) - 1  # the first window reaches back under wheelset 2
    known_hi = u0  # nodes from here on have no estimate yet
    x0 = None
    w, k0 = 0, 0
    resid2, generations = np.zeros(len(bogie)), 0
    while True:
        k_end = int(round(((w + 1) * settings.window + settings.lookahead) / step))
        last = k_end >= K - 1
        k1 = K - 1 if last else k_end
        u1 = min(int(math.ceil((ps.s[k1] + xw[0] + d / 2 - q0) / d)) + 1, n_nodes)
        mu = nodes[u0:u1].copy()
        if known_hi < u1:  # nodes new to this window continue the last estimate flat
            mu[max(known_hi - u0, 0):] = nodes[known_hi - 1] if known_hi > u0 else 0.0
        win = _Window(car, ps, k0, k1, nodes, q0, d, u0, u1, static_start=x0 is None)
        Ym = Y[k0:k1 + 1]
        mu, sd, g = _search(win, Ym, scale, mu, x0, settings, rng)
        generations += g
        nodes[u0:u1] = mu
        known_hi = max(known_hi, u1)
        k_next = K - 1 if last else int(round((w + 1) * settings.window / step))
        keep = u1 if last else int(round((ps.s[k_next] + xw[0] - q0) / d))  # nodes behind wheelset 1 are kept
        spread[u0:keep] = sd[:keep - u0]
        Ys, X = win.simulate(mu[None, :], x0)
        r = (Ys[:, :, 0] - Ym)[:k_next - k0 + (1 if last else 0)]
        resid2 += np.sum(r * r, axis=0)
        if last:
            break
        x0 = X[k_next - k0, :, 0]
        u0, k0, w = keep, k_next, w + 1
        if progress and w % 100 == 0:
            progress(f"infer-track-ce: {ps.run_id} {ps.s[k0] - ps.s[0]:.0f} of {ps.s[-1] - ps.s[0]:.0f} m, "
                     f"{generations / w:.1f} generations a window")
    q = q0 + d * np.arange(n_nodes)
    distance = ps.s + xw[0]
    ratio = {c.name: float(resid2[i] / K / scale[i] ** 2) for i, c in enumerate(bogie)}
    return PassProfile(ps.run_id, distance, np.interp(distance, q, nodes), np.interp(distance, q, spread),
                       math.nan, ratio, np.empty((distance.size, 0)))  # no error model: no draws
