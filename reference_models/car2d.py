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

Gravity is left out: coordinates are deviations from static equilibrium, as railcal's outputs
are (an acceleration is the same either way). exudyn's phi turns counter-clockwise, which
lifts the front; railcal's pitch lowers it, so ``pitch = -phi`` and ``pitch_rate = -omega_z``.

The rail input is a natural cubic spline through a track table (as the FMU interpolates its
track file), traversed at constant speed. exudyn evaluates it in C++ as a symbolic user
function: a balanced binary tree of ``IfThenElse`` over the spline intervals with the
interval's cubic at each leaf, so one evaluation costs ~log2(intervals) comparisons and no
Python runs during time integration.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import exudyn as exu
import numpy as np
import scipy.interpolate
import scipy.optimize
from exudyn.advancedUtilities import CreateSymbolicUserFunction
from exudyn.itemInterface import (CartesianSpringDamper, CoordinateConstraint, MarkerBodyPosition,
                                  MarkerNodeCoordinate, Node1D, NodePointGround, NodeRigidBody2D, ObjectMass1D,
                                  ObjectRigidBody2D, SensorNode)

from calibration.models.car2d import bogie_positions, build_car, damped_modes, undamped_modes, wheelset_positions
from calibration.models.parameters import CarParameters

BODIES = ("carbody", "bogie1", "bogie2")
OUTPUTS = tuple(f"{b}_{q}" for b in BODIES for q in ("acc_z", "pitch_rate"))  # the car FMU's names
_VERTICAL = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # Mass1D's axis along y


