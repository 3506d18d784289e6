"""The 2D car of :mod:`calibration.models.car2d`, built again in exudyn from its own items.

An independent reference for railcal's car model: it is built from the calibrated
:class:`~calibration.models.parameters.CarParameters` only (never from the assembled
matrices of :mod:`calibration.models.assembly`), solved by exudyn's own eigen solver and
time integrator, and compared with railcal's model by ``tests/test_reference_car2d.py``
and ``scripts/crosscheck_car.py``.

The model, in exudyn's x-y plane (x forward, y = railcal's z up):

* carbody, bogie 1 (x = +L_v) and bogie 2 (x = -L_v): ``ObjectRigidBody2D`` on
  ``NodeRigidBody2D`` (x, y, phi); the longitudinal coordinate x of each is held at zero by a
  ``CoordinateConstraint`` to ground, so only bounce and pitch remain;
* wheelsets 1-4 (x = L_v + L_b, L_v - L_b, -L_v + L_b, -L_v - L_b): vertical ``ObjectMass1D``
  on a ``Node1D``, whose coordinate is prescribed to the rail level by a
  ``CoordinateConstraint`` with a time-dependent offset; the wheelset mass m_w carries no load
  of the suspension, as in railcal's ``wheelsets="rail"`` model;
* primary (k_p, c_p per wheelset) and secondary (k_s, c_s per bogie) suspension: vertical
  ``CartesianSpringDamper`` between ``MarkerBodyPosition`` markers at the attachment points
  (stiffness and damping only along y, so a pitching body's small horizontal point motion
  meets no spring).

railcal's extended car (:class:`~calibration.models.car2d.CarExtras`, ``extras=``) is built
the same way, each addition from its physical quantities (a shape function and railcal's
vehicle geometry are the only things shared):

* ``cog_offset``: the carbody's node sits at its centre of mass x_c, J_v about it; when hung
  bodies are part of m_v (``hung_in_m_v``) the rigid rest's mass, centre and inertia are
  re-derived here (:func:`carbody_rest`) from the mass moments of the whole less theirs;
* ``bending_hz``: one elastic coordinate q on a ``Node1D``; an ``ObjectGenericODE2`` over
  [carbody node, q node] holds its modal mass, stiffness and damping and gives one
  ``MarkerObjectODE2Coordinates`` over (x, y, phi, q). Every carbody attachment point is then
  a massless ``Node1D`` (a zero-mass ``ObjectMass1D``, so the springs attach as elsewhere)
  tied by a linear ``CoordinateVectorConstraint``: point = y + (x - x_c) phi + shape(x - x_c) q,
  shape = :func:`~calibration.models.assembly.beam_bending_shape`;
* ``reservoir_ratio``: per air spring a ``Node1D`` of ``node_mass`` at the bogie's x, on the
  reservoir spring k_r to the carbody and the orifice damper c_o to the bogie;
* ``track_stiffness``: under each wheelset a ``track_mass`` point on the track's
  spring-damper to ground; the rail-level constraint holds the wheelset at that point's
  level plus the rail level (the irregularity at the wheel-rail contact);
* ``bodies`` / ``elements``: point masses (``ObjectMass1D``) and their spring-dampers, e.g.
  equipment hung under the carbody.

Gravity is left out: coordinates are deviations from static equilibrium, as railcal's outputs
are (an acceleration is the same either way). exudyn's phi turns counter-clockwise, which
lifts the front; railcal's pitch lowers it, so ``pitch = -phi`` and ``pitch_rate = -omega_z``.

The rail input (:mod:`reference_models.rail`) drives the wheelsets' rail-level constraints
through symbolic user functions, so no Python runs during time integration.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import exudyn as exu
import numpy as np
import scipy.optimize
from exudyn.itemInterface import (CartesianSpringDamper, CoordinateConstraint, CoordinateVectorConstraint,
                                  MarkerBodyPosition, MarkerNodeCoordinate, MarkerNodeCoordinates,
                                  MarkerObjectODE2Coordinates, Node1D, NodePointGround, NodeRigidBody2D,
                                  ObjectGenericODE2, ObjectGround, ObjectMass1D, ObjectRigidBody2D, SensorNode)

from calibration.models.assembly import Body, SpringDamper, beam_bending_shape
from calibration.models.car2d import (CarExtras, bogie_positions, build_car, damped_modes, undamped_modes,
                                      wheelset_positions)
from calibration.models.parameters import CarParameters

from .rail import RailInput, drive_rail_constraints

BODIES = ("carbody", "bogie1", "bogie2")
OUTPUTS = tuple(f"{b}_{q}" for b in BODIES for q in ("acc_z", "pitch_rate"))  # the car FMU's names
_VERTICAL = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # Mass1D's axis along y


# ---------------------------------------------------------------------------- the model
@dataclass(frozen=True, eq=False)
class CarHandles:
    """Indices of the exudyn car's items.

    ``nodes`` and ``bodies``: carbody, bogie1, bogie2, wheelset1..4, and with extras
    reservoir1..2, track1..4 (the track masses under the wheelsets on a flexible track), the
    extra bodies and ``carbody_bending`` (the node of q; its body is the
    ``ObjectGenericODE2``); ``springs``: every spring-damper by railcal's element name
    (primary1..4, secondary1..2, track1..4, reservoir1_spring, reservoir1_orifice, ..., the
    extra elements); ``rail_constraints``: one per wheelset (to ground, or to its track mass
    when the track is flexible);
    ``longitudinal_constraints``: one per rigid body. ``coordinates`` maps railcal's DOF names
    (carbody_z, carbody_pitch, carbody_bending, reservoir1_z, ...) to (ODE2 index, sign) with
    railcal DOF = sign * exudyn coordinate. ``carbody_points`` (bending only) maps the
    vehicle-frame x [m] of each carbody attachment point to its (node, constraint);
    ``bending_shape`` is the carbody's shape over x - x_c [m] (None: rigid). ``keep_alive``
    holds the system container and the symbolic user functions, which must outlive the system.
    """

    p: CarParameters
    rail: RailInput | None
    nodes: dict
    bodies: dict
    springs: dict
    rail_constraints: tuple
    longitudinal_constraints: tuple
    coordinates: dict
    keep_alive: tuple = field(repr=False, default=())
    extras: CarExtras = CarExtras()
    carbody_points: dict = field(default_factory=dict)
    bending_shape: Callable[[float], float] | None = field(repr=False, default=None)


def carbody_rest(p: CarParameters, ex: CarExtras) -> tuple[float, float, float]:
    """(mass [kg], centre of mass x [m], pitch inertia [kg m^2] about it) of the rigid carbody.

    The whole carbody is m_v at ``cog_offset`` with J_v about it. When the hung bodies are
    part of it (``hung_in_m_v``), their mass moments about x = 0 (zeroth, first, second) are
    taken off the whole's; the rest's centre and inertia follow from what is left.
    """
    if not (ex.hung_in_m_v and ex.bodies):
        return p.m_v, ex.cog_offset, p.J_v
    moments = np.array([p.m_v, p.m_v * ex.cog_offset, p.J_v + p.m_v * ex.cog_offset ** 2])
    for b in ex.bodies:
        moments -= b.mass * np.array([1.0, b.x, b.x ** 2])
    mass, first, second = moments
    inertia = second - first ** 2 / mass if mass > 0 else 0.0  # parallel axes: about x = 0 -> about the centre
    if not (mass > 0 and inertia > 0):
        raise ValueError(f"the hung bodies (part of m_v = {p.m_v:.0f} kg, J_v = {p.J_v:.4g} kg m^2) leave the rigid "
                         f"carbody {mass:.0f} kg and {inertia:.4g} kg m^2; both must stay positive")
    return float(mass), float(first / mass), float(inertia)


def _check_buildable(ex: CarExtras) -> None:
    """ValueError for additions the exudyn car does not build (railcal's assembly would)."""
    for b in ex.bodies:
        if b.inertia is not None or b.modes:
            raise ValueError(f"extra body {b.name!r}: the exudyn car builds extra bodies as point masses only "
                             "(no pitch inertia, no elastic modes)")
    for e in ex.elements:
        for end in (e.top, e.bottom):
            if end.input is not None:
                raise ValueError(f"extra element {e.name!r} ends on the input {end.input!r}: the exudyn car joins "
                                 "extra elements to bodies only")


def _rest_lines(p: CarParameters, z_rail: np.ndarray, x_c: float) -> dict:
    """Each rigid body's (level [m] at its centre, railcal pitch [rad], centre x [m]) at rest on
    rail levels ``z_rail`` under wheelsets 1-4: without gravity, static equilibrium on the
    rails is kinematic, every spring relaxed."""
    z_bogie = [0.5 * (z_rail[2 * i] + z_rail[2 * i + 1]) for i in range(2)]
    pitch_bogie = [(z_rail[2 * i + 1] - z_rail[2 * i]) / (2.0 * p.L_b) for i in range(2)]
    pitch_carbody = (z_bogie[1] - z_bogie[0]) / (2.0 * p.L_v)
    z_carbody = 0.5 * (z_bogie[0] + z_bogie[1]) - x_c * pitch_carbody
    xb = bogie_positions(p)
    return {"carbody": (z_carbody, pitch_carbody, x_c),
            **{f"bogie{i + 1}": (z_bogie[i], pitch_bogie[i], xb[i]) for i in range(2)}}


class _CarBuilder:
    """Adds the car's items to an exudyn system: bodies at rest on the rail at t = 0, their
    attachment points, vertical spring-dampers. ``rest`` holds each body's
    (level [m] at x0, railcal pitch [rad], x0 [m]) at t = 0."""

    def __init__(self, mbs: exu.MainSystem, rest: dict):
        self.mbs, self.rest = mbs, dict(rest)
        n_ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
        self.m_ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_ground, coordinate=0))
        self.nodes, self.bodies, self.springs = {}, {}, {}
        self.rigid, self.point_dofs, self.longitudinal = [], [], []
        self.elastic = None  # with bending: (marker on [carbody, q] coordinates, shape over x - x_c)
        self.carbody_points = {}  # with bending: x -> (node, constraint, marker)
        self.ground = None  # the ground object, made when a spring is fixed to it

    def level(self, body: str, x: float) -> float:
        """Rest level [m] at t = 0 of the point of ``body`` at vehicle-frame ``x`` [m]."""
        z, pitch, x0 = self.rest[body]
        return z - (x - x0) * pitch

    def rigid_body(self, name: str, mass: float, inertia: float) -> None:
        """A body in bounce and pitch at its rest centre; its longitudinal coordinate held at zero."""
        z, pitch, x0 = self.rest[name]
        mbs = self.mbs
        self.nodes[name] = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[x0, 0.0, 0.0],
                                                       initialCoordinates=[0.0, z, -pitch]))
        self.bodies[name] = mbs.AddObject(ObjectRigidBody2D(nodeNumber=self.nodes[name], mass=mass, inertia=inertia))
        m_x = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=self.nodes[name], coordinate=0))
        self.longitudinal.append(mbs.AddObject(CoordinateConstraint(markerNumbers=[self.m_ground, m_x])))
        self.rigid.append(name)

    def _point(self, mass: float, x: float, z: float, v: float = 0.0) -> tuple[int, int]:
        """(node, body) of a vertical point mass [kg] at ``x`` [m], starting at level ``z`` [m], rate ``v`` [m/s]."""
        node = self.mbs.AddNode(Node1D(referenceCoordinates=[0.0], initialCoordinates=[z], initialVelocities=[v]))
        body = self.mbs.AddObject(ObjectMass1D(nodeNumber=node, mass=mass, referencePosition=[x, 0.0, 0.0],
                                               referenceRotation=_VERTICAL))
        return node, body

    def point_mass(self, name: str, mass: float, x: float, z: float, v: float = 0.0, *, dof: bool = True) -> None:
        """The point mass ``name`` [kg] at ``x`` [m], starting at level ``z`` [m] and rate ``v`` [m/s];
        ``dof``: one of railcal's DOFs (not a point whose level the rail prescribes)."""
        self.nodes[name], self.bodies[name] = self._point(mass, x, z, v)
        self.rest[name] = (z, 0.0, x)
        if dof:
            self.point_dofs.append(name)

    def hold_to_rail(self, name: str, on: str | None = None) -> int:
        """A rail-level constraint on the point mass ``name``: its level is the rail's, above
        ground or above the point mass ``on`` (offset functions set later)."""
        m = self.mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=self.nodes[name], coordinate=0))
        below = self.m_ground if on is None else \
            self.mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=self.nodes[on], coordinate=0))
        return self.mbs.AddObject(CoordinateConstraint(markerNumbers=[below, m]))

    def elastic_carbody(self, shape: Callable[[float], float], modal_mass: float, frequency: float,
                        damping_ratio: float) -> None:
        """The carbody's bending coordinate q: an ``ObjectGenericODE2`` over [carbody node, q node]
        holds the mode's modal mass [kg], stiffness m w^2 and damping 2 zeta m w (the rigid part's
        block is zero: ``ObjectRigidBody2D`` carries it) and gives one marker over (x, y, phi, q)."""
        mbs = self.mbs
        self.nodes["carbody_bending"] = mbs.AddNode(Node1D(referenceCoordinates=[0.0]))
        w = 2.0 * np.pi * frequency
        block = [np.zeros((4, 4)) for _ in range(3)]
        for matrix, value in zip(block, (modal_mass, modal_mass * w * w, 2.0 * damping_ratio * modal_mass * w)):
            matrix[3, 3] = value
        self.bodies["carbody_bending"] = mbs.AddObject(ObjectGenericODE2(
            nodeNumbers=[self.nodes["carbody"], self.nodes["carbody_bending"]], massMatrix=block[0],
            stiffnessMatrix=block[1], dampingMatrix=block[2]))
        self.elastic = (mbs.AddMarker(MarkerObjectODE2Coordinates(objectNumber=self.bodies["carbody_bending"])), shape)

    def _carbody_point(self, x: float) -> int:
        """Marker of the bending carbody's point at ``x`` [m]: a massless point coordinate tied to
        y_c + (x - x_c) phi_c + shape(x - x_c) q (exudyn's phi lifts the front: railcal's -pitch)."""
        if x not in self.carbody_points:
            mbs = self.mbs
            marker, shape = self.elastic
            x_c = self.rest["carbody"][2]
            node, body = self._point(0.0, x, self.level("carbody", x))  # massless: the constraint moves it
            m_point = mbs.AddMarker(MarkerNodeCoordinates(nodeNumber=node))
            # the marker's (x, y, phi, q) include the carbody node's reference x_c, which weighs 0 here
            con = mbs.AddObject(CoordinateVectorConstraint(
                markerNumbers=[marker, m_point], scalingMarker0=[[0.0, 1.0, x - x_c, shape(x - x_c)]],
                scalingMarker1=[[1.0]], offset=[0.0]))
            m_body = mbs.AddMarker(MarkerBodyPosition(bodyNumber=body, localPosition=[0.0, 0.0, 0.0]))
            self.carbody_points[x] = (node, con, m_body)
        return self.carbody_points[x][2]

    def attach(self, body: str, x: float) -> int:
        """Position marker of ``body``'s point at vehicle-frame ``x`` [m] (``ground``: the fixed point there)."""
        if body == "ground":
            if self.ground is None:
                self.ground = self.mbs.AddObject(ObjectGround())
            return self.mbs.AddMarker(MarkerBodyPosition(bodyNumber=self.ground, localPosition=[x, 0.0, 0.0]))
        if body == "carbody" and self.elastic is not None:
            return self._carbody_point(x)
        if body not in self.bodies:
            raise ValueError(f"no body {body!r} to attach to; have {', '.join(self.bodies)}")
        x0 = self.rest[body][2]
        if body not in self.rigid and x != x0:
            raise ValueError(f"point mass {body} (x = {x0} m) cannot carry an attachment at x = {x} m")
        return self.mbs.AddMarker(MarkerBodyPosition(bodyNumber=self.bodies[body], localPosition=[x - x0, 0.0, 0.0]))

    def spring_damper(self, name: str, top: tuple[str, float], bottom: tuple[str, float], k: float,
                      c: float) -> None:
        """A vertical spring [N/m] and damper [N s/m] between body points (body, x): stiffness and
        damping along y only, so a pitching body's small horizontal point motion meets no spring."""
        m_top = self.attach(*top)
        m_bottom = self.attach(*bottom)
        self.springs[name] = self.mbs.AddObject(CartesianSpringDamper(
            markerNumbers=[m_bottom, m_top], stiffness=[0.0, k, 0.0], damping=[0.0, c, 0.0]))

    def coordinates(self) -> dict:
        """railcal's DOF name -> (ODE2 index, sign) of the assembled system."""
        out = {}
        for name in self.rigid:
            first = self.mbs.GetNodeODE2Index(self.nodes[name])
            out[f"{name}_z"] = (first + 1, 1.0)
            out[f"{name}_pitch"] = (first + 2, -1.0)
        if self.elastic is not None:
            out["carbody_bending"] = (self.mbs.GetNodeODE2Index(self.nodes["carbody_bending"]), 1.0)
        for name in self.point_dofs:
            out[f"{name}_z"] = (self.mbs.GetNodeODE2Index(self.nodes[name]), 1.0)
        return out


