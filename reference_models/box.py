"""The box-type vehicle of :mod:`calibration.models.box`, built again in exudyn.

An independent reference for railcal's reduced box vehicle
(:func:`calibration.models.box.vehicle_reduction.reduce_vehicle`). It is built from the vehicle
description (:func:`calibration.models.box.shinkansen.shinkansen_vehicle`) and the stiffness
factors only: the carbody's modal data (the flexible body's definition) are its free-free
modes and static-correction pseudo-modes from the free carbody's own matrices
(``assemble(free_carbody(vehicle))``, by railcal's
:func:`~calibration.models.box.vehicle_reduction.carbody_basis`); the vehicle around it, bogies,
suspension and rails, is exudyn's items, never railcal's assembled vehicle or reduced matrices.

The model (carbody frame: x forward, y left, z up; no gravity, coordinates are deviations
from static equilibrium):

* carbody: a modal flexible body on ONE ``NodeGenericODE2`` of modal coordinates eta: the free
  carbody's modes below ``cutoff_hz`` (the six rigid-body modes among them) and one
  residual-flexibility pseudo-mode per carbody load (the exciter, and every suspension seat
  along each axis its element acts in), M-orthonormal and K-diagonal. Two exudyn objects
  share that node:

  - an ``ObjectGenericODE2`` holds the modal equations: mass I, stiffness diag(omega^2),
    damping diag(2 zeta omega) on every coordinate with omega > 2 pi 0.05 rad/s (constant
    sparse matrices);
  - an ``ObjectFFRFreducedOrder`` (CMS body) holds the kinematics: its "mesh nodes" are the
    attachment points only, each suspension seat (the patch-mean displacement of the seat, as
    railcal seats it), each floor sensor and the exciter, with the rows of ``modeBasis`` = that
    point's displacement per mode; its markers and sensors give the points' motion and take
    the suspension forces onto eta through the same rows. Its floating frame (a
    ``NodeRigidBodyRxyz``) is held at the origin by six ``CoordinateConstraint``s, since the
    rigid motion is carried by modes, and its FFRF inertia terms are off
    (``computeFFRFterms=False``): with the frame held they only couple held coordinates, and
    evaluating them (products of 3n x 3n matrices at every mass-matrix and force evaluation)
    took 95 % of the integration time. The body is the linear modal model either way
    (identical eigenfrequencies and responses);
* bogies 1 and 2 (and an extended model's equipment): ``ObjectRigidBody`` on
  ``NodeRigidBodyRxyz`` at their centres of mass, mass and principal inertias from the vehicle
  description; a body's held DOF (the equipment's all but the vertical) by a
  ``CoordinateConstraint`` each;
* every suspension ``Link``: a ``CartesianSpringDamper`` (per-axis k [N/m] and c [N s/m]) from a
  ``MarkerSuperElementPosition`` at the seat (or, for an axle box, a ``MarkerBodyPosition`` on
  its wheelset's rail point) to a ``MarkerBodyPosition`` on the bogie;
* the rail under wheelset j (1 leads: wheelset x descending, as railcal numbers them): a
  vertical ``ObjectMass1D`` on a ``Node1D`` whose coordinate is prescribed to the rail level by
  a ``CoordinateConstraint`` with symbolic spline offsets (:class:`reference_models.rail.
  RailInput`, C++ at run time); every axle box of that wheelset hangs on it, so its ground end
  moves vertically with the rail (railcal: e = D q + e_z z_j). Without a rail the levels are
  held at zero (the stationary excitation test);
* the exciter: a ``LoadForceVector`` along +z on its mesh node, its force interpolated
  linearly between the given samples; floor sensors: ``SensorSuperElement`` accelerations.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import exudyn as exu
import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.sparse.linalg
from exudyn.itemInterface import (
    CartesianSpringDamper,
    CoordinateConstraint,
    LoadForceVector,
    MarkerBodyPosition,
    MarkerNodeCoordinate,
    MarkerSuperElementPosition,
    Node1D,
    NodeGenericODE2,
    NodePointGround,
    NodeRigidBodyRxyz,
    ObjectFFRFreducedOrder,
    ObjectGenericODE2,
    ObjectMass1D,
    ObjectRigidBody,
    SensorSuperElement,
    VObjectFFRFreducedOrder,
    VObjectGenericODE2,
)

from calibration.models.box.assembly import RIGID_DOFS, BoxModel, local_operator, assemble
from calibration.models.box.vehicle_reduction import carbody_basis
from calibration.models.box.fit import sensor_operator
from calibration.models.box.shinkansen import free_carbody
from reference_models.rail import RailInput, drive_rail_constraints

RIGID_HZ = 0.05  # [Hz] carbody modes below this are rigid-body motions (no structural damping)
RAIL_MASS = 1.0  # [kg] of each prescribed rail point (its motion is given: the value only scales a reaction)
_UP = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # Mass1D's axis along z


# ---------------------------------------------------------------------------- the flexible body
@dataclass(frozen=True, eq=False)
class CarbodyModes:
    """The carbody as a modal flexible body.

    Attributes
    ----------
    omega : (n,) [rad/s] of each modal coordinate (rigid ones ~0).
    n_modes : number of true free-free modes (below the cut-off); the rest are pseudo-modes.
    points : (n_p, 3) [m] attachment points (carbody frame).
    names : (n_p,) what each point is: a Link name, a sensor name or the exciter's.
    basis : (3 n_p, n) [m per unit eta] displacement x, y, z of each point per coordinate.
    """

    omega: np.ndarray
    n_modes: int
    points: np.ndarray
    names: tuple
    basis: np.ndarray
    cutoff_hz: float

    def index(self, name: str) -> int:
        return self.names.index(name)


def carbody_modes(vehicle, parameters, cutoff_hz: float, sensors, exciter) -> CarbodyModes:
    """Modal data of the free carbody of ``vehicle`` at stiffness factors ``parameters``
    (dict by name, or in the vehicle's parameter order): its modes below ``cutoff_hz`` [Hz] and
    the residual-flexibility pseudo-modes of the loads at the suspension seats and the exciter
    (static correction), and the displacement of every attachment point per coordinate."""
    cb = assemble(free_carbody(vehicle))
    names = cb.names
    p = np.array([float(parameters[n]) for n in names]) if isinstance(parameters, dict) else \
        np.asarray(parameters, float)
    if p.shape != (len(names),):
        raise ValueError(f"parameters: expected {len(names)} stiffness factors {names}, got shape {p.shape}")
    panels = {pn.name for pn in vehicle.panels}
    pts, labels, ops, loads = [], [], [], []
    for ln in vehicle.links:
        if ln.body_a in panels:
            idx, G = local_operator(cb, ln.body_a, ln.point_a, patch=ln.patch)
            full = np.zeros((3, cb.n_dof))
            full[:, idx] = G
            pts.append(ln.point_a)
            labels.append(ln.name)
            ops.append(full)
            loads += [full[d] for d in range(3) if ln.k[d] or ln.c[d]]
        elif ln.body_b in panels:
            raise ValueError(f"link {ln.name}: a carbody end must be body_a")
    for s in (exciter,) + tuple(sensors):
        rows = np.zeros((3, cb.n_dof))
        for d in "xyz":  # all three translations of the sensor's point
            rows["xyz".index(d)] = sensor_operator(cb, (_along(s, d),))[0]
        pts.append(s.position)
        labels.append(s.name)
        ops.append(rows)
    loads.insert(0, ops[labels.index(exciter.name)]["xyz".index(exciter.direction)])

    # the modes below the cut-off and the pseudo-modes of these loads: the carbody's own modal
    # data (calibration.models.box.vehicle_reduction); the vehicle around it is exudyn's
    V, omega, n_modes = carbody_basis(cb, p, cutoff_hz, np.column_stack(loads))
    basis = np.vstack([op @ V for op in ops])
    return CarbodyModes(omega, n_modes, np.array(pts, float), tuple(labels), basis, float(cutoff_hz))


def _container(A: np.ndarray) -> exu.MatrixContainer:
    mc = exu.MatrixContainer()
    mc.SetWithDenseMatrix(A, useDenseMatrix=False)
    return mc


def _along(sensor, direction):
    return replace(sensor, direction=direction)


# ---------------------------------------------------------------------------- the model
@dataclass(frozen=True, eq=False)
class BoxHandles:
    """Indices of the exudyn box vehicle's items.

    ``carbody``: the CMS object (attachment-point kinematics); ``modal_object``: the
    ObjectGenericODE2 of the modal equations; ``modal_node``: the modal coordinates;
    ``frame_node``: the CMS object's held floating frame; ``bogies`` / ``bogie_nodes`` by name;
    ``links``: connector per Link name;
    ``mesh``: mesh-node index per attachment name (Link names, sensor names, exciter);
    ``rail_nodes`` / ``rail_constraints``: the prescribed rail point of wheelsets 1-4 and its
    constraint; ``wheelset_x`` (4,) [m]: their positions; ``load``: the exciter load (None
    without force); ``modes``: the CarbodyModes used; ``keep_alive``: the system container and
    user functions.
    """

    carbody: int
    modal_object: int
    modal_node: int
    frame_node: int
    bogies: dict
    bogie_nodes: dict
    links: dict
    mesh: dict
    rail_nodes: tuple
    rail_constraints: tuple
    wheelset_x: np.ndarray
    load: int | None
    modes: CarbodyModes
    keep_alive: tuple = field(repr=False, default=())


def axle_box_wheelsets(vehicle) -> np.ndarray:
    """Track-wise positions [m] (carbody frame) of wheelsets 1-4, leading first: the distinct x
    of the axle boxes' ground ends, as :func:`~calibration.models.box.vehicle_reduction.reduce_vehicle`
    numbers them."""
    x = sorted({round(ln.point_a[0], 9) for ln in vehicle.links if ln.body_a == "ground" and ln.body_b != "ground"},
               reverse=True)
    if len(x) != 4:
        raise ValueError(f"expected axle boxes (links from 'ground') at four wheelset positions, found x = {x} m")
    return np.array(x, float)


def rail_levels(rail: RailInput, wheelset_x: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rail level [m] and its rate [m/s] under the wheelsets at ``wheelset_x`` [m] at times ``t`` [s],
    each (n_t, n_wheelsets)."""
    s = rail.start + rail.speed * np.asarray(t, float)[:, None] + np.asarray(wheelset_x)[None, :]
    spline = rail.spline()
    return spline(s), rail.speed * spline(s, 1)


def _check_covers(rail: RailInput, wheelset_x: np.ndarray, duration: float) -> None:
    first, last = rail.start + wheelset_x.min(), rail.start + rail.speed * duration + wheelset_x.max()
    if first < rail.distance[0] or last > rail.distance[-1]:
        raise ValueError(f"rail: the wheelsets run over track distances {first:.2f}-{last:.2f} m in {duration} s, "
                         f"but the table covers only {rail.distance[0]:.2f}-{rail.distance[-1]:.2f} m")


def build_box_exudyn(vehicle_model, parameters, *, cutoff_hz: float, zeta: float, sensors=None, exciter=None,
                     rail: RailInput | None = None, force=None,
                     modes: CarbodyModes | None = None) -> tuple[exu.MainSystem, BoxHandles]:
    """Build and assemble the box-type vehicle in exudyn, on rails.

    Parameters
    ----------
    vehicle_model : BoxModel or BoxVehicle  the vehicle (only its description is read).
    parameters : dict or array  stiffness factors (nominal 1) by name or in parameter order.
    cutoff_hz : float  [Hz] carbody modes kept.
    zeta : float  [-] modal damping ratio of the carbody's elastic coordinates.
    sensors, exciter : campaign Sensors; default the excitation test's SENSOR_GRID, EXCITER.
    rail : RailInput, optional  the track passed at its speed [m/s] from ``rail.start`` [m]
        (track distance of the carbody centre at t = 0); None holds every rail level at zero.
    force : (t [s], F [N]) arrays, optional  exciter force (+z on the floor), linear between
        samples, held at the last value after them.
    modes : CarbodyModes, optional  the carbody's modal data from :func:`carbody_modes` for these
        ``vehicle_model``, ``parameters``, ``cutoff_hz``, ``sensors`` and ``exciter``, to build
        several systems from one computation of them (it takes most of a build); None computes them.

    Returns
    -------
    mbs : exudyn.MainSystem, assembled; initial state = static equilibrium on the rail levels at
        t = 0 (found by exudyn's static solver), bodies at rest, rail points at the rails' rates.
    handles : BoxHandles
    """
    if rail is not None and not isinstance(rail, RailInput):
        raise TypeError(f"rail: expected a reference_models.rail.RailInput, not {type(rail).__name__}")
    if not zeta >= 0:
        raise ValueError(f"zeta = {zeta}; must be >= 0")
    if sensors is None or exciter is None:
        from calibration.models.box.rig import EXCITER, SENSOR_GRID
        sensors = SENSOR_GRID if sensors is None else sensors
        exciter = EXCITER if exciter is None else exciter
    vehicle = getattr(vehicle_model, "vehicle", vehicle_model)
    wheelset_x = axle_box_wheelsets(vehicle)
    if modes is None:
        modes = carbody_modes(vehicle, parameters, cutoff_hz, sensors, exciter)
    else:
        missing = [s.name for s in (exciter, *sensors) if s.name not in modes.names]
        if modes.cutoff_hz != cutoff_hz or missing:
            raise ValueError(f"modes: computed for a cut-off of {modes.cutoff_hz} Hz, here {cutoff_hz} Hz"
                             + (f"; no attachment point for {', '.join(missing)}" if missing else ""))
    n = modes.omega.size

    sc = exu.SystemContainer()
    mbs = sc.AddSystem()
    n_ground = mbs.AddNode(NodePointGround())
    m_ground = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=n_ground, coordinate=0))

    # carbody: the modal equations on the modal node, and a CMS body with a held frame for the
    # attachment points' kinematics (no FFRF inertia terms: they would act on the held frame only)
    frame = mbs.AddNode(NodeRigidBodyRxyz(referenceCoordinates=[0.0] * 6))
    for i in range(6):
        m = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=frame, coordinate=i))
        mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m]))
    modal = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0] * n, initialCoordinates=[0.0] * n,
                                        initialCoordinates_t=[0.0] * n, numberOfODE2Coordinates=n))
    elastic = modes.omega > 2 * np.pi * RIGID_HZ
    modal_object = mbs.AddObject(ObjectGenericODE2(
        nodeNumbers=[modal], massMatrix=_container(np.eye(n)), stiffnessMatrix=_container(np.diag(modes.omega**2)),
        dampingMatrix=_container(np.diag(np.where(elastic, 2.0 * zeta * modes.omega, 0.0))),
        visualization=VObjectGenericODE2(show=False)))
    carbody = mbs.AddObject(ObjectFFRFreducedOrder(
        nodeNumbers=[frame, modal], modeBasis=modes.basis, referencePositions=modes.points.ravel(),
        computeFFRFterms=False, visualization=VObjectFFRFreducedOrder(show=False)))
    mesh = {name: i for i, name in enumerate(modes.names)}

    def seat(name):
        return mbs.AddMarker(MarkerSuperElementPosition(bodyNumber=carbody, meshNodeNumbers=[mesh[name]],
                                                        weightingFactors=[1.0]))

    bogies, bogie_nodes = {}, {}
    for rb in vehicle.bodies:
        bogie_nodes[rb.name] = mbs.AddNode(NodeRigidBodyRxyz(referenceCoordinates=list(rb.centre) + [0.0] * 3))
        bogies[rb.name] = mbs.AddObject(ObjectRigidBody(nodeNumber=bogie_nodes[rb.name], mass=rb.mass,
                                                        inertia=list(rb.inertia) + [0.0] * 3))
        for held in rb.fixed:  # a held DOF (an extended model's equipment moves vertically only)
            m = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=bogie_nodes[rb.name], coordinate=RIGID_DOFS.index(held)))
            mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m]))

    # the rail under each wheelset: a vertical point mass whose level the rail prescribes
    rail_nodes, rail_bodies, rail_constraints = [], [], []
    for x in wheelset_x:
        node = mbs.AddNode(Node1D(referenceCoordinates=[0.0]))
        rail_nodes.append(node)
        rail_bodies.append(mbs.AddObject(ObjectMass1D(nodeNumber=node, mass=RAIL_MASS, referencePosition=[x, 0.0, 0.0],
                                                      referenceRotation=_UP)))
        m = mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=node, coordinate=0))
        rail_constraints.append(mbs.AddObject(CoordinateConstraint(markerNumbers=[m_ground, m])))

    def body_point(body, point):
        if body == "ground":  # an axle box's ground end: on its wheelset's rail point
            j = int(np.argmin(np.abs(wheelset_x - point[0])))
            local = _UP.T @ (np.asarray(point, float) - [wheelset_x[j], 0.0, 0.0])
            return mbs.AddMarker(MarkerBodyPosition(bodyNumber=rail_bodies[j], localPosition=list(local)))
        rb = next(b for b in vehicle.bodies if b.name == body)
        return mbs.AddMarker(MarkerBodyPosition(bodyNumber=bogies[body],
                                                localPosition=list(np.subtract(point, rb.centre))))

    links = {}
    for ln in vehicle.links:
        if ln.body_b == "ground":
            raise ValueError(f"link {ln.name}: a ground end must be body_a")
        a = seat(ln.name) if ln.name in mesh else body_point(ln.body_a, ln.point_a)
        b = body_point(ln.body_b, ln.point_b)
        # relaxed in the reference configuration: the offset is the ends' reference distance
        links[ln.name] = mbs.AddObject(CartesianSpringDamper(
            markerNumbers=[a, b], stiffness=list(ln.k), damping=list(ln.c),
            offset=list(np.subtract(ln.point_b, ln.point_a))))

    load, keep_alive, statics = None, [sc], {"on": False}
    if force is not None:
        tf, F = (np.asarray(v, float) for v in force)
        if tf.ndim != 1 or F.shape != tf.shape or np.any(np.diff(tf) <= 0):
            raise ValueError("force: (t, F) must be 1-D of equal length with t strictly increasing")
        direction = np.eye(3)["xyz".index(exciter.direction)]

        def uf_force(mbs_, t, load_vector):
            # the static solve below runs at a pseudo-time of its own, not at t = 0: the
            # equilibrium the run starts from takes the force at the first time
            return list(np.interp(tf[0] if statics["on"] else t, tf, F) * direction)

        load = mbs.AddLoad(LoadForceVector(markerNumber=seat(exciter.name), loadVector=[0.0, 0.0, 0.0],
                                           loadVectorUserFunction=uf_force))
        keep_alive.append(uf_force)
    mbs.Assemble()

    if rail is not None:
        z0, dz0 = (v[0] for v in rail_levels(rail, wheelset_x, np.zeros(1)))
        # static equilibrium on the rail levels at t = 0 (no gravity: the suspension's response to them)
        for con, z in zip(rail_constraints, z0):
            mbs.SetObjectParameter(con, "offset", float(z))
        mbs.Assemble()
        ss = exu.SimulationSettings()
        ss.staticSolver.verboseMode = 0
        ss.staticSolver.newton.numericalDifferentiation.jacobianConnectorDerivative = False
        # linear: one Newton step leaves a residual of round-off (~1e-8 N against ~1e3 N in the
        # springs), which the default relative goal would chase without end
        ss.staticSolver.newton.absoluteTolerance = 1e-6
        ss.solution.file.write = False
        statics["on"] = True
        try:
            solved = mbs.SolveStatic(ss)
        finally:
            statics["on"] = False
        if not solved:
            raise RuntimeError("build_box_exudyn: exudyn's static solver failed on the rail levels at t = 0")
        for node in [modal, *bogie_nodes.values()]:
            q = mbs.GetNodeOutput(node, exu.OutputVariableType.Coordinates)
            mbs.SetNodeParameter(node, "initialCoordinates", list(np.asarray(q, float)))
        for node, z, dz in zip(rail_nodes, z0, dz0):
            mbs.SetNodeParameter(node, "initialCoordinates", [float(z)])
            mbs.SetNodeParameter(node, "initialVelocities", [float(dz)])
        mbs.Assemble()
        keep_alive += drive_rail_constraints(mbs, rail, rail_constraints, wheelset_x)
    return mbs, BoxHandles(carbody, modal_object, modal, frame, bogies, bogie_nodes, links, mesh, tuple(rail_nodes),
                           tuple(rail_constraints), wheelset_x, load, modes, tuple(keep_alive))


