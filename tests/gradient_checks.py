"""Shared by the response-fit tests: a fit's exact cost gradient against central differences."""
from __future__ import annotations

import numpy as np
import pytest


def assert_gradient_is_exact(problem) -> None:
    """``problem.cost``'s gradient (every parameter free) equals central differences of its
    cost at a point off the optimum, drawn inside its bounds."""
    x = problem.lo + np.random.default_rng(1).uniform(0.2, 0.8, problem.lo.size) * (problem.hi - problem.lo)
    every, none = np.ones(x.size, bool), np.zeros(x.size, bool)
    _, grad = problem.cost(x, every)
    step = 1e-5 * np.maximum(1.0, np.abs(x))
    numeric = [(problem.cost(x + h * e, none)[0] - problem.cost(x - h * e, none)[0]) / (2 * h)
               for h, e in zip(step, np.eye(x.size))]
    assert grad == pytest.approx(numeric, rel=1e-4, abs=1e-4 * np.max(np.abs(numeric)))
