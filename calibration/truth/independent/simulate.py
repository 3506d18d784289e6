"""Running a built car (:mod:`.model`): its static equilibrium, its linearisation and a
time integration of a journey with the inputs under the wheelsets.

The time integration is exudyn's implicit generalized-alpha (spectral radius 0.8, which
damps the contact and pad modes the step cannot resolve) with a modified Newton method: the
Jacobian is kept while it converges. A 1 ms step (1 kHz) was measured against 0.5 ms on the
intercity car at 35 m/s: bogie rms acceleration equal within 0.1 %, axle box within 2 %,
carbody equal; 0.25 ms takes four times longer for no visible change below 200 Hz.
"""
from __future__ import annotations

from dataclasses import dataclass

import exudyn as exu
import exudyn.itemInterface as ei
import numpy as np
import scipy.linalg

from .model import CarModel

VERBOSE = 0
# Newton's relative tolerance: one iteration per step; the bogie's rms acceleration moves by
# 5e-5 against 1e-4 (measured), the modified Newton's contraction being about 0.005
NEWTON_TOLERANCE = 1e-2


def _settings(h: float | None = None, n: int = 0) -> "exu.SimulationSettings":
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = h if h else 1.0
    ss.timeIntegration.verboseMode = VERBOSE
    ss.staticSolver.verboseMode = 0
    ss.linearSolver.solverType = exu.LinearSolverType.EXUdense
    ss.show.statistics = False
    ss.show.computationTime = VERBOSE > 0
    if h:
        ss.timeIntegration.numberOfSteps = n
        ss.timeIntegration.endTime = n * h
        ss.timeIntegration.newton.useModifiedNewton = True
        ss.timeIntegration.generalizedAlpha.spectralRadius = 0.8
        ss.timeIntegration.newton.relativeTolerance = NEWTON_TOLERANCE
        ss.timeIntegration.newton.absoluteTolerance = 1e-2
    return ss


def settle(m: CarModel) -> np.ndarray:
    """Solve for the static equilibrium on a perfect track and make it the initial state;
    returns the ODE2 coordinates (displacements from the reference configuration) [m, rad]."""
    for v in m.inputs:
        v.SetValue(0.0)
    ss = _settings()
    ss.staticSolver.newton.relativeTolerance = 1e-8
    ss.staticSolver.newton.absoluteTolerance = 1e-6
    m.mbs.SolveStatic(ss)
    q = np.array(m.mbs.systemData.GetODE2Coordinates())
    m.mbs.systemData.SetODE2Coordinates(list(q), configuration=exu.ConfigurationType.Initial)
    return q


@dataclass(frozen=True)
class Modes:
    """Linearised modes at the current state: frequencies [Hz] (undamped), damped
    frequencies [Hz], damping ratios, mode shapes (columns, ODE2 coordinates) and labels."""

    frequencies: np.ndarray
    damped_frequencies: np.ndarray
    damping_ratios: np.ndarray
    shapes: np.ndarray
    labels: tuple

    def by_label(self) -> dict:
        """The lowest mode of each label (the seed's convention for the bogie pair):
        label -> (frequency [Hz], damped frequency [Hz], damping ratio)."""
        out: dict = {}
        for f, fd, z, lab in zip(self.frequencies, self.damped_frequencies, self.damping_ratios, self.labels):
            if lab != "other" and lab not in out:
                out[lab] = (float(f), float(fd), float(z))
        return out


def _label(m: CarModel, shape: np.ndarray, mass: np.ndarray) -> str:
    """Name a mode by where its kinetic energy sits: carbody bounce/pitch/bending, bogie bounce/pitch."""
    e = mass * shape ** 2
    total = e.sum()
    g = m.groups
    cy, by, bp = (e[g[k]].sum() / total for k in ("carbody_y", "bogie_y", "bogie_pitch"))
    if cy > 0.5:
        x = np.asarray(m.p.x_nodes)
        y = shape[g["carbody_y"]]
        A = np.column_stack([np.ones_like(x), x])
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        fit = 1 - np.sum((y - A @ coef) ** 2) / max(np.sum(y ** 2), 1e-300)
        if fit < 0.8:
            return "carbody_bending"
        return "carbody_bounce" if abs(coef[0]) >= abs(coef[1]) * m.p.L_v else "carbody_pitch"
    if by + bp > 0.5:
        return "bogie_bounce" if by >= bp else "bogie_pitch"
    return "other"