# ---------------------------------------------------------------------------- rail input
@dataclass(frozen=True, eq=False)
class RailInput:
    """The rail level along the track, passed at constant speed.

    Attributes
    ----------
    distance : array  [m] track distances of the table, strictly increasing (>= 3 points).
    level : array  [m] rail level at ``distance``; interpolated by a natural cubic spline.
    speed : float  [m/s] vehicle speed, > 0.
    start : float  [m] track distance of the carbody centre at t = 0.
    """

    distance: np.ndarray
    level: np.ndarray
    speed: float
    start: float = 0.0

    def __post_init__(self) -> None:
        s = np.array(self.distance, dtype=float)
        z = np.array(self.level, dtype=float)
        if s.ndim != 1 or z.shape != s.shape:
            raise ValueError(f"RailInput: distance {s.shape} and level {z.shape} must be 1-D of equal length")
        if len(s) < 3:
            raise ValueError(f"RailInput: the track table needs at least 3 points, has {len(s)}")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(z))):
            raise ValueError("RailInput: distance and level must be finite")
        if np.any(np.diff(s) <= 0):
            k = int(np.argmax(np.diff(s) <= 0))
            raise ValueError(f"RailInput: distance must increase strictly; row {k + 1} ({s[k + 1]} m) "
                             f"follows {s[k]} m")
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"RailInput: speed = {self.speed} m/s; must be > 0")
        if not np.isfinite(self.start):
            raise ValueError(f"RailInput: start = {self.start} m is not finite")
        s.flags.writeable = z.flags.writeable = False
        object.__setattr__(self, "distance", s)
        object.__setattr__(self, "level", z)
        object.__setattr__(self, "speed", float(self.speed))
        object.__setattr__(self, "start", float(self.start))

    def spline(self) -> scipy.interpolate.CubicSpline:
        """Rail level [m] over track distance [m]: the natural cubic spline of the table."""
        return scipy.interpolate.CubicSpline(self.distance, self.level, bc_type="natural")

    def under_wheelsets(self, p: CarParameters, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rail level [m] and its rate [m/s] under wheelsets 1-4 at times ``t`` [s], each (n_t, 4)."""
        s = self.start + self.speed * np.asarray(t, float)[:, None] + wheelset_positions(p)[None, :]
        spline = self.spline()
        return spline(s), self.speed * spline(s, 1)

    def time_on_track(self, p: CarParameters) -> float:
        """Time [s] until the leading wheelset passes the end of the table."""
        return float((self.distance[-1] - self.start - wheelset_positions(p).max()) / self.speed)

    def check_covers(self, p: CarParameters, duration: float) -> None:
        """Raise ValueError unless every wheelset stays on the table for ``duration`` [s]."""
        xw = wheelset_positions(p)
        first, last = self.start + xw.min(), self.start + self.speed * duration + xw.max()
        if first < self.distance[0] or last > self.distance[-1]:
            raise ValueError(f"RailInput: the wheelsets run over track distances {first:.2f}-{last:.2f} m in "
                             f"{duration} s, but the table covers only {self.distance[0]:.2f}-"
                             f"{self.distance[-1]:.2f} m")


def _piecewise_tree(x, breaks: np.ndarray, coefs: np.ndarray, lo: int, hi: int):
    """Symbolic value at ``x`` of the piecewise polynomial (scipy PPoly layout: ``coefs[k, i]``
    multiplies (x - breaks[i])**(order - k)) over intervals lo..hi-1, as a balanced tree of
    IfThenElse; intervals outside the table extend the first/last polynomial."""
    if hi - lo == 1:
        u = x - float(breaks[lo])
        value = float(coefs[0, lo])
        for c in coefs[1:, lo]:
            value = value * u + float(c)
        return value
    mid = (lo + hi) // 2
    return exu.symbolic.IfThenElse(x < float(breaks[mid]), _piecewise_tree(x, breaks, coefs, lo, mid),
                                   _piecewise_tree(x, breaks, coefs, mid, hi))


def rail_functions(rail: RailInput, x_wheelset: float):
    """Python offset functions (level [m], rate [m/s] vs time) of a wheelset at vehicle-frame
    ``x_wheelset``, written in exudyn symbolic arithmetic so they convert to C++ expressions."""
    spline = rail.spline()
    slope = spline.derivative()
    s0, v = rail.start + x_wheelset, rail.speed

    def level(mbs, t, itemNumber, lOffset):
        return _piecewise_tree(s0 + v * t, spline.x, spline.c, 0, spline.c.shape[1])

    def rate(mbs, t, itemNumber, lOffset):
        return v * _piecewise_tree(s0 + v * t, slope.x, slope.c, 0, slope.c.shape[1])

    return level, rate


def drive_rail_constraints(mbs, rail: RailInput, constraints, wheelset_x) -> list:
    """Give each wheelset's rail-level constraint the track's level and rate as symbolic user
    functions (after ``mbs.Assemble()``, exudyn's recipe) and assemble again. Returns the
    functions, which must outlive the system."""
    keep = []
    for con, x in zip(constraints, wheelset_x):
        level, rate = rail_functions(rail, float(x))
        uf = CreateSymbolicUserFunction(mbs, level, "offsetUserFunction", con)
        uf_t = CreateSymbolicUserFunction(mbs, rate, "offsetUserFunction_t", con)
        mbs.SetObjectParameter(con, "offsetUserFunction", uf)
        mbs.SetObjectParameter(con, "offsetUserFunction_t", uf_t)
        keep += [uf, uf_t]
    mbs.Assemble()
    return keep


# ---------------------------------------------------------------------------- the model
@dataclass(frozen=True, eq=False)
class CarHandles:
    """Indices of the exudyn car's items.

    ``nodes`` and ``bodies``: carbody, bogie1, bogie2, wheelset1..4; ``springs``: primary1..4,
    secondary1..2; ``rail_constraints``: one per wheelset; ``longitudinal_constraints``: one per
    rigid body. ``coordinates`` maps railcal's DOF names (carbody_z, carbody_pitch, ...) to
    (ODE2 index, sign) with railcal DOF = sign * exudyn coordinate. ``keep_alive`` holds the
    system container and the symbolic user functions, which must outlive the system.
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


def build_car_exudyn(p: CarParameters, *, rail: RailInput | None = None) -> tuple[exu.MainSystem, CarHandles]:
    """Build and assemble the planar car in exudyn.

    Parameters
    ----------
    p : CarParameters  masses [kg], inertias [kg m^2], stiffnesses [N/m], dampings [N s/m],
        lengths [m].
    rail : RailInput, optional  the track to drive the wheelsets; None holds the rails at zero
        level (for eigen-analysis).

    Returns
    -------
    mbs : exudyn.MainSystem  assembled, initial state = static equilibrium on the rail at
        t = 0 (all springs relaxed, body velocities zero, wheelsets at the rail's level and rate).
    handles : CarHandles
    """
    if not isinstance(p, CarParameters):
        raise TypeError(f"build_car_exudyn needs CarParameters, not {type(p).__name__}")
    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    xb = {"carbody": 0.0, "bogie1": bogie_positions(p)[0], "bogie2": bogie_positions(p)[1]}
    xw = wheelset_positions(p)
    z0, dz0 = rail.under_wheelsets(p, np.zeros(1)) if rail is not None else (np.zeros((1, 4)), np.zeros((1, 4)))
    z0, dz0 = z0[0], dz0[0]

    # without gravity, static equilibrium on the rails at t = 0 is kinematic: every spring relaxed
    z_bogie = {f"bogie{i + 1}": 0.5 * (z0[2 * i] + z0[2 * i + 1]) for i in range(2)}
    pitch = {f"bogie{i + 1}": (z0[2 * i + 1] - z0[2 * i]) / (2.0 * p.L_b) for i in range(2)}
    z_start = {"carbody": 0.5 * (z_bogie["bogie1"] + z_bogie["bogie2"]), **z_bogie}
    pitch["carbody"] = (z_bogie["bogie2"] - z_bogie["bogie1"]) / (2.0 * p.L_v)

    n_ground = mbs.AddNode(NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    m_ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_ground, coordinate=0))
    nodes, bodies, coordinates, longitudinal = {}, {}, {}, []
    mass = {"carbody": (p.m_v, p.J_v), "bogie1": (p.m_b, p.J_b), "bogie2": (p.m_b, p.J_b)}
    for name in BODIES:
        nodes[name] = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[xb[name], 0.0, 0.0],
                                                  initialCoordinates=[0.0, z_start[name], -pitch[name]]))
        bodies[name] = mbs.AddObject(ObjectRigidBody2D(nodeNumber=nodes[name], mass=mass[name][0],
                                                       inertia=mass[name][1]))
        m_x = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[name], coordinate=0))
        longitudinal.append(mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m_x])))

    def attach(body: str, x: float):
        return mbs.AddMarker(MarkerBodyPosition(bodyNumber=bodies[body], localPosition=[x - xb[body], 0.0, 0.0]))

    def spring_damper(top, bottom, k, c):
        return mbs.AddObject(CartesianSpringDamper(markerNumbers=[bottom, top], stiffness=[0.0, k, 0.0],
                                                   damping=[0.0, c, 0.0]))

    springs, rail_constraints, keep_alive = {}, [], [sc]
    for i in range(2):
        springs[f"secondary{i + 1}"] = spring_damper(attach("carbody", xb[f"bogie{i + 1}"]),
                                                     attach(f"bogie{i + 1}", xb[f"bogie{i + 1}"]), p.k_s, p.c_s)
    for j in range(4):
        w = f"wheelset{j + 1}"
        nodes[w] = mbs.AddNode(Node1D(referenceCoordinates=[0.0], initialCoordinates=[z0[j]],
                                      initialVelocities=[dz0[j]]))
        bodies[w] = mbs.AddObject(ObjectMass1D(nodeNumber=nodes[w], mass=p.m_w,
                                               referencePosition=[xw[j], 0.0, 0.0], referenceRotation=_VERTICAL))
        m_w = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=nodes[w], coordinate=0))
        con = mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m_w]))
        rail_constraints.append(con)
        m_contact = mbs.AddMarker(MarkerBodyPosition(bodyNumber=bodies[w], localPosition=[0.0, 0.0, 0.0]))
        springs[f"primary{j + 1}"] = spring_damper(attach(f"bogie{1 + j // 2}", xw[j]), m_contact, p.k_p, p.c_p)

    mbs.Assemble()
    if rail is not None:
        keep_alive += drive_rail_constraints(mbs, rail, rail_constraints, xw)

    for name in BODIES:
        first = mbs.GetNodeODE2Index(nodes[name])
        coordinates[f"{name}_z"] = (first + 1, 1.0)
        coordinates[f"{name}_pitch"] = (first + 2, -1.0)
    handles = CarHandles(p, rail, nodes, bodies, springs, tuple(rail_constraints), tuple(longitudinal),
                         coordinates, tuple(keep_alive))
    return mbs, handles