# ---------------------------------------------------------------------------- eigenvalues
def exudyn_frequencies(mbs: exu.MainSystem, below_hz: float = 20.0) -> np.ndarray:
    """Undamped natural frequencies [Hz] below ``below_hz`` of an assembled exudyn system, by
    ``ComputeODE2Eigenvalues`` (constraints eliminated by its null-space projection)."""
    ss = exu.SimulationSettings()
    # At rest every connector is relaxed, so the derivative of the connector Jacobian (d J^T/dq
    # times force) is zero; exudyn finds it by finite differences of marker positions ~10 m
    # with a 1e-9 step, whose round-off alone moved the suspension modes by 2e-4 (relative).
    ss.staticSolver.newton.numericalDifferentiation.jacobianConnectorDerivative = False
    ss.solution.file.write = False  # no solution/ folder in the caller's directory
    w2, _ = mbs.ComputeODE2Eigenvalues(simulationSettings=ss, useAbsoluteValues=False)
    f = np.sqrt(np.clip(np.sort(np.asarray(w2, float)), 0.0, None)) / (2 * np.pi)
    return f[f < below_hz]


def reduced_frequencies(reduced, below_hz: float = 20.0) -> np.ndarray:
    """Undamped natural frequencies [Hz] below ``below_hz`` of a railcal ReducedVehicle."""
    w2 = scipy.linalg.eigh(reduced.K, reduced.M, eigvals_only=True)
    f = np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi)
    return f[f < below_hz]


