"""Frequencies of a whole population of parameter sets in one batched eigen-solve.

For fixed geometry the 2D car's mass matrix is linear in the masses and inertias and its
stiffness matrix linear in the stiffnesses: M(p) = sum_i p_i M_i, K(p) = sum_j p_j K_j.
:class:`LinearFamily` assembles each unit matrix once, with the same builder that makes a
single model (exact: the matrices are linear, so a difference of two assemblies is the
unit matrix to round-off), and then solves a population of eigenproblems at once:
M^-1/2 K M^-1/2 is symmetric because M is diagonal here, so ``numpy.linalg.eigh`` runs
over the whole batch. Modes are labelled per parameter set by their kinetic energy, as
:func:`calibration.models.car2d.undamped_modes` does.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .car2d import _GROUPS, build_car
from .parameters import CarParameters

MASS_NAMES = ("m_v", "J_v", "m_b", "J_b")
LABELS = tuple(_GROUPS)  # mode labels, in the order of the label indices of LinearFamily.modes
STIFFNESS_NAMES = ("k_p", "k_s")


@dataclass(frozen=True)
class LinearFamily:
    """The 6-DOF car at fixed geometry as M(p), K(p) linear in the parameters ``names``."""

    base: CarParameters
    names: tuple[str, ...]
    dofs: tuple[str, ...]
    M0: np.ndarray
    K0: np.ndarray
    M_unit: dict
    K_unit: dict

    @classmethod
    def of_car(cls, base: CarParameters, names=MASS_NAMES + STIFFNESS_NAMES) -> "LinearFamily":
        unknown = [n for n in names if n not in MASS_NAMES + STIFFNESS_NAMES]
        if unknown:
            raise ValueError(f"parameters {unknown} do not enter M or K linearly at fixed geometry")
        ref = build_car(base)
        M_unit, K_unit = {}, {}
        for n in names:
            bumped = build_car(base.replace(**{n: 2 * getattr(base, n)}))
            v = getattr(base, n)
            M_unit[n] = (bumped.M - ref.M) / v
            K_unit[n] = (bumped.K - ref.K) / v
        M0 = ref.M - sum(getattr(base, n) * M_unit[n] for n in names)
        K0 = ref.K - sum(getattr(base, n) * K_unit[n] for n in names)
        if np.abs(M0 - np.diag(np.diag(M0))).max() > 0 or any(
                np.abs(m - np.diag(np.diag(m))).max() > 0 for m in M_unit.values()):
            raise ValueError("the batched solver needs a diagonal mass matrix")
        return cls(base, tuple(names), ref.dofs, M0, K0, M_unit, K_unit)

    def matrices(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, n, n) mass and stiffness matrices for parameter rows P (N, len(names))."""
        P = np.atleast_2d(P)
        M = self.M0 + np.einsum("ni,ijk->njk", P, np.stack([self.M_unit[n] for n in self.names]))
        K = self.K0 + np.einsum("ni,ijk->njk", P, np.stack([self.K_unit[n] for n in self.names]))
        return M, K

    def modes(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Batched undamped modes of parameter rows P: frequencies f (N, n) [Hz] ascending,
        mass-normalised shapes phi (N, n, n) (columns, phi^T M phi = 1) and the label of
        each mode (N, n) as an index into ``LABELS``, by kinetic energy as ``undamped_modes``."""
        M, K = self.matrices(P)
        d = np.sqrt(np.einsum("njj->nj", M))
        w2, V = np.linalg.eigh(K / d[:, :, None] / d[:, None, :])
        f = np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi)
        energy = V**2  # of the M^1/2-scaled shapes: kinetic energy fraction per DOF
        scores = np.stack([energy[:, [self.dofs.index(x) for x in dofs if x in self.dofs], :].sum(axis=1)
                           for dofs in _GROUPS.values()], axis=1)  # (N, n_groups, n_modes)
        return f, V / d[:, :, None], np.argmax(scores, axis=1)

    def labelled_mode(self, p: np.ndarray, label: str) -> tuple[float, np.ndarray]:
        """(w^2 [rad^2/s^2], mass-normalised shape) of the lowest mode labelled ``label`` at one row."""
        f, phi, label_of = self.modes(np.asarray(p, float)[None, :])
        ks = np.flatnonzero(label_of[0] == LABELS.index(label))
        if ks.size == 0:
            raise ValueError(f"no {label} mode at these parameters")
        k = int(ks[np.argmin(f[0, ks])])
        return float((2 * np.pi * f[0, k]) ** 2), phi[0, :, k]

    def frequencies(self, P: np.ndarray) -> dict[str, np.ndarray]:
        """Undamped frequencies [Hz] by label for each parameter row; shape (N,) per label.

        Labels follow the kinetic-energy rule of ``undamped_modes``; of modes sharing a label
        (the bogie pairs) the lowest is reported, as :func:`frequencies_by_label` does. A
        parameter row without a mode of some label gets NaN for it.
        """
        f, _, label_of = self.modes(P)
        out = {}
        for g, name in enumerate(LABELS):
            mask = label_of == g
            if not mask.any():
                continue
            lowest = np.where(mask, f, np.inf).min(axis=1)
            out[name] = np.where(np.isfinite(lowest), lowest, np.nan)
        return out
