"""Refinement of a box calibration after the swarm: the CasADi NLP on the reduced model
(:func:`refine_box`) and the sequential-LP polish on the full model that keeps the MAC
floor (:func:`polish_box`)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .models.box.fit import MAC_SHORTFALL_PCT, BoxFit
from .optimisers.minimax import linearised_minimax
from .optimisers.refine import refine


@dataclass(frozen=True)
class BoxRefinement:
    parameters: np.ndarray
    start_max_error_pct: float  # full model, at the start
    max_error_pct: float  # full model, at the end
    rounds: int
    statuses: tuple[str, ...]


def refine_box(fit: BoxFit, p_start, low, high, *, rounds: int = 10, trust: float = 0.2,
               step_weight: float = 1e-6, tol_pct: float = 1e-4) -> BoxRefinement:
    """CasADi refinement (eigen-equations as constraints, :func:`refine`) on the reduced
    model, in rounds: the basis is rebuilt at the current point, the NLP takes the smallest
    change that fits (``step_weight``) inside +-``trust``, and the round is accepted only
    if the *full* model's RTRI error improves (otherwise the region is halved). Each round
    starts where the basis is exact, so the error falls as the steps shrink. Never returns
    a worse full-model error than its start; stops at ``tol_pct`` [%]."""
    targets = {t.label: t.frequency_hz for t in fit.targets}
    low, high = np.asarray(low, float), np.asarray(high, float)
    p = np.asarray(p_start, float)
    start = best = fit.full_check(p)["max_error_pct"]
    statuses = []
    for k in range(rounds):
        if best <= tol_pct:
            break
        fit.rebuild(p)
        lo, hi = np.maximum(low, p * (1 - trust)), np.minimum(high, p * (1 + trust))
        r = refine(fit, p, targets, lo, hi, judge=lambda f, t: max(abs(f[x] / v - 1) for x, v in t.items()),
                   step_weight=step_weight)
        statuses.append(r.status)
        err = fit.full_check(r.parameters)["max_error_pct"]
        if err < best:
            p, best = r.parameters, err
        else:
            trust /= 2
    return BoxRefinement(p, start, best, len(statuses), tuple(statuses))


def polish_box(fit: BoxFit, p_start, low, high, *, steps: int = 20, trust: float = 0.005, margin: float = 0.005,
               min_trust: float = 1e-3, step_cost: float = 1e-5, progress=None) -> BoxRefinement:
    """Sequential linear programming on the *full* model, after :func:`refine_box` where the
    MAC floor binds: the CasADi NLP fits frequencies only, and near the answer the step it
    wants can take a pairing's MAC under ``fit.min_mac`` (a partner mixing with a close
    neighbour), so every such round is refused. Each step here linearises the partners'
    frequencies and MACs (exact eigenvalue and eigenvector derivatives,
    :meth:`BoxFit.gradients`) and takes the minimax step
    (:func:`calibration.optimisers.minimax.linearised_minimax`) within +-``trust`` in log
    factors and the bounds that keeps every linearised MAC >= the floor + ``margin`` (a MAC
    already below that: >= its value), each target's error carrying the score's penalty for
    its linearised MAC shortfall (so an unsound pairing is lifted back over the floor where
    that pays, as the score counts it), plus ``step_cost`` per unit of the step's summed |d|
    (1e-5: 0.001 % of error per 1 in log factors, a tie-break: a factor the errors do not
    see stays where it is; without it the LP, whose answers are vertices, took the four
    end-wall and floor-floor joints to the same corner at every step and they ended equal,
    2.11 each on seed Figure 5; with it the end-wall translational joint stays at 1.0-1.02,
    while the other three, each worth a little to the largest error, still ride the region's
    edge together and end equal, 2.7-3.0). A step is kept only if the full model's
    scored error falls and no sound pairing turns unsound (the score's penalty for a MAC a
    hair under the floor can be smaller than a step's gain, and a fit with an unsound
    pairing has lost a mode); the region then grows by half, else it halves, and the polish
    stops when it falls under ``min_trust`` (0.1 % of the factors). Never returns a worse
    full-model error than its start. Each step costs one full eigen-solve and, with a MAC
    floor, one sparse factorisation per target (it cost 1 + 2 d eigen-solves, d factors,
    with the MACs by central differences)."""
    q, lo, hi = np.log(np.asarray(p_start, float)), np.log(np.asarray(low, float)), np.log(np.asarray(high, float))
    check, G, J = fit.gradients(np.exp(q), macs=fit.min_mac > 0)
    start = best = check["max_error_pct"]
    statuses = []
    for _ in range(steps):
        if trust < min_trust:
            break
        keep, penalty = None, None
        if fit.min_mac > 0:
            keep = (check["mac"], J, np.minimum(check["mac"], fit.min_mac + margin))
            penalty = (check["mac"], J, fit.min_mac, MAC_SHORTFALL_PCT / 100)
        lp = linearised_minimax(check["frequency_hz"] / fit.f_target, G, q, lo, hi, trust, *(keep or ()),
                                penalty=penalty, step_cost=step_cost)
        if lp is None:
            statuses.append("no step keeps the MAC floor")
            trust /= 2
            continue
        trial, G_trial, J_trial = fit.gradients(np.exp(q + lp[0]), macs=fit.min_mac > 0)
        lost = bool(np.any(check["sound"] & ~trial["sound"]))  # a sound pairing made unsound
        kept = trial["max_error_pct"] < best and not lost
        statuses.append("kept" if kept else "unsound" if lost else "not kept")
        if progress:
            progress(f"polish step {len(statuses)}: region +-{100 * trust:.3g} %, predicted {100 * lp[1]:.3f} %, "
                     f"full model {trial['max_error_pct']:.3f} %, MAC {' '.join(f'{v:.3f}' for v in trial['mac'])}"
                     f"{'' if kept else ' (not kept: a pairing unsound)' if lost else ' (not kept)'}")
        if kept:
            q, check, G, J, best = q + lp[0], trial, G_trial, J_trial, trial["max_error_pct"]
            trust *= 1.5
        else:
            trust /= 2
    return BoxRefinement(np.exp(q), start, best, len(statuses), tuple(statuses))
