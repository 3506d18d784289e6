"""Amplitude-dependent suspension: dry friction in the secondary and primary suspension,
linearised at the amplitude of each (run, speed) cell.

A friction force F sign(v) on a relative velocity v that is Gaussian with standard
deviation sigma is, in the mean-square sense, a viscous damper of

    c_eq = sqrt(2 / pi) F / sigma

(statistical linearisation: c_eq = E[F sign(v) v] / E[v^2]). Friction thus damps a quiet
ride more than a rough one: a cell's damping depends on how hard the track drives it.
sigma of each suspension element comes from the baseline car driven by the cell's
measured rail input (no response data), so held-out cells get theirs without fitting.

The training cells are sorted into :data:`CLASSES` classes of secondary amplitude (equal
counts); each class is one car, its sigma the class's mean square over its seconds, so a
fit costs :data:`CLASSES` frequency responses per evaluation, not one per cell.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ...models.assembly import elongation_rows
from ...models.car2d import CarExtras, build_car, dynamic_stiffness
from ...models.parameters import CarParameters
from .records import Statistics

#: the extension's parameters [N]: friction force of each bogie's secondary suspension and
#: of each wheelset's primary suspension (both sides together)
FRICTION = ("friction_secondary", "friction_primary")
GAUSSIAN = float(np.sqrt(2.0 / np.pi))
#: amplitude classes of the training cells
CLASSES = 4
_SECONDARY = ("secondary1", "secondary2")
_PRIMARY = ("primary1", "primary2", "primary3", "primary4")


def suspension_rms(p: CarParameters, extras: CarExtras, stats: Statistics, keys) -> dict:
    """{cell: (sigma_s, sigma_p)}: root-mean-square relative velocity [m/s] across the
    secondary and the primary suspension (over their elements) predicted by car ``p`` from
    each cell's rail input, in the statistics' bands."""
    asm = build_car(p, extras=extras)
    w = 2 * np.pi * stats.centres
    Hq = np.linalg.solve(*dynamic_stiffness(asm.K, asm.M, asm.C, asm.B_k, asm.B_c, w))  # per unit rail level
    out = {}
    T = {}
    for group in (_SECONDARY, _PRIMARY):
        rows = [elongation_rows(asm, n) for n in group]
        g = np.stack([r[0] for r in rows])
        h = np.stack([r[1] for r in rows])
        # velocity per unit rail acceleration: i w (g Hq + h) x (-1 / w^2)
        T[group] = -(1j / w)[:, None, None] * (g @ Hq + h[None])
    for k in stats.ordered(keys):
        Suu = stats.S[k][:, :4, :4]
        sec = max(stats.seconds[k], 1e-300)
        sig = []
        for group in (_SECONDARY, _PRIMARY):
            ms = np.einsum("kij,kjl,kil->i", T[group], Suu, T[group].conj()).real / sec
            sig.append(float(np.sqrt(max(ms.mean(), 1e-30))))
        out[k] = tuple(sig)
    return out


@dataclass(frozen=True)
class AmplitudeClasses:
    """The training cells' classes of secondary amplitude and each class's sigmas [m/s].

    edges : (CLASSES - 1,) inner class edges in sigma_s [m/s]
    sigma : (n_class, 2) each class's (sigma_s, sigma_p)
    reference : (sigma_s, sigma_p) over all training cells: the amplitude the fitted car's
        damping stands for
    cells : {cell: (sigma_s, sigma_p)} of every cell (training and held out)
    """

    edges: np.ndarray
    sigma: np.ndarray
    reference: tuple[float, float]
    cells: Mapping

    def of(self, cell) -> int:
        """The class of ``cell`` (a held-out cell: the class its sigma_s falls in)."""
        return int(np.searchsorted(self.edges, self.cells[cell][0]))

    def added(self, values: Mapping, sigma) -> tuple[float, float]:
        """(dc_s, dc_p) [N s/m]: the damping the friction of ``values`` adds at ``sigma``."""
        return tuple(GAUSSIAN * float(values.get(n, 0.0)) / s for n, s in zip(FRICTION, sigma))

    def relative(self, values: Mapping, cell) -> tuple[float, float]:
        """(dc_s, dc_p) of ``cell``'s class against the reference amplitude's [N s/m]."""
        a = self.added(values, self.sigma[self.of(cell)])
        b = self.added(values, self.reference)
        return a[0] - b[0], a[1] - b[1]


def _mean_square(cells: Mapping, seconds: Mapping, keys) -> tuple[float, float]:
    sec = np.array([seconds[k] for k in keys])
    s = np.array([cells[k] for k in keys])
    return tuple(float(v) for v in np.sqrt((s ** 2 * sec[:, None]).sum(axis=0) / sec.sum()))


def amplitude_classes(p: CarParameters, stats: Statistics, train_keys, heldout_keys=()) -> AmplitudeClasses:
    """The classes of the training cells by the secondary amplitude car ``p`` predicts."""
    train = stats.ordered(train_keys)
    cells = suspension_rms(p, CarExtras(), stats, set(train) | set(heldout_keys))
    n = min(CLASSES, len(train))
    order = sorted(train, key=lambda k: cells[k][0])
    split = np.array_split(np.arange(len(order)), n)
    edges = np.array([0.5 * (cells[order[a[-1]]][0] + cells[order[b[0]]][0]) for a, b in zip(split, split[1:])])
    sigma = np.array([_mean_square(cells, stats.seconds, [order[i] for i in idx]) for idx in split])
    return AmplitudeClasses(edges, sigma, _mean_square(cells, stats.seconds, train), cells)
