"""Least squares of a model family against measured FRFs: the exact residual (the complex
log ratio log(H_model / H_meas) weighted by its standard deviation), a smoothed one for a
continuation from a rough start, and the bounded trust-region solve."""
from __future__ import annotations

import functools

import numpy as np
import scipy.optimize

from .data import MeasuredFRF
from .family import Family
from .frf import normalised_error


def residual(meas: MeasuredFRF, H: np.ndarray, floor: float) -> np.ndarray:
    """log|H / H_meas| and the phase of H / H_meas, each over its standard deviation
    sqrt(2 (sigma^2 + floor^2)), stacked: its squared norm is the number of lines times the
    sum over channels of E_o (:mod:`.frf`)."""
    q = H / meas.H
    scale = 1.0 / np.sqrt(2 * (meas.sigma2 + floor**2))
    return np.concatenate([(np.log(np.abs(q)) * scale).ravel(), (np.angle(q) * scale).ravel()])


def smoother(f: np.ndarray, width: float) -> np.ndarray:
    """(n_f, n_f) Gaussian smoothing in log frequency, standard deviation ``width``
    (relative), rows summing to 1."""
    d = np.log(f)[:, None] - np.log(f)[None, :]
    S = np.exp(-0.5 * (d / width) ** 2)
    return S / S.sum(axis=1, keepdims=True)


class SmoothResidual:
    """Residual of the smoothed power spectra, log(S |H_model|^2) - log(S |H_meas|^2) (in
    units of 0.1), every third line: misaligned peaks of model and measurement still
    overlap, so a fit from a rough start is drawn towards them (a continuation step
    before the exact residual)."""

    def __init__(self, meas: MeasuredFRF, width: float):
        self.S = smoother(meas.frequency, width)[::3]
        self.ref = np.log(self.S @ np.abs(meas.H) ** 2)

    def __call__(self, H) -> np.ndarray:
        return ((np.log(self.S @ np.abs(H) ** 2) - self.ref) / 0.1).ravel()


def jacobian(fam: Family, x, meas: MeasuredFRF, floor: float, free: np.ndarray, hi: np.ndarray,
             residual_of=None) -> np.ndarray:
    """d :func:`residual` / d x[free] at ``x`` (or of ``residual_of``, a smoothed residual,
    whose damping columns are differenced too). The damping columns of the exact residual
    are exact, the others forward differences (step 1e-4 in the log units of the factors
    and the extension's parameters, 0.1 mm for a mount point [m]; backwards where ``hi``
    is nearer)."""
    lay = fam.layout
    exact = residual_of is None
    residual_of = functools.partial(residual, meas, floor=floor) if exact else residual_of
    scale = 1.0 / np.sqrt(2 * (meas.sigma2 + floor**2))
    bad = np.full(residual_of(meas.H).size, 1e3)
    H, dH = fam.accelerance(x, meas.frequency, zeta_derivatives=True)
    r0 = residual_of(H) if np.all(np.isfinite(H)) and not np.any(H == 0) else bad
    cols = []
    for j in np.flatnonzero(free):
        if exact and lay.n_p <= j < lay.n_p + lay.n_slots:
            q = dH[j - lay.n_p] / H * scale
            cols.append(np.concatenate([q.real.ravel(), q.imag.ravel()]))
            continue
        h = 1e-4 * max(1.0, abs(x[j]))
        h = -h if x[j] + h > hi[j] else h
        xh = np.array(x, float)
        xh[j] += h
        Hh = fam.accelerance(xh, meas.frequency)
        rh = residual_of(Hh) if np.all(np.isfinite(Hh)) and not np.any(Hh == 0) else bad
        cols.append((rh - r0) / h)
    return np.column_stack(cols)


def least_squares(fam: Family, x0, lo, hi, meas: MeasuredFRF, max_nfev: int, floor: float,
                  free: np.ndarray | None = None, smooth: float = 0.0) -> np.ndarray:
    """Bounded trust-region least squares of :func:`residual` (or, with ``smooth`` > 0,
    of :class:`SmoothResidual` of that relative width) over the ``free`` unknowns of ``x0``
    (bounds ``lo``, ``hi``; Jacobian :func:`jacobian`); returns the whole vector."""
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    free = np.ones(x0.size, bool) if free is None else np.asarray(free, bool)
    smoothed = SmoothResidual(meas, smooth) if smooth else None
    residual_of = smoothed or functools.partial(residual, meas, floor=floor)
    bad = np.full(residual_of(meas.H).size, 1e3)

    def full(xf):
        x = x0.copy()
        x[free] = xf
        return x

    def fun(xf):
        H = fam.accelerance(full(xf), meas.frequency)
        if not np.all(np.isfinite(H)) or np.any(H == 0):
            return bad
        return residual_of(H)

    def jac(xf):
        return jacobian(fam, full(xf), meas, floor, free, hi, smoothed)

    res = scipy.optimize.least_squares(fun, x0[free], jac=jac, bounds=(lo[free], hi[free]), method="trf",
                                       max_nfev=max_nfev, x_scale=1.0)
    return full(res.x)


def total_error(fam: Family, x, meas: MeasuredFRF, floor: float) -> float:
    """Sum over channels of E_o of the family at ``x`` against ``meas`` [-]."""
    return float(np.sum(normalised_error(meas, fam.accelerance(x, meas.frequency), floor)))
