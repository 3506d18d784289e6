"""One linearised minimax step, the core of a sequential-LP fit of frequencies.

Given the model-over-target frequency ratios r (m,) at log factors q and their derivatives
G = d r / d log p (m, n), the step d minimises t subject to

    -t <= r_i + (G d)_i - 1 <= t          (every target, relative error)
    c_j + (C d)_j >= floor                (optional: quantities kept above a floor, e.g. MACs)
    |d_k| <= trust,  lo_k <= q_k + d_k <= hi_k,

a linear programme (HiGHS). The predicted max relative error is t. With a ``step_cost`` c
the LP minimises t + c sum_k |d_k| instead: of the steps that reach (nearly) the same t it
takes the smallest, so factors the errors hardly depend on stay where they are rather than
riding to a corner of the region at every step. With a shortfall
penalty (each target's MAC a_i, its derivatives J, a floor and a weight w, as the box fit
scores an unsound pairing), target i's row becomes |r_i + (G d)_i - 1| + w s_i <= t with
s_i >= floor - a_i - (J d)_i and s_i >= 0: t is then the linearised *scored* error, and a
step may lift a MAC back over its floor where that pays.
"""
from __future__ import annotations

import numpy as np


def linearised_minimax(ratio, G, q, lo, hi, trust: float, keep=None, keep_grad=None, floor=0.0, penalty=None,
                       step_cost: float = 0.0):
    """The step d in log factors minimising max |ratio + G d - 1| within +-``trust`` of ``q``
    and inside [``lo``, ``hi``]; with ``keep`` (k,) and its derivatives ``keep_grad`` (k, n),
    also keeps keep + keep_grad d >= ``floor`` (a number or one per row); with ``penalty`` =
    (a (m,), J (m, n), floor, weight), each target's error carries weight x its linearised
    shortfall of a under the floor; ``step_cost`` per unit of |d| (summed over the factors)
    is added to the objective. Returns (d, the predicted max t), or None if the LP has no
    solution (e.g. the floor cannot be kept within the region)."""
    from scipy.optimize import linprog

    G = np.asarray(G, float)
    m, n = G.shape
    ns = m if penalty is not None else 0  # shortfall slacks
    W = np.zeros((m, ns)) if penalty is None else penalty[3] * np.eye(m)
    A = np.vstack([np.hstack([G, -np.ones((m, 1)), W]), np.hstack([-G, -np.ones((m, 1)), W])])
    b = np.concatenate([1 - np.asarray(ratio, float), np.asarray(ratio, float) - 1])
    if penalty is not None:  # -J d - s <= a - floor
        a, J, pfloor, _ = penalty
        A = np.vstack([A, np.hstack([-np.asarray(J, float), np.zeros((m, 1)), -np.eye(m)])])
        b = np.concatenate([b, np.asarray(a, float) - pfloor])
    if keep is not None:
        K = np.asarray(keep_grad, float)
        A = np.vstack([A, np.hstack([-K, np.zeros((K.shape[0], 1 + ns))])])
        b = np.concatenate([b, np.asarray(keep, float) - floor])
    nu = n if step_cost > 0 else 0  # u_k >= |d_k|
    A = np.hstack([A, np.zeros((A.shape[0], nu))])
    if nu:
        I = np.eye(n)
        A = np.vstack([A, np.hstack([I, np.zeros((n, 1 + ns)), -I]), np.hstack([-I, np.zeros((n, 1 + ns)), -I])])
        b = np.concatenate([b, np.zeros(2 * n)])
    r = linprog(np.r_[np.zeros(n), 1.0, np.zeros(ns), np.full(nu, step_cost)], A_ub=A, b_ub=b, method="highs",
                bounds=[(max(-trust, a - x), min(trust, c - x)) for x, a, c in zip(q, lo, hi)]
                + [(0, None)] * (1 + ns + nu))
    return (r.x[:n], r.x[n]) if r.success else None
