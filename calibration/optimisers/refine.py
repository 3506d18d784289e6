"""Constrained refinement after the global search, formulated in CasADi and solved by IPOPT.

Unknowns: the scaled parameters x (p = p_start * x) and, for every targeted mode i, its
eigenpair (lambda_i = w_i^2, phi_i). Constraints, exact and differentiated by CasADi's
algorithmic differentiation (no finite differences):

    K(p) phi_i - lambda_i M(p) phi_i = 0,    phi_i^T M(p) phi_i = 1,

with M and K linear in the parameters (:class:`calibration.models.batch.LinearFamily`),
parameter bounds (the search ranges; e.g. the carbody mass within the load build-up of the
seed's Table 5), lambda_i > 0. Objective: the sum of squared relative frequency errors,
sum_i (sqrt(lambda_i) / (2 pi f_i) - 1)^2. It starts at the global optimum with the
eigenpairs of the modes labelled as the targets there, and never returns a worse objective
than its start, judged by the caller's objective (``judge``, default the NLP's own): if
IPOPT ends worse by that measure (or fails), the start is returned, and it says so. The
end point is judged on the labelled frequencies of the model there, so a tracked eigenpair
that drifted onto another mode cannot pass for a fit.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from ..models.batch import LinearFamily


@dataclass(frozen=True)
class RefineResult:
    parameters: np.ndarray  # in the family's parameter order
    frequencies_hz: dict
    objective_start: float
    objective_end: float
    max_relative_error: float
    status: str  # IPOPT's return status
    improved: bool  # False: the start was kept


def _relative_sse(f: dict, targets: dict) -> float:
    return float(sum((f[k] / v - 1) ** 2 for k, v in targets.items()))


def _judged(family: LinearFamily, p: np.ndarray, targets: dict, judge) -> tuple[float, dict]:
    F = family.frequencies(p[None, :])
    f = {k: float(F[k][0]) for k in targets}
    return float(judge(f, targets)), f


def refine(family: LinearFamily, p_start: np.ndarray, targets: dict, low: np.ndarray, high: np.ndarray, *,
           judge=None, tol: float = 1e-14, max_iter: int = 500, step_weight: float = 0.0) -> RefineResult:
    """``judge(frequencies: dict, targets: dict) -> float`` decides what "worse" means.
    ``step_weight`` > 0 adds step_weight * sum_j (p_j / p_start_j - 1)^2 to the objective:
    with more parameters than targets it picks the smallest change that fits (the box
    model refines in rounds on a basis that is accurate near its centre)."""
    judge = _relative_sse if judge is None else judge
    p_start = np.asarray(p_start, float)
    labels = tuple(targets)
    n = len(family.dofs)
    d = len(family.names)
    x = ca.SX.sym("x", d)
    p = x * ca.DM(p_start)
    M = ca.DM(family.M0)
    K = ca.DM(family.K0)
    for j, name in enumerate(family.names):
        M = M + p[j] * ca.DM(family.M_unit[name])
        K = K + p[j] * ca.DM(family.K_unit[name])
    lam = ca.SX.sym("lam", len(labels))
    phis = [ca.SX.sym(f"phi_{i}", n) for i in range(len(labels))]
    g, f = [], 0
    for i, lbl in enumerate(labels):
        g.append(K @ phis[i] - lam[i] * (M @ phis[i]))
        g.append(phis[i].T @ M @ phis[i] - 1)
        w_target = 2 * np.pi * targets[lbl]
        f = f + (ca.sqrt(lam[i]) / w_target - 1) ** 2
    if step_weight:
        f = f + step_weight * ca.sumsqr(x - 1)
    z = ca.vertcat(x, lam, *phis)
    solver = ca.nlpsol("refine", "ipopt", {"x": z, "f": f, "g": ca.vertcat(*g)},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": tol,
                        "ipopt.max_iter": max_iter})
    pairs = [family.labelled_mode(p_start, lbl) for lbl in labels]
    z0 = np.concatenate([np.ones(d), [w2 for w2, _ in pairs], *[phi for _, phi in pairs]])
    inf = np.inf
    lbz = np.concatenate([low / p_start, np.full(len(labels), 1e-9), np.full(n * len(labels), -inf)])
    ubz = np.concatenate([high / p_start, np.full(len(labels), inf), np.full(n * len(labels), inf)])
    ng = sum(int(gi.numel()) for gi in g)
    sol = solver(x0=z0, lbx=lbz, ubx=ubz, lbg=np.zeros(ng), ubg=np.zeros(ng))
    status = solver.stats()["return_status"]
    p_end = np.clip(np.array(sol["x"][:d]).ravel() * p_start, low, high)
    obj_start, f_start = _judged(family, p_start, targets, judge)
    obj_end, f_end = _judged(family, p_end, targets, judge)
    improved = bool(np.isfinite(obj_end) and obj_end < obj_start)
    if not improved:
        p_end, obj_end, f_end = p_start, obj_start, f_start
    max_rel = max(abs(f_end[k] / v - 1) for k, v in targets.items())
    return RefineResult(p_end, f_end, obj_start, obj_end, float(max_rel), status, improved)
