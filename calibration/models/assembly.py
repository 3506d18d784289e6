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

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class Body:
    """A rigid body moving vertically (and pitching when ``inertia`` is given).

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

    @property
    def dof_names(self) -> tuple[str, ...]:
        return (f"{self.name}_z",) if self.inertia is None else (f"{self.name}_z", f"{self.name}_pitch")


@dataclass(frozen=True)
class Attachment:
    """A point: on a body (at vehicle-frame ``x``) or on a prescribed input (``input``)."""

    body: str | None = None
    x: float = 0.0
    input: str | None = None

    def __post_init__(self) -> None:
        if (self.body is None) == (self.input is None):
            raise ValueError("an attachment is on exactly one of a body or an input")


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
        h[list(inputs).index(att.input)] = 1.0
        return g, h
    body = next((b for b in bodies if b.name == att.body), None)
    if body is None:
        raise KeyError(f"no body {att.body!r}")
    g[dofs.index(f"{body.name}_z")] = 1.0
    if body.inertia is not None:
        g[dofs.index(f"{body.name}_pitch")] = -(att.x - body.x)
    elif att.x != body.x:
        raise ValueError(f"point mass {body.name} cannot carry an attachment off its centre")
    return g, h


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
    B_k = np.zeros((n, m))
    B_c = np.zeros((n, m))
    for e in elements:
        g_top, h_top = _point_rows(bodies, dofs, e.top, inputs)
        g_bot, h_bot = _point_rows(bodies, dofs, e.bottom, inputs)
        g = g_top - g_bot  # elongation = g @ q + h @ u (compression positive down on top)
        h = h_top - h_bot
        K += e.stiffness * np.outer(g, g)
        C += e.damping * np.outer(g, g)
        B_k -= e.stiffness * np.outer(g, h)
        B_c -= e.damping * np.outer(g, h)
    return Assembly(dofs, tuple(inputs), M, C, K, B_k, B_c, tuple(bodies), tuple(elements))
