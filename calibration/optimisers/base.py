"""What every global optimiser shares: the searched parameters and the result.

An objective maps a population (N, d) of parameter rows to (N,) values, so each iteration
is one batched model evaluation. Optimisers are registered in
:data:`calibration.optimisers.OPTIMISERS`, and the tests loop over that registry.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SearchParameter:
    """One searched parameter (SI): initial mean and deviation (Cross-Entropy), range, and
    the convergence range of the seed's Table 7. ``low``/``high`` None: no range given
    (Cross-Entropy truncates at zero only; a swarm needs finite ranges)."""

    name: str
    mean: float
    std: float
    low: float | None
    high: float | None
    convergence_range: float

    def __post_init__(self):
        if not (np.isfinite(self.mean) and np.isfinite(self.std) and self.std > 0 and self.convergence_range > 0):
            raise ValueError(f"{self.name}: mean and std must be finite, std and convergence range > 0")
        for bound in (self.low, self.high):
            if bound is not None and not np.isfinite(bound):
                raise ValueError(f"{self.name}: a range limit must be finite (leave it out for none)")
        if self.low is not None and self.high is not None and not self.low < self.high:
            raise ValueError(f"{self.name}: low = {self.low} must be below high = {self.high} (infeasible bounds)")
        lo = 0.0 if self.low is None else self.low
        hi = np.inf if self.high is None else self.high
        if not lo <= self.mean <= hi:
            raise ValueError(f"{self.name}: initial mean {self.mean} outside [{lo}, {hi}]")


def bounds(parameters) -> tuple[np.ndarray, np.ndarray]:
    low = np.array([0.0 if p.low is None else p.low for p in parameters])
    high = np.array([np.inf if p.high is None else p.high for p in parameters])
    return low, high
