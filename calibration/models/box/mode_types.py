"""Mode types of a carbody as the floor's vertical motion shows them, for targets given
by frequency and type only (no measured shape), e.g. the RTRI seed's Figure 5.

Each type is an idealised floor pattern z(x, y) in coordinates normalised to the carbody
(xi = 2 x / length in [-1, 1], eta = 2 y / width in [-1, 1]); a target of that type is
paired with the model mode of largest MAC with the pattern at the sensors (seed eq. 4).
Free-free beam shapes are used for bending (Euler beam, lambda_1 = 4.7300,
lambda_2 = 7.8532), the twist of a free-free bar for torsion.
"""
from __future__ import annotations

import numpy as np

from .fit import ModeTarget


def _beam(xi: np.ndarray, k: int) -> np.ndarray:
    lam = (4.730040745, 7.853204624)[k - 1]
    s = lam * (xi + 1) / 2
    sigma = (np.cosh(lam) - np.cos(lam)) / (np.sinh(lam) - np.sin(lam))
    return np.cosh(s) + np.cos(s) - sigma * (np.sinh(s) + np.sin(s))


MODE_TYPES = {
    "vertical_bending_1": ("first vertical bending: floor moves as a free-free beam, nodes near the bogies",
                           lambda xi, eta: _beam(xi, 1)),
    "vertical_bending_2": ("second vertical bending: antisymmetric along the car, three nodes",
                           lambda xi, eta: _beam(xi, 2)),
    "torsion_1": ("first torsion: the sections twist in opposite senses at the two ends",
                  lambda xi, eta: eta * np.sin(np.pi * xi / 2)),
    "torsion_2": ("second torsion: the ends twist alike, the middle the other way",
                  lambda xi, eta: eta * np.cos(np.pi * xi)),
    "lateral_vertical_1": ("lateral-vertical coupled (roll of the section with lateral bending): left and "
                           "right sides move oppositely, in phase along the car",
                           lambda xi, eta: eta * np.cos(np.pi * xi / 2)),
    "breathing": ("breathing: the cross-section deforms, the floor centre moving against its edges",
                  lambda xi, eta: (1 - 2 * eta**2) * np.cos(np.pi * xi / 2)),
    "breathing_2": ("second breathing: the cross-section deforms as in breathing, the front and rear halves "
                    "in opposite senses",
                    lambda xi, eta: (1 - 2 * eta**2) * np.sin(np.pi * xi)),
}


def template(mode_type: str, sensors, length: float, width: float) -> np.ndarray:
    """The pattern of ``mode_type`` at the sensors' (x, y) positions, largest entry 1."""
    if mode_type not in MODE_TYPES:
        raise KeyError(f"unknown mode type {mode_type!r}; known: {', '.join(MODE_TYPES)}")
    xy = np.array([s.position[:2] for s in sensors], float)
    z = MODE_TYPES[mode_type][1](2 * xy[:, 0] / length, 2 * xy[:, 1] / width)
    return z / np.abs(z).max()


def typed_targets(targets: dict[str, float], sensors, length: float, width: float) -> tuple[ModeTarget, ...]:
    """ModeTargets from {mode type: frequency [Hz]}."""
    return tuple(ModeTarget(label, float(f), template(label, sensors, length, width)) for label, f in targets.items())
