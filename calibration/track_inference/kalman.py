"""The track's longitudinal level from the calibrated car's response: a Kalman filter in
the distance domain with a fixed-lag smoother.

The state, at grid point k (the car's centre at s_k, every ``step`` metres):

* the car's state x (the calibrated 2D car with its wheelsets on the rail, any extended
  model's additions included);
* a register z of the rail's level from just ahead of the leading wheelset to ``lag``
  metres behind the trailing one, z[i] = r(s_k + x_1 + 2 step - i step);
* the slope at the register's front, which with z[0] is the state of the shaping filter:
  the profile is white noise through the published German vertical spectrum's two poles,
  S(W) = A W_c^2 / ((W^2 + W_r^2)(W^2 + W_c^2)), discretised exactly over a step, with
  W_r raised to 2 pi / ``longest``: waves longer than the longest reported (D2's 70 m)
  are barely seen by the bogie, and left at the spectrum's hundreds of metres they wander
  under the estimate as each new measurement moves them (measured: D1 error 0.11-0.15 mm
  with them, 0.05 mm without, on a development campaign);
* a slowly wandering offset per channel (gravity, misalignment, gyro offset and drift).

Over a step the register shifts by one cell and the car moves exactly (its modes, first-
order hold on the rail inputs) over the step's time, step / v; each wheelset's rail level
and rate (v times the slope) are read off the register by interpolation. A bogie channel
is C x + D u, an axle box the rail's own acceleration, v^2 r'' + a r'.

Every profile point stays in the register until ``lag`` metres behind the trailing
wheelset: its estimate when it leaves uses every measurement taken while any wheelset was
on it and after, for as long as the bogie still responds to it. That is a fixed-lag
smoother. A longer lag was not better: 24 m and 40 m gave 1.3-2x the D1 error of 12 m on
the development campaigns, and with the spectrum not flattened even the model's own error
draws grew with the lag, so that what remains uncertain at long wavelengths is the likely
cause (not established). Its variance is the filter's for that cell.

The spectrum's level and each channel's noise are not taken on trust: they are chosen
from the data by a coarse likelihood search on the innovations (:func:`fit_noise`).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.linalg

from .. import checks
from ..models.car2d import CarExtras, Output, build_car, state_space, wheelset_positions
from ..models.parameters import CarParameters
from ..models.simulate import _phi
from ..models.track_irregularity import GERMAN_SPECTRA
from .passes import Pass


CHUNK = 256  # steps whose transitions are computed together


@dataclass(frozen=True)
class KalmanSettings:
    """step [m] of the distance grid; lag [m] behind the trailing wheelset at which a point's
    estimate is read; spectrum: the published vertical spectrum shaping the profile, scaled
    by ``roughness`` (its variance factor) and flat above ``longest`` [m]; noise [SI] per channel kind, the rms of the
    measurement's misfit on the grid (sensor noise and what the model leaves out);
    offset_walk [SI/sqrt(m)]: how fast a channel's offset may wander."""

    step: float = 0.25
    lag: float = 12.0
    longest: float = 70.0
    spectrum: str = "german_low"
    roughness: float = 1.0
    noise: dict = field(default_factory=lambda: {"bogie_acc": 0.05, "gyro": 0.002, "axle": 0.5})
    offset_walk: dict = field(default_factory=lambda: {"bogie_acc": 2e-3, "gyro": 2e-4, "axle": 2e-2})

    def __post_init__(self):
        checks.positive(self, "step", "roughness", "longest")
        checks.non_negative(self, "lag")
        if self.spectrum not in GERMAN_SPECTRA:
            raise ValueError(f"KalmanSettings.spectrum must be one of {', '.join(GERMAN_SPECTRA)}, "
                             f"got {self.spectrum!r}")


@dataclass(frozen=True)
class PassProfile:
    """A pass's inferred level ``level`` [m] with its standard deviation ``std`` [m] (all
    wavelengths) at ``distance`` [m] along the line, the log-likelihood of its measurements
    and each channel's squared innovation over its predicted variance, averaged over the
    steps after the register's first fill (1 when the filter's noise and prior are right)."""

    run_id: str
    distance: np.ndarray
    level: np.ndarray
    std: np.ndarray
    log_likelihood: float
    innovation_ratio: dict
    error_draws: np.ndarray  # (samples, draws): the estimate's error, sampled (see infer_pass)


