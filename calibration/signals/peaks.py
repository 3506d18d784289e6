"""Sub-sample location of a sampled maximum."""
from __future__ import annotations

import numpy as np


def parabolic_shift(y: np.ndarray, k: int) -> float:
    """Offset [samples] from ``k`` of the vertex of the parabola through y[k-1], y[k], y[k+1];
    0 at the ends of ``y`` or where the three points do not bend down."""
    if not 0 < k < len(y) - 1:
        return 0.0
    a, b, c = y[k - 1], y[k], y[k + 1]
    denom = a - 2 * b + c
    return float(0.5 * (a - c) / denom) if denom < 0 else 0.0