def _hung_level(car: _CarBuilder, body: Body, elements: tuple[SpringDamper, ...]) -> float:
    """Rest level [m] of an extra point mass: that of the body point its first element joins it
    to (every spring relaxed when each extra body hangs on one, as equipment on its mount)."""
    for e in elements:
        ends = (e.top, e.bottom)
        if body.name in (ends[0].body, ends[1].body):
            other = ends[1] if ends[0].body == body.name else ends[0]
            if other.body not in car.rest:
                raise ValueError(f"extra body {body.name!r} hangs from {other.body!r}, which is not built before it")
            return car.level(other.body, other.x)
    raise ValueError(f"extra body {body.name!r} is joined to the car by no element")


def build_car_exudyn(p: CarParameters, *, rail: RailInput | None = None,
                     extras: CarExtras | None = None) -> tuple[exu.MainSystem, CarHandles]:
    """Build and assemble the planar car in exudyn.

    Parameters
    ----------
    p : CarParameters  masses [kg], inertias [kg m^2], stiffnesses [N/m], dampings [N s/m],
        lengths [m].
    rail : RailInput, optional  the track to drive the wheelsets; None holds the rails at zero
        level (for eigen-analysis).
    extras : CarExtras, optional  railcal's additions to the seed's car (module docstring);
        None: the seed's car.

    Returns
    -------
    mbs : exudyn.MainSystem  assembled, initial state = static equilibrium on the rail at
        t = 0 (all springs relaxed, body velocities zero, rail-held points at the rail's level
        and rate; on a flexible track the centre of mass of each wheelset and its track mass
        at rest).
    handles : CarHandles
    """
    if not isinstance(p, CarParameters):
        raise TypeError(f"build_car_exudyn needs CarParameters, not {type(p).__name__}")
    ex = CarExtras() if extras is None else extras
    if not isinstance(ex, CarExtras):
        raise TypeError(f"build_car_exudyn needs CarExtras for extras, not {type(ex).__name__}")
    _check_buildable(ex)
    m_c, x_c, J_c = carbody_rest(p, ex)
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    xb, xw = bogie_positions(p), wheelset_positions(p)
    z0, dz0 = rail.under_wheelsets(p, np.zeros(1)) if rail is not None else (np.zeros((1, 4)), np.zeros((1, 4)))
    z0, dz0 = z0[0], dz0[0]

    car = _CarBuilder(mbs, _rest_lines(p, z0, x_c))
    car.rigid_body("carbody", m_c, J_c)
    for i in range(2):
        car.rigid_body(f"bogie{i + 1}", p.m_b, p.J_b)
    if ex.bending_hz is not None:
        car.elastic_carbody(beam_bending_shape(ex.carbody_length, ex.bending_node), ex.bending_mass_ratio * p.m_v,
                            ex.bending_hz, ex.bending_damping)
    for i in range(2):
        car.spring_damper(f"secondary{i + 1}", ("carbody", xb[i]), (f"bogie{i + 1}", xb[i]), p.k_s, p.c_s)

    rail_constraints = []
    for j in range(4):
        w, bogie = f"wheelset{j + 1}", f"bogie{1 + j // 2}"
        if ex.track_stiffness is None:  # the wheelset is held to the rail level; it loads nothing
            car.point_mass(w, p.m_w, xw[j], z0[j], dz0[j], dof=False)
            rail_constraints.append(car.hold_to_rail(w))
        else:  # the wheelset is held at the level of the track mass under it plus the rail level
            # railcal's coordinate is their centre of mass (neither is one of its DOFs), at rest at the
            # start as every body is: the track mass moves down as the wheelset follows the rail up
            track = f"track{j + 1}"
            a = p.m_w / (p.m_w + ex.track_mass)
            car.point_mass(track, ex.track_mass, xw[j], 0.0, -a * dz0[j], dof=False)
            car.spring_damper(track, (track, xw[j]), ("ground", xw[j]), ex.track_stiffness,
                              2.0 * ex.track_damping_ratio * np.sqrt(ex.track_stiffness * ex.track_mass))
            car.point_mass(w, p.m_w, xw[j], z0[j], (1.0 - a) * dz0[j], dof=False)
            rail_constraints.append(car.hold_to_rail(w, on=track))
        car.spring_damper(f"primary{j + 1}", (bogie, xw[j]), (w, xw[j]), p.k_p, p.c_p)

    if ex.reservoir_ratio > 0:  # air spring reservoir: k_r to the carbody, in series with the orifice c_o
        k_r = ex.reservoir_ratio * p.k_s
        c_o = k_r / (2.0 * np.pi * ex.reservoir_corner_hz)
        for i in range(2):
            node = f"reservoir{i + 1}"
            car.point_mass(node, ex.node_mass, xb[i], car.level("carbody", xb[i]))
            car.spring_damper(f"{node}_spring", ("carbody", xb[i]), (node, xb[i]), k_r, 0.0)
            car.spring_damper(f"{node}_orifice", (node, xb[i]), (f"bogie{i + 1}", xb[i]), 0.0, c_o)

    for b in ex.bodies:
        car.point_mass(b.name, b.mass, b.x, _hung_level(car, b, ex.elements))
    for e in ex.elements:
        car.spring_damper(e.name, (e.top.body, e.top.x), (e.bottom.body, e.bottom.x), e.stiffness, e.damping)

    mbs.Assemble()
    keep_alive = [sc]
    if rail is not None:
        keep_alive += drive_rail_constraints(mbs, rail, rail_constraints, xw)
    handles = CarHandles(p, rail, car.nodes, car.bodies, car.springs, tuple(rail_constraints),
                         tuple(car.longitudinal), car.coordinates(), tuple(keep_alive), extras=ex,
                         carbody_points={x: (node, con) for x, (node, con, _) in car.carbody_points.items()},
                         bending_shape=car.elastic[1] if car.elastic is not None else None)
    return mbs, handles