#: A mode's damped eigenvalue lies within this fraction of its undamped frequency in natural
#: frequency (non-proportional damping moves it a few per cent at a damping ratio of 0.5);
#: the nearest oscillatory eigenvalue further off belongs to another mode. Pioneer R's
#: near-critically damped bogie modes were given the carbody pitch's (0.63 Hz, 0.23).
OVERDAMPED_MATCH = 0.2


def linearise(m: CarModel) -> Modes:
    """Modes of the car linearised about its current state, the held coordinates eliminated."""
    M, K, D = m.mbs.ComputeLinearizedSystem(_settings(), projectIntoConstraintNullspace=False)[:3]
    M, K, D = (np.asarray(a) for a in (M, K, D))
    held = set(m.x_coordinates) | set(m.wheel_y if m.rigid else [])
    keep = np.array([i for i in range(M.shape[0]) if i not in held])
    M, K, D = M[np.ix_(keep, keep)], K[np.ix_(keep, keep)], D[np.ix_(keep, keep)]
    w2, V = scipy.linalg.eigh(K, M)
    f = np.sqrt(np.maximum(w2, 0)) / (2 * np.pi)
    n = M.shape[0]
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 1e-6]
    wn = np.abs(lam)
    zeta = -lam.real / wn
    # match each undamped mode to the damped eigenvalue nearest in natural frequency; a mode
    # with none within OVERDAMPED_MATCH of it is overdamped (its eigenvalues are real): NaN
    fd, zd = np.full_like(f, np.nan), np.full_like(f, np.nan)
    for i, fi in enumerate(f):
        k = int(np.argmin(np.abs(wn / (2 * np.pi) - fi)))
        if abs(wn[k] / (2 * np.pi * fi) - 1) <= OVERDAMPED_MATCH:
            fd[i], zd[i] = lam[k].imag / (2 * np.pi), zeta[k]
    shapes = np.zeros((len(m.mbs.systemData.GetODE2Coordinates()), len(f)))
    shapes[keep] = V
    mass = np.zeros(shapes.shape[0])
    mass[keep] = np.diag(M)
    labels = tuple(_label(m, shapes[:, i], mass) for i in range(len(f)))
    return Modes(f, fd, zd, shapes, labels)


def run_in(inputs: np.ndarray, steps: int) -> np.ndarray:
    """``inputs`` preceded by ``steps`` rows that bring the car from the perfect track it
    settled on to the line's first row (a raised-cosine ramp), so that a journey starts
    without a jump."""
    w = 0.5 * (1 - np.cos(np.pi * np.arange(steps) / steps))
    return np.concatenate([w[:, None] * inputs[:1], inputs])


def simulate(m: CarModel, inputs: np.ndarray, h: float, nodes: dict) -> dict:
    """Integrate from the static equilibrium on a perfect track over ``len(inputs) - 1``
    steps of ``h`` [s]; ``inputs[k]`` holds the eight input values (r_1..r_4 [m],
    m_1..m_4) at t = k h (see :func:`run_in`). ``nodes``: name -> node index; returns
    name -> (coordinates, velocities, accelerations), each an array (steps + 1, node
    coordinates)."""
    mbs = m.mbs
    sensors = {}
    for name, node in nodes.items():
        sensors[name] = [mbs.AddSensor(ei.SensorNode(nodeNumber=node, outputVariableType=ot, storeInternal=True,
                                                     writeToFile=False))
                         for ot in (exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_t,
                                    exu.OutputVariableType.Coordinates_tt)]
    variables = m.inputs
    last = len(inputs) - 1

    def pre_step(mbs_, t):
        # the implicit step ending at t + h evaluates its forces there
        row = inputs[min(int(t / h + 1.5), last)]
        for v, x in zip(variables, row):
            v.SetValue(x)
        return True

    mbs.Assemble()
    settle(m)  # before the pre-step function exists: the static solver calls it too
    mbs.SetPreStepUserFunction(pre_step)
    mbs.SolveDynamic(_settings(h, last))
    out = {}
    for name, ids in sensors.items():
        out[name] = tuple(np.asarray(mbs.GetSensorStoredData(i))[:, 1:] for i in ids)
    return out
