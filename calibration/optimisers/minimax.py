"""One linearised minimax step, the core of a sequential-LP fit of frequencies.

Given the model-over-target frequency ratios r (m,) at log factors q and their derivatives
G = d r / d log p (m, n), the step d minimises t subject to

    -t <= r_i + (G d)_i - 1 <= t          (every target, relative error)
    c_j + (C d)_j >= floor                (optional: quantities kept above a floor, e.g. MACs)
    |d_k| <= trust,  lo_k <= q_k + d_k <= hi_k,

a linear programme (HiGHS). The predicted max relative error is t.
"""
from __future__ import annotations

import numpy as np


def linearised_minimax(ratio, G, q, lo, hi, trust: float, keep=None, keep_grad=None, floor=0.0):
    """The step d in log factors minimising max |ratio + G d - 1| within +-``trust`` of ``q``
    and inside [``lo``, ``hi``]; with ``keep`` (k,) and its derivatives ``keep_grad`` (k, n),
    also keeps keep + keep_grad d >= ``floor`` (a number or one per row). Returns (d, the
    predicted max |.|), or None if the LP has no solution (e.g. the floor cannot be kept
    within the region)."""
    from scipy.optimize import linprog

    G = np.asarray(G, float)
    m, n = G.shape
    A = np.vstack([np.hstack([G, -np.ones((m, 1))]), np.hstack([-G, -np.ones((m, 1))])])
    b = np.concatenate([1 - np.asarray(ratio, float), np.asarray(ratio, float) - 1])
    if keep is not None:
        K = np.asarray(keep_grad, float)
        A = np.vstack([A, np.hstack([-K, np.zeros((K.shape[0], 1))])])
        b = np.concatenate([b, np.asarray(keep, float) - floor])
    r = linprog(np.r_[np.zeros(n), 1.0], A_ub=A, b_ub=b, method="highs",
                bounds=[(max(-trust, a - x), min(trust, c - x)) for x, a, c in zip(q, lo, hi)] + [(0, None)])
    return (r.x[:n], r.fun) if r.success else None