def full_frequencies(model: BoxModel, parameters, below_hz: float = 20.0, shift_hz: float = 0.2) -> np.ndarray:
    """Undamped natural frequencies [Hz] below ``below_hz`` of the full assembled box model."""
    p = np.array([float(parameters[n]) for n in model.names]) if isinstance(parameters, dict) else \
        np.asarray(parameters, float)
    K, M = model.stiffness(p).tocsc(), model.M.tocsc()
    v0 = np.random.default_rng(0).standard_normal(model.n_dof)
    k = 40
    while True:
        w2 = scipy.sparse.linalg.eigsh(K, k=k, M=M, sigma=-(2 * np.pi * shift_hz) ** 2, which="LM", v0=v0,
                                       return_eigenvectors=False)
        f = np.sort(np.sqrt(np.clip(w2, 0.0, None)) / (2 * np.pi))
        if f[-1] > below_hz or k >= model.n_dof - 2:
            return f[f < below_hz]
        k = min(2 * k, model.n_dof - 2)


def eigen_errors(reference: np.ndarray, other: np.ndarray) -> np.ndarray:
    """|other - reference| / reference per reference value, after a one-to-one pairing by
    least total distance; values without a partner (sets of unequal size) are left out of
    ``other``, so the larger set must be ``other``."""
    reference, other = np.asarray(reference), np.asarray(other)
    rows, cols = scipy.optimize.linear_sum_assignment(np.abs(reference[:, None] - other[None, :]))
    err = np.full(len(reference), np.inf)
    err[rows] = np.abs(other[cols] - reference[rows]) / np.abs(reference[rows])
    return err


