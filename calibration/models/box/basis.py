"""Orthonormal Legendre polynomials on [-1, 1] and their exact 1D integrals.

A panel's fields are double series p_i(xi) p_j(eta) of the orthonormal Legendre
polynomials p_i = sqrt((2 i + 1) / 2) P_i, so every energy integral over the rectangle
is a Kronecker product of 1D integrals E[r, s][i, k] = int p_i^(r) p_k^(s) dxi, computed
once per order by Gauss-Legendre quadrature that is exact for the polynomial degree.
Orders 0 and 1 hold the rigid motions, so each panel carries its six rigid degrees of
freedom (seed section 2.1).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
from numpy.polynomial import legendre


@lru_cache(maxsize=None)
def _coefficients(order: int, derivative: int = 0) -> tuple[np.ndarray, ...]:
    """Legendre-series coefficients of p_0^(derivative) .. p_order^(derivative), made once
    per (order, derivative)."""
    out = []
    for i in range(order + 1):
        c = np.zeros(i + 1)
        c[i] = np.sqrt((2 * i + 1) / 2)
        d = legendre.legder(c, derivative) if derivative else c
        d.setflags(write=False)
        out.append(d)
    return tuple(out)


def values(order: int, x: np.ndarray, derivative: int = 0) -> np.ndarray:
    """(len(x), order + 1): the ``derivative``-th derivative of p_0 .. p_order at x.

    Evaluate a whole quadrature grid in one call: the cost is one ``legval`` per
    polynomial, whatever the number of points."""
    x = np.atleast_1d(np.asarray(x, float))
    cols = [legendre.legval(x, d) if d.size else np.zeros_like(x) for d in _coefficients(order, derivative)]
    return np.stack(cols, axis=1)


@lru_cache(maxsize=None)
def integrals(order: int) -> dict[tuple[int, int], np.ndarray]:
    """E[(r, s)] = int_{-1}^{1} p_i^(r) p_k^(s) dxi for r, s in 0..2, each (order+1)^2."""
    return integrals_over(order, ((-1.0, 1.0),))


@lru_cache(maxsize=None)
def integrals_over(order: int, intervals: tuple[tuple[float, float], ...]) -> dict[tuple[int, int], np.ndarray]:
    """As :func:`integrals`, over the union of ``intervals`` ((lo, hi) within [-1, 1], not
    overlapping) instead of the whole of [-1, 1]: on each, the Gauss rule exact up to degree
    2 order + 3 (mapped so that (-1, 1) takes its nodes and weights unchanged)."""
    xg, wg = legendre.leggauss(order + 2)
    out = {(r, s): np.zeros((order + 1, order + 1)) for r in range(3) for s in range(3)}
    for lo, hi in intervals:
        if not -1.0 <= lo < hi <= 1.0:
            raise ValueError(f"interval ({lo}, {hi}) is not inside [-1, 1]")
        x, w = (lo + hi) / 2 + xg * (hi - lo) / 2, wg * (hi - lo) / 2
        V = [values(order, x, r) for r in range(3)]
        for r in range(3):
            for s in range(3):
                out[(r, s)] += (V[r] * w[:, None]).T @ V[s]
    return out
