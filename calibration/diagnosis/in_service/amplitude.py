"""Amplitude-dependent suspension: dry friction in the secondary and primary suspension,
linearised at the amplitude of each (run, speed) cell.

A friction force F sign(v) on a relative velocity v that is Gaussian with standard
deviation sigma is, in the mean-square sense, a viscous damper of

    c_eq = sqrt(2 / pi) F / sigma

(statistical linearisation: c_eq = E[F sign(v) v] / E[v^2]). Friction thus damps a quiet
ride more than a rough one: a cell's damping depends on how hard the track drives it.
sigma of each suspension element comes from the baseline car driven by the cell's
measured rail input (no response data), so held-out cells are placed without fitting.

The training cells are sorted into :data:`CLASSES` classes of secondary amplitude (equal
counts); each class is one car, its sigma the class's rms over its cells' seconds, so a
fit costs :data:`CLASSES` frequency responses per evaluation, not one per cell. A held-out
cell takes the class its sigma falls in, and that class's sigma.

The baseline's sigma is a first guess: friction damps a quiet cell more, so the truth's
quiet cells move less than the baseline (one damping for all) predicts, and the amplitude
spread it sees is too narrow; a friction fitted on it comes out too large (1.3-1.7x on the
first bench). :func:`relinearised` recomputes each class's sigma with the damping the
fitted friction gives it at its sigma (iterated to a fixed point), the usual
self-consistency of statistical linearisation, and the fit is repeated (:data:`RELINEARISE`
times at most), each time moving the sigmas halfway (in log) to those the last fit gives:
a full step overshoots (a friction too large damps the quiet cells too much, and the next
fit's is too small). That costs three times a plain fit, so the hypotheses are judged on
plain fits and only the vehicle's final model is made consistent (:func:`.selection.select`).
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
#: refits at most with the classes' sigmas made consistent with the fitted friction, and
#: the relative change of the sigmas under which they count as consistent
RELINEARISE = 10
CONSISTENT = 1e-3
_SECONDARY = ("secondary1", "secondary2")
_PRIMARY = ("primary1", "primary2", "primary3", "primary4")


def suspension_rms(p: CarParameters, extras: CarExtras, stats: Statistics, keys) -> dict:
    """{cell: (sigma_s, sigma_p)}: root-mean-square relative velocity [m/s] across the
    secondary and the primary suspension (over their elements) predicted by car ``p`` from
    each cell's rail input, in the statistics' bands."""
    T = _velocity_transfer(p, extras, stats.centres)
    return {k: _rms(T, stats, k) for k in stats.ordered(keys)}


def _velocity_transfer(p: CarParameters, extras: CarExtras, f: np.ndarray) -> dict:
    """{element group: (n_f, n_elements, 4)} relative velocity per unit rail acceleration."""
    asm = build_car(p, extras=extras)
    w = 2 * np.pi * f
    Hq = np.linalg.solve(*dynamic_stiffness(asm.K, asm.M, asm.C, asm.B_k, asm.B_c, w))  # per unit rail level
    T = {}
    for group in (_SECONDARY, _PRIMARY):
        rows = [elongation_rows(asm, n) for n in group]
        g = np.stack([r[0] for r in rows])
        h = np.stack([r[1] for r in rows])
        # velocity per unit rail acceleration: i w (g Hq + h) x (-1 / w^2)
        T[group] = -(1j / w)[:, None, None] * (g @ Hq + h[None])
    return T


def _rms(T: dict, stats: Statistics, k) -> tuple[float, float]:
    Suu = stats.S[k][:, :4, :4]
    sec = max(stats.seconds[k], 1e-300)
    sig = []
    for group in (_SECONDARY, _PRIMARY):
        ms = np.einsum("kij,kjl,kil->i", T[group], Suu, T[group].conj()).real / sec
        sig.append(float(np.sqrt(max(ms.mean(), 1e-30))))
    return sig[0], sig[1]


def friction_damping(values: Mapping, sigma) -> tuple[float, float]:
    """(dc_s, dc_p) [N s/m]: the viscous damping equivalent to the friction forces of
    ``values`` (:data:`FRICTION`) at rms relative velocities ``sigma`` = (sigma_s, sigma_p)."""
    dc_s, dc_p = (GAUSSIAN * float(values.get(n, 0.0)) / s for n, s in zip(FRICTION, sigma))
    return dc_s, dc_p


@dataclass(frozen=True)
class AmplitudeClasses:
    """The training cells' classes of secondary amplitude and each class's sigmas [m/s].

    member : {cell: class} of every cell (training and held out: a held-out cell's is the
        class its first sigma_s falls in)
    sigma : (n_class, 2) each class's (sigma_s, sigma_p)
    reference : (sigma_s, sigma_p) over all training cells: the amplitude the fitted car's
        damping stands for
    cells : {cell: (sigma_s, sigma_p)} of every cell
    """

    member: Mapping
    sigma: np.ndarray
    reference: tuple[float, float]
    cells: Mapping

    def of(self, cell) -> int:
        """The class of ``cell``."""
        return self.member[cell]

    def added(self, values: Mapping, sigma) -> tuple[float, float]:
        """(dc_s, dc_p) [N s/m]: the damping the friction of ``values`` adds at ``sigma``."""
        return friction_damping(values, sigma)

    def relative(self, values: Mapping, cell) -> tuple[float, float]:
        """(dc_s, dc_p) of ``cell``'s class against the reference amplitude's [N s/m]."""
        a = self.added(values, self.sigma[self.of(cell)])
        b = self.added(values, self.reference)
        return a[0] - b[0], a[1] - b[1]


def _seconds_rms(cells: Mapping, seconds: Mapping, keys) -> tuple[float, float]:
    """The rms over ``keys`` of their cells' sigmas, weighted by their seconds."""
    sec = np.array([seconds[k] for k in keys])
    s = np.array([cells[k] for k in keys])
    return tuple(float(v) for v in np.sqrt((s ** 2 * sec[:, None]).sum(axis=0) / sec.sum()))