def _shaping(settings: KalmanSettings):
    """(Phi, Q, P_inf, F) of the two-pole shaping filter over one step, state [r, r']."""
    a, wc, wr, _ = GERMAN_SPECTRA[settings.spectrum]
    wr = max(wr, 2 * np.pi / settings.longest)
    b = np.sqrt(np.pi * a * settings.roughness) * wc  # one-sided S = (1/pi) |H|^2 for unit white noise
    F = np.array([[0.0, 1.0], [-wr * wc, -(wr + wc)]])
    G = np.array([[0.0], [b]])
    h = settings.step
    van_loan = scipy.linalg.expm(np.block([[-F, G @ G.T], [np.zeros((2, 2)), F.T]]) * h)
    Phi = van_loan[2:, 2:].T
    Q = Phi @ van_loan[:2, 2:]
    P_inf = scipy.linalg.solve_continuous_lyapunov(F, -G @ G.T)
    return Phi, 0.5 * (Q + Q.T), P_inf, F


def _interp_rows(c: float, n: int, step: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows over the register giving the level, slope and curvature at fractional cell c."""
    i = int(np.floor(c))
    f = c - i
    lev, slope, curv = np.zeros(n), np.zeros(n), np.zeros(n)
    lev[i], lev[i + 1] = 1 - f, f
    for m, w in ((i, 1 - f), (i + 1, f)):  # central differences at the two cells, interpolated
        slope[m - 1] += w / (2 * step)
        slope[m + 1] -= w / (2 * step)
        curv[m - 1] += w / step ** 2
        curv[m] -= 2 * w / step ** 2
        curv[m + 1] += w / step ** 2
    return lev, slope, curv


class CarStepper:
    """The calibrated car's exact step over ``h`` seconds with first-order hold on its eight
    rail inputs u = [levels at wheelsets 1-4, their rates], and its outputs for the pass's
    bogie channels: x' = Phi x + Ga u_k + Gb u_k+1, y = C x + D u."""

    def __init__(self, p: CarParameters, extras: CarExtras | None, channels, gyro_gain: float = 1.0):
        self.wheel_x = wheelset_positions(p)
        bogie = [c for c in channels if c.kind != "axle"]
        outputs = [Output(c.name, "acceleration" if c.kind == "bogie_acc" else "pitch_rate", "bogie1", c.x)
                   for c in bogie]
        ss = state_space(build_car(p, extras=extras), outputs or [Output("_", "pitch_rate", "bogie1")])
        gains = np.array([gyro_gain if c.kind == "gyro" else 1.0 for c in bogie])[:, None]
        self.C, self.D = (ss.C * gains, ss.D * gains) if outputs else (ss.C[:0], ss.D[:0])
        self.A, self.B = ss.A, ss.B
        self.lam, V = np.linalg.eig(ss.A)
        self.V, self.Vinv = V, np.linalg.inv(V)
        self.VinvB = self.Vinv @ ss.B
        self.nx = ss.A.shape[0]

    def step_matrices(self, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Phi, Ga, Gb) over ``h`` seconds (real)."""
        e = np.exp(self.lam * h)
        phi1, phi2 = _phi(self.lam, h)
        return (((self.V * e) @ self.Vinv).real, ((self.V * (phi1 - phi2)) @ self.VinvB).real,
                ((self.V * phi2) @ self.VinvB).real)


class _Model:
    """The filter's fixed matrices for a car and a pass's channels."""

    def __init__(self, p: CarParameters, extras: CarExtras | None, channels, settings: KalmanSettings,
                 gyro_gain: float = 1.0):
        self.settings = settings
        h = settings.step
        self.car = car = CarStepper(p, extras, channels, gyro_gain)
        xw = car.wheel_x
        self.c = (xw[0] - xw) / h + 2.0  # wheelsets' fractional cells
        self.N = int(np.ceil(self.c[-1] + settings.lag / h)) + 3
        self.lag_offset = xw[0] + 2 * h - (self.N - 1) * h  # position of the last cell, from the centre
        self.C, self.D, self.nx = car.C, car.D, car.nx
        self.kinds = [c.kind for c in channels]
        self.wheelset = [c.wheelset for c in channels]
        self.nb = len(channels)
        self.n = self.nx + self.N + 1 + self.nb
        self.Phi_s, self.Q_s, self.P_inf, self.F_s = _shaping(settings)
        rows = [_interp_rows(c, self.N, h) for c in self.c]
        nxt = [_interp_rows(c - 1, self.N, h) for c in self.c]
        self.lev, self.slope = np.array([r[0] for r in rows]), np.array([r[1] for r in rows])
        self.lev_next, self.slope_next = np.array([r[0] for r in nxt]), np.array([r[1] for r in nxt])
        # a channel's row over the state is H0 + v H1 + v^2 H2 + a H3 (v speed, a acceleration)
        self.H = np.zeros((4, self.nb, self.n))
        z = slice(self.nx, self.nx + self.N)
        k = 0
        for r, kind in enumerate(self.kinds):
            if kind == "axle":
                _, slope, curv = rows[self.wheelset[r] - 1]
                self.H[2, r, z], self.H[3, r, z] = curv, slope
            else:
                self.H[0, r, :self.nx] = self.C[k]
                self.H[0, r, z] = self.D[k, :4] @ self.lev
                self.H[1, r, z] = self.D[k, 4:] @ self.slope
                k += 1
            self.H[0, r, self.nx + self.N + 1 + r] = 1.0

    def transitions(self, h: np.ndarray, v0: np.ndarray, v1: np.ndarray):
        """(Phi_x, E) for steps of ``h`` seconds from speed v0 to v1: x' = Phi_x x + E z."""
        car = self.car
        lam = car.lam[None, :] * h[:, None]
        e = np.exp(lam)
        phi1, phi2 = _phi(car.lam[None, :], h[:, None])
        Phi = np.einsum("ij,kj,jl->kil", car.V, e, car.Vinv, optimize=True).real
        Ga = np.einsum("ij,kj,jl->kil", car.V, phi1 - phi2, car.VinvB, optimize=True).real
        Gb = np.einsum("ij,kj,jl->kil", car.V, phi2, car.VinvB, optimize=True).real
        E = (Ga[:, :, :4] @ self.lev + v0[:, None, None] * (Ga[:, :, 4:] @ self.slope)
             + Gb[:, :, :4] @ self.lev_next + v1[:, None, None] * (Gb[:, :, 4:] @ self.slope_next))
        return Phi, E

    def measurement(self, v: float, a: float) -> np.ndarray:
        """(n_channels, n): each channel's row over the state (its offset included)."""
        return self.H[0] + v * self.H[1] + (v * v) * self.H[2] + a * self.H[3]

    def prior(self, y0: np.ndarray, settings: KalmanSettings):
        """Initial mean and covariance: the profile stationary with the spectrum, the car at rest
        on it, each offset at the channel's first value."""
        n, nx, N = self.n, self.nx, self.N
        h = settings.step
        P = np.zeros((n, n))
        lags = h * np.arange(N)
        ac = np.array([(scipy.linalg.expm(self.F_s * d) @ self.P_inf)[0, 0] for d in lags])
        P[nx:nx + N, nx:nx + N] = scipy.linalg.toeplitz(ac)
        # cell i against the front's slope: E[r'(s) r(s - i step)], row 1 of exp(F d) P_inf
        cross = np.array([(scipy.linalg.expm(self.F_s * d) @ self.P_inf)[1, 0] for d in lags])
        P[nx:nx + N, nx + N] = P[nx + N, nx:nx + N] = cross
        P[nx + N, nx + N] = self.P_inf[1, 1]
        P[:nx, :nx] = np.eye(nx) * 1e-4
        x = np.zeros(n)
        x[nx + N + 1:] = y0
        scale = np.array([max(abs(v), 1.0) for v in y0])
        P[nx + N + 1:, nx + N + 1:] = np.diag((0.1 * scale) ** 2)
        return x, P


def _predict(m: _Model, M: np.ndarray, Phi_x: np.ndarray, E: np.ndarray) -> np.ndarray:
    """F @ M for the state's transition F (M has the state on its first axis)."""
    nx, N = m.nx, m.N
    out = np.empty_like(M)
    z = M[nx:nx + N]
    out[:nx] = Phi_x @ M[:nx] + E @ z
    g = M[nx + N]
    out[nx] = m.Phi_s[0, 0] * z[0] + m.Phi_s[0, 1] * g
    out[nx + N] = m.Phi_s[1, 0] * z[0] + m.Phi_s[1, 1] * g
    out[nx + 1:nx + N] = z[:-1]
    out[nx + N + 1:] = M[nx + N + 1:]
    return out


def infer_pass(ps: Pass, p: CarParameters, settings: KalmanSettings, *, extras: CarExtras | None = None,
               gyro_gain: float = 1.0, draws: int = 8, seed: int = 0) -> PassProfile:
    """The level under the pass's leading bogie, fixed-lag smoothed.

    ``draws`` synthetic passes run through the same filter beside the measured one: each
    draws a profile and measurements from the filter's own model (a simulation smoother,
    Durbin and Koopman 2002), so their estimates' errors sample the estimate's error
    distribution; filtered to a band, they give the band's standard deviation."""
    m = _Model(p, extras, ps.channels, settings, gyro_gain)
    nx, N, nb, n = m.nx, m.N, m.nb, m.n
    rng = np.random.default_rng(seed)
    Y = np.column_stack([c.values for c in ps.channels])
    R = np.array([settings.noise[k] ** 2 for k in m.kinds])
    q_off = np.array([settings.offset_walk[k] ** 2 * settings.step for k in m.kinds])
    x0, P = m.prior(Y[0], settings)
    w, U = np.linalg.eigh(P)
    # columns: the estimate, the draws' estimates, the draws' truths (one transition for all)
    Z = np.tile(x0[:, None], (1, 1 + 2 * draws))
    Z[:, 1 + draws:] += (U * np.sqrt(np.maximum(w, 0.0))) @ rng.standard_normal((n, draws))
    est, tru = slice(0, 1 + draws), slice(1 + draws, 1 + 2 * draws)
    Lq = np.linalg.cholesky(m.Q_s + 1e-30 * np.eye(2))
    K = ps.s.size
    level, var, err = np.full(K, np.nan), np.full(K, np.nan), np.zeros((K, draws))
    loglik, ratio_sum = 0.0, np.zeros(nb)
    iz, ig, last = nx, nx + N, nx + N - 1
    off = np.arange(ig + 1, n)
    Rm = np.diag(R)
    for k in range(K):
        c = k % CHUNK
        if c == 0:  # a chunk's transitions and random numbers at once
            j = slice(k, min(k + CHUNK, K - 1))
            Phis, Es = m.transitions(np.diff(ps.t[j.start:j.stop + 1]), ps.v[j], ps.v[j.start + 1:j.stop + 1])
            e_meas = np.sqrt(R)[None, :, None] * rng.standard_normal((CHUNK, nb, draws))
            e_front = Lq @ rng.standard_normal((CHUNK, 2, draws))
            e_off = np.sqrt(q_off)[None, :, None] * rng.standard_normal((CHUNK, nb, draws))
        H = m.measurement(ps.v[k], ps.a[k])
        HZ = H @ Z
        nu = np.concatenate([Y[k][:, None], HZ[:, tru] + e_meas[c]], axis=1) - HZ[:, est]
        PHt = P @ H.T
        S = H @ PHt + Rm
        Sinv = np.linalg.inv(S)
        loglik -= 0.5 * (nu[:, 0] @ Sinv @ nu[:, 0] + np.linalg.slogdet(S)[1])
        if k >= N:  # once the register holds measured profile, not the prior's start
            ratio_sum += nu[:, 0] ** 2 / np.diag(S)
        G = PHt @ Sinv
        Z[:, est] += G @ nu
        P -= G @ PHt.T
        level[k], var[k] = Z[last, 0], P[last, last]
        err[k] = Z[last, 1:1 + draws] - Z[last, tru]
        if k + 1 < K:
            Z = _predict(m, Z, Phis[c], Es[c])
            Z[[iz, ig], tru] += e_front[c]
            Z[ig + 1:, tru] += e_off[c]
            P = _predict(m, _predict(m, P, Phis[c], Es[c]).T, Phis[c], Es[c])
            P = 0.5 * (P + P.T)
            P[iz, iz] += m.Q_s[0, 0]
            P[iz, ig] += m.Q_s[0, 1]
            P[ig, iz] += m.Q_s[1, 0]
            P[ig, ig] += m.Q_s[1, 1]
            P[off, off] += q_off
    distance = ps.s + m.lag_offset
    ratio = {c.name: float(ratio_sum[r] / max(K - N, 1)) for r, c in enumerate(ps.channels)}
    return PassProfile(ps.run_id, distance, level, np.sqrt(np.maximum(var, 0.0)), float(loglik), ratio, err)


def _sub_pass(ps: Pass, length: float) -> Pass:
    n = min(ps.s.size, max(8, int(length / float(ps.s[1] - ps.s[0]))))
    return Pass(ps.run_id, ps.s[:n], ps.t[:n], ps.v[:n], ps.a[:n],
                tuple(replace(c, values=c.values[:n]) for c in ps.channels))


def fit_noise(ps: Pass, p: CarParameters, settings: KalmanSettings, *, extras: CarExtras | None = None,
              gyro_gain: float = 1.0, length: float = 800.0, rounds: int = 2) -> tuple[KalmanSettings, float]:
    """The spectrum's level and each channel kind's noise that make the first ``length``
    metres of ``ps`` most likely: a coordinate search in log steps (x3, then x sqrt 3) from
    ``settings``. Returns the settings and their log-likelihood."""
    sub = _sub_pass(ps, length)
    kinds = sorted({c.kind for c in ps.channels})

    def score(s: KalmanSettings) -> float:
        return infer_pass(sub, p, s, extras=extras, gyro_gain=gyro_gain, draws=0).log_likelihood

    def scaled(s: KalmanSettings, what: str, f: float) -> KalmanSettings:
        if what == "roughness":
            return replace(s, roughness=s.roughness * f * f)
        return replace(s, noise={**s.noise, what: s.noise[what] * f})

    best, best_ll = settings, score(settings)
    for factor in (3.0, np.sqrt(3.0))[:rounds]:
        for what in ("roughness", *kinds):
            for f in (factor, 1.0 / factor):
                trial = scaled(best, what, f)
                ll = score(trial)
                if ll > best_ll:
                    best, best_ll = trial, ll
                    break
    return best, best_ll