# ---------------------------------------------------------------------------- eigenvalues
def exudyn_eigenvalues(p: CarParameters, *, damped: bool, extras: CarExtras | None = None) -> np.ndarray:
    """Eigenvalues of the car (with ``extras``) on fixed rails from exudyn's
    ``ComputeODE2Eigenvalues`` (constraints eliminated by its null-space projection).

    Returns
    -------
    damped=False: undamped natural frequencies [Hz], ascending (one per DOF: 6 for the seed's car).
    damped=True: the eigenvalues [rad/s] of the damped system with non-negative imaginary part
        (one per conjugate pair, and each real root), ordered by modulus.
    """
    mbs, _ = build_car_exudyn(p, extras=extras)
    if not damped:
        w2, _ = mbs.ComputeODE2Eigenvalues(useAbsoluteValues=False)
        return np.sqrt(np.sort(np.asarray(w2, float))) / (2.0 * np.pi)
    lam, _ = mbs.ComputeODE2Eigenvalues(computeComplexEigenvalues=True, useAbsoluteValues=False)
    lam = np.asarray(lam, complex)
    scale = np.abs(lam).max()
    lam = lam[lam.imag >= -1e-12 * scale]
    return lam[np.argsort(np.abs(lam))]


def railcal_eigenvalues(p: CarParameters, *, damped: bool, extras: CarExtras | None = None) -> np.ndarray:
    """railcal's own eigenvalues of the rail-level car (with ``extras``), in
    :func:`exudyn_eigenvalues`' format, from :func:`calibration.models.car2d.undamped_modes` /
    ``damped_modes``."""
    asm = build_car(p, extras=extras)
    if not damped:
        return np.sort([m.frequency_hz for m in undamped_modes(asm)])
    lam = []
    for m in damped_modes(asm):
        wn = 2.0 * np.pi * m.frequency_hz
        wd = 2.0 * np.pi * m.damped_frequency_hz if m.damped_frequency_hz is not None else 0.0
        lam.append(complex(-m.damping_ratio * wn, wd))
    lam = np.array(lam)
    return lam[np.argsort(np.abs(lam))]