def _classes(member: Mapping, cells: Mapping, stats: Statistics, train) -> AmplitudeClasses:
    n = max(member[k] for k in train) + 1
    sigma = np.array([_seconds_rms(cells, stats.seconds, [k for k in train if member[k] == c]) for c in range(n)])
    return AmplitudeClasses(dict(member), sigma, _seconds_rms(cells, stats.seconds, train), dict(cells))


def amplitude_classes(p: CarParameters, stats: Statistics, train_keys, heldout_keys=()) -> AmplitudeClasses:
    """The classes of the training cells by the secondary amplitude car ``p`` predicts."""
    train = stats.ordered(train_keys)
    cells = suspension_rms(p, CarExtras(), stats, set(train) | set(heldout_keys))
    n = min(CLASSES, len(train))
    order = sorted(train, key=lambda k: cells[k][0])
    split = np.array_split(np.arange(len(order)), n)
    edges = np.array([0.5 * (cells[order[a[-1]]][0] + cells[order[b[0]]][0]) for a, b in zip(split, split[1:])])
    member = {k: int(np.searchsorted(edges, s[0])) for k, s in cells.items()}
    member.update({order[i]: c for c, idx in enumerate(split) for i in idx})
    return _classes(member, cells, stats, train)


def viscous(p: CarParameters, values: Mapping) -> CarParameters:
    """A fitted car's viscous damping: its c_s and c_p less what the friction of ``values``
    adds at their reference amplitude (``amplitude_reference_m_per_s``), which a fit with
    friction folds into them."""
    ref = values.get("amplitude_reference_m_per_s")
    if ref is None:
        return p
    dc_s, dc_p = friction_damping(values, (ref["secondary"], ref["primary"]))
    return p.replace(c_s=p.c_s - dc_s, c_p=p.c_p - dc_p)


def halfway(a: AmplitudeClasses, b: AmplitudeClasses, stats: Statistics, train_keys) -> AmplitudeClasses:
    """Classes (``a``'s members) whose cells' sigmas are the geometric means of ``a``'s and ``b``'s."""
    cells = {k: tuple(float(np.sqrt(x * y)) for x, y in zip(a.cells[k], b.cells[k])) for k in a.cells}
    return _classes(a.member, cells, stats, stats.ordered(train_keys))


def relinearised(classes: AmplitudeClasses, p: CarParameters, values: Mapping, stats: Statistics, train_keys,
                 iterations: int = 50, rtol: float = 1e-6, extras: CarExtras = CarExtras()) -> AmplitudeClasses:
    """The classes (same members) with each class's sigma made consistent with the damping
    the friction of ``values`` adds at it, on car ``p`` (its viscous damping) with
    ``extras``: each class's car is p with that damping, its cells' sigmas are that car's,
    iterated to a fixed point."""
    train = stats.ordered(train_keys)
    for _ in range(iterations):
        cells = {}
        for c, sig in enumerate(classes.sigma):
            dc_s, dc_p = classes.added(values, sig)
            T = _velocity_transfer(p.replace(c_s=p.c_s + dc_s, c_p=p.c_p + dc_p), extras, stats.centres)
            cells.update({k: _rms(T, stats, k) for k, m in classes.member.items() if m == c})
        new = _classes(classes.member, cells, stats, train)
        done = np.allclose(new.sigma, classes.sigma, rtol=rtol, atol=0.0)
        classes = new
        if done:
            break
    return classes