# ---------------------------------------------------------------------------- eigenvalues
def exudyn_eigenvalues(p: CarParameters, *, damped: bool) -> np.ndarray:
    """Eigenvalues of the car on fixed rails from exudyn's ``ComputeODE2Eigenvalues``
    (constraints eliminated by its null-space projection).

    Returns
    -------
    damped=False: undamped natural frequencies [Hz], ascending (6).
    damped=True: the eigenvalues [rad/s] of the damped system with non-negative imaginary part
        (one per conjugate pair, and each real root), ordered by modulus.
    """
    mbs, _ = build_car_exudyn(p)
    if not damped:
        w2, _ = mbs.ComputeODE2Eigenvalues(useAbsoluteValues=False)
        return np.sqrt(np.sort(np.asarray(w2, float))) / (2.0 * np.pi)
    lam, _ = mbs.ComputeODE2Eigenvalues(computeComplexEigenvalues=True, useAbsoluteValues=False)
    lam = np.asarray(lam, complex)
    scale = np.abs(lam).max()
    lam = lam[lam.imag >= -1e-12 * scale]
    return lam[np.argsort(np.abs(lam))]


def railcal_eigenvalues(p: CarParameters, *, damped: bool) -> np.ndarray:
    """railcal's own eigenvalues of the rail-level car, in :func:`exudyn_eigenvalues`' format,
    from :func:`calibration.models.car2d.undamped_modes` / ``damped_modes``."""
    asm = build_car(p)
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
    generalized-alpha (1 = trapezoidal rule, no numerical damping). The wheelsets'
    rail-level constraints are index-3 (positions prescribed).
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

    t [s]; outputs: ``{name}_acc_z`` [m/s^2] (vertical acceleration of the body's centre) and
    ``{name}_pitch_rate`` [rad/s] (railcal's sign) for carbody, bogie1, bogie2;
    wall_time [s] of exudyn's time integration alone; build_time [s] of the model (symbolic
    rail functions included).
    """

    t: np.ndarray
    outputs: dict
    wall_time: float
    build_time: float


def simulate_car_exudyn(p: CarParameters, rail: RailInput, *, duration: float, output_interval: float = 1e-3,
                        settings: IntegratorSettings = IntegratorSettings()) -> CarResponse:
    """Drive the exudyn car over ``rail`` for ``duration`` [s] from static equilibrium and
    sample its outputs every ``output_interval`` [s] (a multiple of the step size)."""
    ratio = output_interval / settings.step_size
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        raise ValueError(f"output_interval {output_interval} s must be a multiple of the step size "
                         f"{settings.step_size} s")
    n_out = round(duration / output_interval)
    if n_out < 1 or abs(n_out * output_interval - duration) > 1e-9 * duration:
        raise ValueError(f"duration {duration} s must be a positive multiple of output_interval {output_interval} s")
    rail.check_covers(p, duration)
    t0 = time.perf_counter()
    mbs, h = build_car_exudyn(p, rail=rail)
    sensors = {}
    for b in BODIES:
        sensors[f"{b}_acc_z"] = mbs.AddSensor(SensorNode(nodeNumber=h.nodes[b], storeInternal=True, writeToFile=False,
                                                         outputVariableType=exu.OutputVariableType.Acceleration))
        sensors[f"{b}_pitch_rate"] = mbs.AddSensor(SensorNode(
            nodeNumber=h.nodes[b], storeInternal=True, writeToFile=False,
            outputVariableType=exu.OutputVariableType.AngularVelocity))
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
    for name, s in sensors.items():
        data = np.asarray(mbs.GetSensorStoredData(s))
        t = data[:, 0]
        outputs[name] = data[:, 2] if name.endswith("acc_z") else -data[:, 3]
    return CarResponse(t, outputs, wall, build_time)
