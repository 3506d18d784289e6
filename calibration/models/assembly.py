"""Planar (vertical + pitch) multibody assembly from rigid bodies and spring-dampers.

A model is a list of :class:`Body` and :class:`SpringDamper`; :func:`assemble` turns
it into the matrices of

    M q'' + C q' + K q = B_k u + B_c u'

where ``q`` holds each body's vertical displacement (and pitch, for bodies with
inertia) and ``u`` the prescribed vertical motions (e.g. rail level under each
wheelset). Extensions add bodies and elements; nobody types a matrix.

Sign conventions (shared/spec/campaign-format.md): x forward, z up, a positive pitch
moves the front (x > 0) down, so a point at distance ``x`` ahead of a body's centre
moves ``z - x * theta``.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class ElasticMode:
    """A free-free elastic mode of a body, one more generalised coordinate ``q``.

    A point of the body at vehicle-frame ``x`` moves ``shape(x - body.x) * q`` on top of
    the rigid motion. ``modal_mass`` [kg] is the mode's generalised mass for that shape
    scaling, ``frequency`` [Hz] its natural frequency on free supports, ``damping_ratio``
    its modal damping. The shape must be orthogonal to the rigid motions (a free-free mode
    is), so the mass matrix stays diagonal.
    """

    name: str
    shape: Callable[[float], float]
    modal_mass: float
    frequency: float
    damping_ratio: float = 0.0


#: Nodes of a uniform free-free beam's first bending, as a fraction of its half-length from
#: the centre (the roots of the shape at 0.2242 and 0.7758 of the length).
UNIFORM_BEAM_NODE = 0.5516849545952847


def beam_bending_shape(length: float, node: float | None = None) -> Callable[[float], float]:
    """First free-free bending shape of a uniform beam of ``length`` [m], centred on 0 and
    scaled to 1 at its ends (beta L = 4.7300). Its generalised mass for that scaling is a
    quarter of the beam's mass; it is orthogonal to bounce and pitch.

    ``node``: the nodes at +-node x length / 2 instead (a fraction of the half-length). A
    real carbody's mass is not uniform (cab ends, underfloor equipment, bogie masses), and
    its nodes move; the uniform shape stretched along x so that its nodes sit there, again
    1 at the ends, is a one-parameter family holding the uniform beam at ``node`` =
    :data:`UNIFORM_BEAM_NODE`."""
    bl = 4.730040744862704
    s = (np.cosh(bl) - np.cos(bl)) / (np.sinh(bl) - np.sin(bl))
    stretch = 1.0 if node is None else UNIFORM_BEAM_NODE / node

    def raw(u):
        b = bl * (stretch * u / length + 0.5)
        return np.cosh(b) + np.cos(b) - s * (np.sinh(b) + np.sin(b))

    end = raw(length / 2)
    return lambda x: float(raw(x) / end)


@dataclass(frozen=True)
class Body:
    """A rigid body moving vertically (and pitching when ``inertia`` is given), optionally
    with free-free elastic modes (``modes``).

    Attributes
    ----------
    name : str
    mass : float  [kg]
    x : float  [m] longitudinal position of the centre of mass in the vehicle frame.
    inertia : float or None  [kg m^2] pitch inertia about the centre of mass; None for a
        point mass (one vertical DOF only).
    """

    name: str
    mass: float
    x: float
    inertia: float | None = None
    modes: tuple[ElasticMode, ...] = ()

    @property
    def dof_names(self) -> tuple[str, ...]:
        rigid = (f"{self.name}_z",) if self.inertia is None else (f"{self.name}_z", f"{self.name}_pitch")
        return rigid + tuple(f"{self.name}_{m.name}" for m in self.modes)


@dataclass(frozen=True)
class Attachment:
    """A point: on a body (at vehicle-frame ``x``), on a prescribed input (``input``), on
    both (the body's point plus ``gain`` x the input: a coordinate that is not the point's
    own level, such as a wheelset's on a flexible track), or ``fixed`` (the ground)."""

    body: str | None = None
    x: float = 0.0
    input: str | None = None
    fixed: bool = False
    gain: float = 1.0  # of the input

    def __post_init__(self) -> None:
        if self.fixed == (self.body is not None or self.input is not None):
            raise ValueError("an attachment is fixed, or on a body, an input or both")


@dataclass(frozen=True)
class SpringDamper:
    """A linear vertical spring and viscous damper between two attachments (top, bottom)."""

    name: str
    top: Attachment
    bottom: Attachment
    stiffness: float  # [N/m]
    damping: float = 0.0  # [N s/m]


@dataclass(frozen=True)
class Assembly:
    """Assembled second-order system; ``dofs`` and ``inputs`` name rows and columns."""

    dofs: tuple[str, ...]
    inputs: tuple[str, ...]
    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    B_k: np.ndarray  # stiffness input matrix (n_dof x n_input)
    B_c: np.ndarray  # damping input matrix
    bodies: tuple[Body, ...] = field(repr=False, default=())
    elements: tuple[SpringDamper, ...] = field(repr=False, default=())

    def dof(self, name: str) -> int:
        try:
            return self.dofs.index(name)
        except ValueError:
            raise KeyError(f"no degree of freedom {name!r}; have {', '.join(self.dofs)}") from None

    def point_row(self, body: str, x: float) -> np.ndarray:
        """Row vector g with g @ q = vertical displacement of body point at vehicle-frame x."""
        return _point_rows(self.bodies, self.dofs, Attachment(body=body, x=x))[0]


def _point_rows(bodies, dofs, att: Attachment, inputs=()):
    g = np.zeros(len(dofs))
    h = np.zeros(len(inputs))
    if att.input is not None:
        h[list(inputs).index(att.input)] = att.gain
    if att.body is None:
        return g, h
    body = next((b for b in bodies if b.name == att.body), None)
    if body is None:
        raise KeyError(f"no body {att.body!r}")
    g[dofs.index(f"{body.name}_z")] = 1.0
    if body.inertia is not None:
        g[dofs.index(f"{body.name}_pitch")] = -(att.x - body.x)
    elif att.x != body.x:
        raise ValueError(f"point mass {body.name} cannot carry an attachment off its centre")
    for mode in body.modes:
        g[dofs.index(f"{body.name}_{mode.name}")] = mode.shape(att.x - body.x)
    return g, h


def elongation_rows(asm: Assembly, element: str) -> tuple[np.ndarray, np.ndarray]:
    """(g, h): the elongation of ``asm``'s spring-damper named ``element`` is g @ q + h @ u
    (the signs of :func:`assemble`)."""
    e = next((e for e in asm.elements if e.name == element), None)
    if e is None:
        raise KeyError(f"no spring-damper {element!r}; have {', '.join(x.name for x in asm.elements)}")
    return _elongation(asm.bodies, asm.dofs, e, asm.inputs)


def _elongation(bodies, dofs, e: SpringDamper, inputs) -> tuple[np.ndarray, np.ndarray]:
    g_top, h_top = _point_rows(bodies, dofs, e.top, inputs)
    g_bot, h_bot = _point_rows(bodies, dofs, e.bottom, inputs)
    return g_top - g_bot, h_top - h_bot


def assemble(bodies: list[Body], elements: list[SpringDamper], inputs: list[str]) -> Assembly:
    """Assemble M, C, K, B_k, B_c from bodies and spring-dampers."""
    names = [b.name for b in bodies]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate body names in {names}")
    dofs = tuple(d for b in bodies for d in b.dof_names)
    n, m = len(dofs), len(inputs)
    M = np.zeros((n, n))
    for b in bodies:
        M[dofs.index(f"{b.name}_z"), dofs.index(f"{b.name}_z")] = b.mass
        if b.inertia is not None:
            i = dofs.index(f"{b.name}_pitch")
            M[i, i] = b.inertia
    K = np.zeros((n, n))
    C = np.zeros((n, n))
    for b in bodies:
        for mode in b.modes:
            i = dofs.index(f"{b.name}_{mode.name}")
            w = 2 * np.pi * mode.frequency
            M[i, i] = mode.modal_mass
            K[i, i] = mode.modal_mass * w * w
            C[i, i] = 2 * mode.damping_ratio * mode.modal_mass * w
    g = np.zeros((len(elements), n))  # element elongations = g @ q + h @ u (compression positive down on top)
    h = np.zeros((len(elements), m))
    for r, e in enumerate(elements):
        g[r], h[r] = _elongation(bodies, dofs, e, inputs)
    gk = g.T * np.array([e.stiffness for e in elements], float)
    gc = g.T * np.array([e.damping for e in elements], float)
    K += gk @ g
    C += gc @ g
    return Assembly(dofs, tuple(inputs), M, C, K, -gk @ h, -gc @ h, tuple(bodies), tuple(elements))