def eigen_errors(reference: np.ndarray, other: np.ndarray) -> np.ndarray:
    """|other - reference| / |reference| per reference eigenvalue, after pairing the two sets
    one-to-one by least total distance (so near-equal or repeated values cannot swap)."""
    reference, other = np.asarray(reference), np.asarray(other)
    if reference.shape != other.shape:
        raise ValueError(f"eigenvalue sets differ in size: {reference.shape} vs {other.shape}")
    rows, cols = scipy.optimize.linear_sum_assignment(np.abs(reference[:, None] - other[None, :]))
    err = np.empty(len(reference))
    err[rows] = np.abs(other[cols] - reference[rows]) / np.abs(reference[rows])
    return err


# ---------------------------------------------------------------------------- time response
@dataclass(frozen=True)
class IntegratorSettings:
    """exudyn generalized-alpha settings for :func:`simulate_car_exudyn`.

    step_size [s]: 2e-4 s keeps the NRMSE against railcal's exact response near 6e-5 over
    the test track (the error falls as step_size**2); spectral_radius: rho_inf of
    generalized-alpha (1 = trapezoidal rule, no numerical damping). The rail-level
    constraints (and a bending carbody's point constraints) are index-3 (positions
    prescribed).
    """

    step_size: float = 2.0e-4
    spectral_radius: float = 1.0

    def __post_init__(self) -> None:
        if not self.step_size > 0:
            raise ValueError(f"IntegratorSettings: step_size = {self.step_size} s; must be > 0")
        if not 0.0 <= self.spectral_radius <= 1.0:
            raise ValueError(f"IntegratorSettings: spectral_radius = {self.spectral_radius}; must be in [0, 1]")


