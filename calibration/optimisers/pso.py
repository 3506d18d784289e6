"""Particle swarm optimisation (Kennedy & Eberhart, Proc. ICNN 1995) with the inertia
weight of Shi & Eberhart (1998) and the constriction-equivalent coefficients of Clerc &
Kennedy (IEEE TEC 6, 2002): w = 0.7298, c1 = c2 = 1.49618.

Each particle remembers its best position; the swarm its global best. Velocities are
clamped to ``max_velocity`` times each parameter's range, positions to the ranges. The
RTRI seed's stopping rule: stop when the best objective reaches ``target`` (its 0.5 %) or
after ``iterations`` (its 1000). The whole swarm is evaluated in one call per iteration.

An objective that refines itself as the search narrows (the box model's reduced basis is
rebuilt around the swarm's best) passes ``adapt(iteration, global_best) -> bool``; when
it returns True the objective has changed, and every particle's remembered best is
re-evaluated with it so that old and new values are never compared. Reaching ``target``
is confirmed the same way, with ``adapt(iteration, global_best, force=True)``: the search
stops only if the best still meets the target once the objective is exact there.

Objective values are compared at ``digits`` significant digits. A swarm's path is a
chain of comparisons (is this particle better than its best? which is the swarm's best?),
so a difference in the last bits of one value, such as the round-off of a BLAS call on
two threads instead of one, changes every position after it and the answer with them;
values that agree to ``digits`` digits are ties, kept in the same order on any machine
(the relative round-off of the box model's eigen-solves is about 1e-13, its errors are
reported to 3 digits; 0: exact comparisons).

``on_iteration(iteration, best_value)``, if given, is called after every iteration (a
progress bar's hook); it does not change the search.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import checks
from .base import SearchParameter, bounds


@dataclass(frozen=True)
class PSOSettings:
    particles: int = 1000  # RTRI seed
    iterations: int = 1000  # RTRI seed
    target: float = 0.0  # stop when the best objective is at or below this
    inertia: float = 0.7298
    cognitive: float = 1.49618
    social: float = 1.49618
    max_velocity: float = 0.2  # fraction of each range per iteration
    digits: int = 9  # significant digits objective values are compared at (0: all)

    def __post_init__(self):
        checks.whole(self, "particles", minimum=2)
        checks.whole(self, "iterations")
        checks.non_negative(self, "target", "inertia", "cognitive", "social")
        checks.positive(self, "max_velocity")
        if not 0 <= self.digits <= 15:
            raise ValueError(f"PSOSettings.digits must lie in 0..15, got {self.digits}")


def resolved(values, digits: int) -> np.ndarray:
    """``values`` rounded to ``digits`` significant digits (all of them for 0); not finite: inf."""
    v = np.asarray(values, float)
    v = np.where(np.isfinite(v), v, np.inf)
    if digits <= 0:
        return v
    with np.errstate(divide="ignore", invalid="ignore"):
        q = 10.0 ** (np.floor(np.log10(np.abs(v))) - digits + 1)
        return np.where(np.isfinite(q) & (q > 0), np.round(v / q) * q, v)


@dataclass(frozen=True)
class PSOResult:
    names: tuple[str, ...]
    best: np.ndarray
    best_value: float
    iterations: int
    evaluations: int
    reached_target: bool
    history: list = field(repr=False, default_factory=list)  # best value per iteration


def particle_swarm(objective, parameters: tuple[SearchParameter, ...], rng: np.random.Generator, *,
                   settings: PSOSettings = PSOSettings(), adapt=None, on_iteration=None) -> PSOResult:
    names = tuple(p.name for p in parameters)
    low, high = bounds(parameters)
    if not (np.all(np.isfinite(high)) and np.all(np.isfinite(low))) or any(p.low is None for p in parameters):
        missing = [p.name for p in parameters if p.low is None or p.high is None
                   or not np.isfinite(p.low) or not np.isfinite(p.high)]
        raise ValueError(f"a swarm needs a finite range for every parameter; none given for {', '.join(missing)}")
    span = high - low
    n, d = settings.particles, len(parameters)
    x = low + rng.uniform(size=(n, d)) * span
    v = (rng.uniform(size=(n, d)) - 0.5) * span * settings.max_velocity
    fx = resolved(objective(x), settings.digits)
    p_best, p_val = x.copy(), fx.copy()
    g = int(np.argmin(p_val))
    history = [float(p_val[g])]
    evaluations, it = n, 0
    while it < settings.iterations and p_val[g] > settings.target:
        it += 1
        r1, r2 = rng.uniform(size=(n, d)), rng.uniform(size=(n, d))
        v = (settings.inertia * v + settings.cognitive * r1 * (p_best - x)
             + settings.social * r2 * (p_best[g] - x))
        v = np.clip(v, -settings.max_velocity * span, settings.max_velocity * span)
        x = np.clip(x + v, low, high)
        fx = resolved(objective(x), settings.digits)
        evaluations += n
        better = fx < p_val
        p_best[better], p_val[better] = x[better], fx[better]
        g = int(np.argmin(p_val))
        if adapt is not None and (adapt(it, p_best[g].copy())
                                  or (p_val[g] <= settings.target and adapt(it, p_best[g].copy(), force=True))):
            p_val = resolved(objective(p_best), settings.digits)
            evaluations += n
            g = int(np.argmin(p_val))
        history.append(float(p_val[g]))
        if on_iteration is not None:
            on_iteration(it, history[-1])
    return PSOResult(names, p_best[g].copy(), float(p_val[g]), it, evaluations,
                     bool(p_val[g] <= settings.target), history)