# ---------------------------------------------------------------------------- time response
@dataclass(frozen=True, eq=False)
class BoxResponse:
    """Floor accelerations of the exudyn box vehicle.

    t [s]; acc (n_t, n_sensors) [m/s^2] along each sensor's direction; sensors: names;
    wall_time [s] of the time integration alone; build_time [s] (modes, unless given, items and
    the static solution); cpu_time [s] of this process during the integration (wall_time without
    the waits for a shared machine's cores).
    """

    t: np.ndarray
    acc: np.ndarray
    sensors: tuple
    wall_time: float
    build_time: float
    cpu_time: float


def simulate_box_exudyn(vehicle_model, parameters, *, duration: float, cutoff_hz: float, zeta: float,
                        rail: RailInput | None = None, force=None, sensors=None, exciter=None,
                        step_size: float = 2e-4, output_interval: float = 1e-3,
                        spectral_radius: float = 1.0, modes: CarbodyModes | None = None) -> BoxResponse:
    """Floor accelerations of the vehicle over ``rail`` (None: rails held at level zero) with the
    exciter force ``force`` = (t [s], F [N]) (None: no force), from static equilibrium on the
    rails at t = 0, every ``output_interval`` [s] for ``duration`` [s], by exudyn's
    generalized-alpha with ``step_size`` [s] (rho_inf = ``spectral_radius``; 1: the trapezoidal
    rule, its error falls as the step squared: NRMSE 5e-4 at 2e-4 s, 3e-3 at 5e-4 s, 1e-2 at
    1e-3 s over a track). The model is linear, so each step is one linear solve with the
    Jacobian of t = 0 (Newton off; with it on, the answers agree to 6e-8 at twice the cost).
    ``modes``: the carbody's modal data if already computed (:func:`build_box_exudyn`)."""
    if sensors is None:
        from calibration.models.box.rig import SENSOR_GRID
        sensors = SENSOR_GRID
    ratio = output_interval / step_size
    if abs(ratio - round(ratio)) > 1e-9 * ratio or round(ratio) < 1:
        raise ValueError(f"output_interval {output_interval} s must be a multiple of step_size {step_size} s")
    n_out = round(duration / output_interval)
    if n_out < 1 or abs(n_out * output_interval - duration) > 1e-9 * duration:
        raise ValueError(f"duration {duration} s must be a positive multiple of output_interval {output_interval} s")
    if rail is not None:
        _check_covers(rail, axle_box_wheelsets(getattr(vehicle_model, "vehicle", vehicle_model)), duration)
    t0 = time.perf_counter()
    mbs, h = build_box_exudyn(vehicle_model, parameters, cutoff_hz=cutoff_hz, zeta=zeta, sensors=sensors,
                              exciter=exciter, rail=rail, force=force, modes=modes)
    out = [mbs.AddSensor(SensorSuperElement(bodyNumber=h.carbody, meshNodeNumber=h.mesh[s.name], storeInternal=True,
                                            writeToFile=False, outputVariableType=exu.OutputVariableType.Acceleration))
           for s in sensors]
    mbs.Assemble()
    build = time.perf_counter() - t0
    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.endTime = n_out * output_interval
    ti.numberOfSteps = round(ti.endTime / step_size)
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = spectral_radius
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.newton.useModifiedNewton = True  # the model is linear: one Jacobian serves every step ...
    ti.newton.active = False  # ... and one solve with it is the step (no residual check)
    ss.solution.file.write = False  # no solution/ folder in the caller's directory
    ss.solution.sensors.writePeriod = output_interval
    ss.show.statistics = False
    ss.show.computationTime = False
    t0, c0 = time.perf_counter(), time.process_time()
    mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    cols, t = [], None
    for s, k in zip(sensors, out):
        data = np.asarray(mbs.GetSensorStoredData(k))
        t = data[:, 0]
        cols.append(data[:, 1 + "xyz".index(s.direction)])
    return BoxResponse(t, np.column_stack(cols), tuple(s.name for s in sensors), wall, build, cpu)