@dataclass(frozen=True, eq=False)
class CarResponse:
    """Outputs of the exudyn car over a track.

    t [s]; outputs: ``{name}_acc_z`` [m/s^2] (vertical acceleration of the body's centre of
    mass; a bending carbody's includes its shape there times q'') and
    ``{name}_pitch_rate`` [rad/s] (railcal's sign) for carbody, bogie1, bogie2;
    wall_time [s] of exudyn's time integration alone; build_time [s] of the model (symbolic
    rail functions included).
    """

    t: np.ndarray
    outputs: dict
    wall_time: float
    build_time: float


def simulate_car_exudyn(p: CarParameters, rail: RailInput, *, duration: float, output_interval: float = 1e-3,
                        settings: IntegratorSettings = IntegratorSettings(),
                        extras: CarExtras | None = None) -> CarResponse:
    """Drive the exudyn car (with ``extras``) over ``rail`` for ``duration`` [s] from static
    equilibrium and sample its outputs every ``output_interval`` [s] (a multiple of the step
    size)."""
    ratio = output_interval / settings.step_size
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        raise ValueError(f"output_interval {output_interval} s must be a multiple of the step size "
                         f"{settings.step_size} s")
    n_out = round(duration / output_interval)
    if n_out < 1 or abs(n_out * output_interval - duration) > 1e-9 * duration:
        raise ValueError(f"duration {duration} s must be a positive multiple of output_interval {output_interval} s")
    rail.check_covers(p, duration)
    t0 = time.perf_counter()
    mbs, h = build_car_exudyn(p, rail=rail, extras=extras)
    sensors = {}
    for b in BODIES:
        sensors[f"{b}_acc_z"] = mbs.AddSensor(SensorNode(nodeNumber=h.nodes[b], storeInternal=True, writeToFile=False,
                                                         outputVariableType=exu.OutputVariableType.Acceleration))
        sensors[f"{b}_pitch_rate"] = mbs.AddSensor(SensorNode(
            nodeNumber=h.nodes[b], storeInternal=True, writeToFile=False,
            outputVariableType=exu.OutputVariableType.AngularVelocity))
    if h.bending_shape is not None:  # q'' adds shape(0) q'' at the carbody's centre
        sensors["carbody_bending_tt"] = mbs.AddSensor(SensorNode(
            nodeNumber=h.nodes["carbody_bending"], storeInternal=True, writeToFile=False,
            outputVariableType=exu.OutputVariableType.Coordinates_tt))
    mbs.Assemble()
    build_time = time.perf_counter() - t0

    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.endTime = n_out * output_interval
    ti.numberOfSteps = round(ti.endTime / settings.step_size)
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = settings.spectral_radius
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.newton.useModifiedNewton = True  # the model is linear: one Jacobian serves every step
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = output_interval
    ss.show.statistics = False
    ss.show.computationTime = False
    t0 = time.perf_counter()
    mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    wall = time.perf_counter() - t0

    outputs, t = {}, None
    for name in OUTPUTS:
        data = np.asarray(mbs.GetSensorStoredData(sensors[name]))
        t = data[:, 0]
        outputs[name] = data[:, 2] if name.endswith("acc_z") else -data[:, 3]
    if h.bending_shape is not None:
        q_tt = np.asarray(mbs.GetSensorStoredData(sensors["carbody_bending_tt"]))[:, 1]
        outputs["carbody_acc_z"] = outputs["carbody_acc_z"] + h.bending_shape(0.0) * q_tt
    return CarResponse(t, outputs, wall, build_time)
