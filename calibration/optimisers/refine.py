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


def _nlp(x, M, K, w_target, step_weight: float, tol: float, max_iter: int, parameters=None):
    """IPOPT on the eigen-equations with M(x) and K(x) (SX), the targets' angular
    frequencies ``w_target`` [rad/s] and ``parameters`` (SX) the NLP's own, if any."""
    n = M.shape[0]
    lam = ca.SX.sym("lam", len(w_target))
    phis = [ca.SX.sym(f"phi_{i}", n) for i in range(len(w_target))]
    g, f = [], 0
    for i, w in enumerate(w_target):
        g.append(K @ phis[i] - lam[i] * (M @ phis[i]))
        g.append(phis[i].T @ M @ phis[i] - 1)
        f = f + (ca.sqrt(lam[i]) / w - 1) ** 2
    if step_weight:
        f = f + step_weight * ca.sumsqr(x - 1)
    nlp = {"x": ca.vertcat(x, lam, *phis), "f": f, "g": ca.vertcat(*g)}
    if parameters is not None:
        nlp["p"] = parameters
    return ca.nlpsol("refine", "ipopt", nlp, {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                                              "ipopt.tol": tol, "ipopt.max_iter": max_iter})


#: the last NLP built with its stiffness matrices as parameters (:func:`_reused_nlp`), one
#: only: on the reduced box (60 DOF, 12 factors, 8 targets) it holds about 200 MB
_REUSED: dict = {}


def _nonzeros(A: np.ndarray) -> np.ndarray:
    return A.ravel(order="F")[A.ravel(order="F") != 0]


def _as_parameter(A: np.ndarray, name: str) -> tuple[ca.SX, ca.SX]:
    """(A with a symbol for each of its non-zero entries, those symbols, in
    :func:`_nonzeros`' order): an entry that is zero stays the constant zero, so that the
    NLP's expressions and derivatives, and their sparsity, are those of A as a constant."""
    nz = np.flatnonzero(A.ravel(order="F") != 0)
    sym = ca.SX.sym(name, nz.size)
    entries = [ca.SX(0)] * A.size
    for k, i in enumerate(nz):
        entries[i] = sym[k]
    return ca.reshape(ca.vertcat(*entries), *A.shape), sym


def _reused_nlp(family: LinearFamily, p_start: np.ndarray, w_target: tuple, step_weight: float, tol: float,
                max_iter: int):
    """(solver, its parameters' values) for a family of the box's reduced form (mass I, the
    stiffness K0 + sum_j p_j K_j), with the entries of K0 and p_start_j K_j the NLP's
    parameters, or None for another family. Building the NLP (CasADi's derivatives of the
    eigen-equations) costs seconds on the reduced box, solving it a fraction of that, and
    the box refines in rounds of one size and targets, each on a new basis: one NLP serves
    them all.

    Its arithmetic is that of the NLP with the matrices as constants, operation for
    operation (tests/test_optimisers.py): CasADi folds p_start_j x an entry of K_j into one
    constant, which comes here as that product; it turns a product by 1 or -1 into the
    other factor, sharing a node that a parameter would not, so a family whose mass is not
    I, or with an entry 1 or -1 in a K_j, is built the constant way."""
    n, names = len(family.dofs), family.names
    if not np.array_equal(family.M0, np.eye(n)) or any(np.any(family.M_unit[k]) for k in names):
        return None
    units = [np.asarray(family.K_unit[k], float) for k in names]
    scaled = [p_start[j] * K for j, K in enumerate(units)]
    if any(np.any(np.abs(K) == 1) for K in units + scaled):
        return None
    stiffness = [np.asarray(family.K0, float), *scaled]
    key = (w_target, step_weight, tol, max_iter, *((A.shape, np.packbits(A != 0).tobytes()) for A in stiffness))
    if key not in _REUSED:
        x = ca.SX.sym("x", len(names))
        K, *Ks = (_as_parameter(A, f"K{j}") for j, A in enumerate(stiffness))
        M, stiff = ca.DM(np.eye(n)), K[0]
        for j in range(len(names)):
            M = M + x[j] * ca.DM(np.zeros((n, n)))
            stiff = stiff + x[j] * Ks[j][0]
        _REUSED.clear()
        _REUSED[key] = _nlp(x, M, stiff, w_target, step_weight, tol, max_iter,
                            ca.vertcat(K[1], *(sym for _, sym in Ks)))
    return _REUSED[key], {"p": np.concatenate([_nonzeros(A) for A in stiffness])}


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
    w_target = tuple(2 * np.pi * targets[lbl] for lbl in labels)
    reused = _reused_nlp(family, p_start, w_target, step_weight, tol, max_iter)
    if reused is not None:
        solver, values = reused
    else:
        x = ca.SX.sym("x", d)
        p = x * ca.DM(p_start)
        M = ca.DM(family.M0)
        K = ca.DM(family.K0)
        for j, name in enumerate(family.names):
            M = M + p[j] * ca.DM(family.M_unit[name])
            K = K + p[j] * ca.DM(family.K_unit[name])
        solver, values = _nlp(x, M, K, w_target, step_weight, tol, max_iter), {}
    pairs = [family.labelled_mode(p_start, lbl) for lbl in labels]
    z0 = np.concatenate([np.ones(d), [w2 for w2, _ in pairs], *[phi for _, phi in pairs]])
    inf = np.inf
    lbz = np.concatenate([low / p_start, np.full(len(labels), 1e-9), np.full(n * len(labels), -inf)])
    ubz = np.concatenate([high / p_start, np.full(len(labels), inf), np.full(n * len(labels), inf)])
    ng = (n + 1) * len(labels)  # K phi_i - lambda_i M phi_i and phi_i^T M phi_i - 1
    sol = solver(x0=z0, lbx=lbz, ubx=ubz, lbg=np.zeros(ng), ubg=np.zeros(ng), **values)
    status = solver.stats()["return_status"]
    p_end = np.clip(np.array(sol["x"][:d]).ravel() * p_start, low, high)
    obj_start, f_start = _judged(family, p_start, targets, judge)
    obj_end, f_end = _judged(family, p_end, targets, judge)
    improved = bool(np.isfinite(obj_end) and obj_end < obj_start)
    if not improved:
        p_end, obj_end, f_end = p_start, obj_start, f_start
    max_rel = max(abs(f_end[k] / v - 1) for k, v in targets.items())
    return RefineResult(p_end, f_end, obj_start, obj_end, float(max_rel), status, improved)
