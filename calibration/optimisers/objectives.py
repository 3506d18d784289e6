"""Objectives over labelled frequencies, for a population at once.

``F`` maps a mode label to an (N,) array of model frequencies [Hz]; ``targets`` maps the
same labels to measured frequencies [Hz].
"""
from __future__ import annotations

import numpy as np


def sum_squared_error(F: dict, targets: dict) -> np.ndarray:
    """In-service seed eq. 1: sum over targeted modes of (f - f_target)^2 [Hz^2]."""
    return sum((np.asarray(F[k]) - f) ** 2 for k, f in targets.items())


def max_relative_error(F: dict, targets: dict) -> np.ndarray:
    """RTRI seed eq. 3: the largest |f - f_target| / f_target over the targeted modes [-]."""
    return np.max(np.stack([np.abs(np.asarray(F[k]) / f - 1.0) for k, f in targets.items()]), axis=0)


OBJECTIVES = {"sse": sum_squared_error, "max_rel": max_relative_error}
