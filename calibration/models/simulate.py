"""Exact time response of a linear state-space system to piecewise-linear inputs.

The system x' = A x + B w, y = C x + D w is diagonalised once (A = V diag(l) V^-1);
each modal coordinate then obeys, for inputs linear between samples (first-order hold),

    eta[k+1] = exp(l h) eta[k] + (phi1 - phi2) p[k] + phi2 p[k+1],
    phi1 = (exp(l h) - 1) / l,   phi2 = (exp(l h) - 1 - l h) / (l^2 h),

with p = (V^-1 B) w. That recursion is a first-order IIR filter (``scipy.signal.lfilter``),
so millions of samples cost milliseconds, and it is exact to round-off: tests compare it
with a dense ``expm`` of the augmented (Van Loan) matrix. :class:`ModalSimulator` keeps
its state between calls so a long journey streams through in chunks.
"""
from __future__ import annotations

import numpy as np
import scipy.signal

from .car2d import StateSpace


def _phi(lam: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    z = lam * h
    small = np.abs(z) < 1e-3
    e = np.exp(z)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi1 = np.where(small, h * (1 + z / 2 + z**2 / 6 + z**3 / 24), (e - 1) / np.where(small, 1, lam))
        phi2 = np.where(small, h * (0.5 + z / 6 + z**2 / 24 + z**3 / 120),
                        (e - 1 - z) / np.where(small, 1, lam**2 * h))
    return phi1, phi2


class ModalSimulator:
    """Streams inputs through an LTI system exactly (first-order hold on the inputs).

    Parameters
    ----------
    ss : StateSpace
    dt : float  [s] sample interval.
    x0 : array or "static", optional  initial state: zero (default), or "static" for the
        static equilibrium under the first input sample (rates taken as zero).
    """

    def __init__(self, ss: StateSpace, dt: float, x0: np.ndarray | None = None):
        lam, V = np.linalg.eig(ss.A)
        cond = np.linalg.cond(V)
        if not np.isfinite(cond) or cond > 1e10:
            raise np.linalg.LinAlgError(
                f"state matrix is (nearly) defective (eigenvector condition {cond:.3g}); "
                "modal stepping would lose accuracy"
            )
        self.ss, self.dt = ss, float(dt)
        self.lam = lam
        self.Vinv_B = np.linalg.solve(V, ss.B)
        self.CV = ss.C @ V
        self.a = np.exp(lam * dt)
        self.phi1, self.phi2 = _phi(lam, dt)
        self._V = V
        self._static_start = isinstance(x0, str) and x0 == "static"
        x0 = np.zeros(ss.A.shape[0]) if x0 is None or self._static_start else np.asarray(x0, float)
        self.eta = np.linalg.solve(V, x0.astype(complex))
        self.p_last: np.ndarray | None = None

    def step_chunk(self, w: np.ndarray) -> np.ndarray:
        """Outputs for the input samples ``w`` (n_samples x n_inputs) continuing the stream.

        The first sample of the very first chunk is at the initial state.
        """
        w = np.asarray(w, float)
        if len(w) == 0:
            return np.zeros((0, len(self.ss.outputs)))
        if self._static_start and self.p_last is None and len(w):
            w_static = np.where(np.arange(w.shape[1]) < w.shape[1] // 2, w[0], 0.0)
            x0 = -np.linalg.solve(self.ss.A, self.ss.B @ w_static)
            self.eta = np.linalg.solve(self._V, x0.astype(complex))
        p = w @ self.Vinv_B.T  # (N, n_modes)
        r = np.empty_like(p)
        if self.p_last is None:
            r[0] = self.eta
        else:
            r[0] = self.a * self.eta + (self.phi1 - self.phi2) * self.p_last + self.phi2 * p[0]
        r[1:] = (self.phi1 - self.phi2) * p[:-1] + self.phi2 * p[1:]
        eta = np.empty_like(r)
        for i in range(r.shape[1]):
            eta[:, i] = scipy.signal.lfilter([1.0], [1.0, -self.a[i]], r[:, i])
        self.eta = eta[-1].copy()
        self.p_last = p[-1].copy()
        return (eta @ self.CV.T).real + w @ self.ss.D.T


def simulate(ss: StateSpace, w: np.ndarray, dt: float, x0=None) -> np.ndarray:
    """Outputs (n_samples x n_outputs) for inputs ``w`` sampled every ``dt`` seconds."""
    return ModalSimulator(ss, dt, x0).step_chunk(w)
