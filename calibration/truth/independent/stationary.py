"""``synth_excitation_independent``: a stationary excitation test measured on the independent
truth's shell carbody (:mod:`.shell_car`, :mod:`.stationary_model`), integrated by exudyn.

The test is the seed's section 3.2: the car stands on the rails, an exciter on the ground
pushes the floor up with a band-random force flat in 5-50 Hz, a load cell measures the
force and floor accelerometers the vertical response; 200 Hz logging behind 80 Hz
anti-alias filters. The sensor layout is this module's: nine stations every 2.8 m on three
lines (y = 1.2, 0, -1.2 m), the exciter off every symmetry line at (5.6, 0.8) m.

Per campaign, from ``default_rng(seed)``: each panel group's membrane and bending rigidity x
a lognormal factor (sigma 0.15, clipped to 0.6-1.6); each elastic mode's damping ratio in
1-3 %; per sensor a gain (accelerometers within 2 %, the load cell within 0.5 %), an offset and
its noise. A hidden effect's details come from ``default_rng([seed, 11])``.

exudyn integrates the assembled linear system (an ``ObjectGenericODE2``, the exciter's
force as its force function) with the implicit generalized-alpha method at 2 kHz. The
system is linear, so the truth is also its exact accelerance (:meth:`.LinearSystem.frf`);
the integration's own error against it is measured by a test. Why not exudyn's floating
frame body: with 60 modes its ``ObjectFFRFreducedOrder`` ran at a real-time factor of 0.6
(measured), and the test needs 160.

The truth file lists the system's poles in 3-25 Hz (|s| / 2 pi, -Re s / |s|), the carbody's
free-free modes, the drawn factors, gains and the effect.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass
from pathlib import Path

import exudyn as exu
import exudyn.itemInterface as ei
import numpy as np

from ...data.metadata import CampaignMeta, Excitation, Sensor
from ...data.outputs import CampaignWriter, write_json_atomic
from .campaign import TRUTH_FORMAT
from .hidden import HiddenEffect
from .sensors import decimate, quantise
from .shell_car import ShellCar, mesh, region
from .stationary_model import Bracket, CarbodyModes, LinearSystem, Mounted, assemble, carbody_modes

EFFECT_STREAM = 11
GROUPS = ("roof", "floor", "side", "end")
SOFTENING_REGIONS = ("roof", "floor_front", "floor_middle", "floor_rear")
EQUIPMENT_BAND = (8.0, 20.0)  # [Hz] elastic modes a mount may be tuned to
EQUIPMENT_DETUNING = 0.04
EQUIPMENT_DAMPING = 0.05


@dataclass(frozen=True)
class StationarySettings:
    """What an independently simulated stationary excitation test looks like (SI units)."""

    runs: int = 2
    duration: float = 600.0  # [s] total recording, split over the runs
    fs: float = 200.0  # [Hz] logger rate (seed section 3.2)
    sim_rate: float = 1000.0  # [Hz] integration and analogue rate, a whole multiple of fs
    band: tuple[float, float] = (5.0, 50.0)  # [Hz] the force's flat band (seed section 3.2)
    force_rms: float = 500.0  # [N]
    pre_roll: float = 10.0  # [s] excitation before each run's record
    max_mode_hz: float = 80.0  # with the attachment mode, the drive point's accelerance to 50 Hz
    elastic_damping: tuple[float, float] = (0.01, 0.03)
    factor_sigma: float = 0.15
    factor_clip: tuple[float, float] = (0.6, 1.6)
    acc_gain_error: float = 0.02
    force_gain_error: float = 0.005
    acc_noise: float = 0.002  # [m/s^2] rms, white to sim_rate / 2
    force_noise: float = 1.0  # [N] rms
    acc_offset: float = 0.005  # [m/s^2]
    force_offset: float = 2.0  # [N]
    acc_full_scale: float = 20.0  # [m/s^2] 16-bit
    force_full_scale: float = 5000.0  # [N]
    truth_band_hz: tuple[float, float] = (3.0, 25.0)

    def __post_init__(self):
        if self.runs < 1 or not self.duration / self.runs >= 20.0:
            raise ValueError(f"need runs >= 1 of 20 s or more, got {self.runs} over {self.duration} s")
        k = self.sim_rate / self.fs
        if abs(k - round(k)) > 1e-9 or k < 2:
            raise ValueError(f"sim_rate {self.sim_rate} Hz must be a whole multiple (>= 2) of fs {self.fs} Hz")


def sensor_layout(car: ShellCar) -> tuple[tuple[Sensor, ...], Sensor]:
    """The floor accelerometers (station-major, front first) and the exciter."""
    acc = tuple(Sensor(f"acc_f{i + 1:02d}_{line}", "acceleration", "m/s^2", "floor", "z",
                       (round(11.2 - 2.8 * i, 6), y, car.floor_z))
                for i in range(9) for line, y in (("l", 1.2), ("c", 0.0), ("r", -1.2)))
    return acc, Sensor("exciter_force", "force", "N", "floor", "z", (5.6, 0.8, car.floor_z))


def band_force(n: int, fs: float, band, rms: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian force flat in ``band`` [Hz], none outside, scaled to ``rms`` (FFT synthesis)."""
    spec = np.fft.rfft(rng.standard_normal(n))
    nu = np.fft.rfftfreq(n, 1 / fs)
    spec[(nu < band[0]) | (nu > band[1])] = 0.0
    x = np.fft.irfft(spec, n)
    return x * (rms / x.std())


def integrate(system: LinearSystem, force: np.ndarray, rate: float) -> np.ndarray:
    """Sensor accelerations (n, n_sensors) of ``system`` from rest under ``force`` sampled at
    ``rate`` [Hz] (linear between samples), by exudyn's generalized-alpha integrator."""
    n = system.M.shape[0]
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    node = mbs.AddNode(ei.NodeGenericODE2(numberOfODE2Coordinates=n, referenceCoordinates=[0.0] * n,
                                          initialCoordinates=[0.0] * n, initialCoordinates_t=[0.0] * n))
    b = system.b
    last = force.size - 1

    def load(mbs_, t, item, q, q_t):
        k = t * rate
        i = min(int(k), last - 1)
        a = k - i
        return b * ((1 - a) * force[i] + a * force[i + 1])

    mats = [exu.MatrixContainer(), exu.MatrixContainer(), exu.MatrixContainer()]
    for mc, A in zip(mats, (system.M, system.K, system.C)):
        mc.SetWithDenseMatrix(A, useDenseMatrix=True)
    mbs.AddObject(ei.ObjectGenericODE2(nodeNumbers=[node], massMatrix=mats[0], stiffnessMatrix=mats[1],
                                       dampingMatrix=mats[2], forceUserFunction=load))
    sensors = [mbs.AddSensor(ei.SensorNode(nodeNumber=node, outputVariableType=ot, storeInternal=True,
                                           writeToFile=False))
               for ot in (exu.OutputVariableType.Coordinates, exu.OutputVariableType.Coordinates_t)]
    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = 1 / rate
    ss.timeIntegration.numberOfSteps = last
    ss.timeIntegration.endTime = last / rate
    ss.timeIntegration.verboseMode = 0
    ss.timeIntegration.newton.useModifiedNewton = True
    ss.timeIntegration.generalizedAlpha.spectralRadius = 0.9
    ss.linearSolver.solverType = exu.LinearSolverType.EXUdense
    ss.show.statistics = False
    ss.show.computationTime = False
    mbs.SolveDynamic(ss)
    q, qt = (_on_grid(np.asarray(mbs.GetSensorStoredData(x)), rate, last + 1) for x in sensors)
    # the accelerations the equations of motion give at the integrated state, not the
    # generalized-alpha method's algorithmic ones (which lag: +3 % at a resonance, measured)
    rhs = np.outer(force[:q.shape[0]], system.b) - qt @ system.C.T - q @ system.K.T
    return np.linalg.solve(system.M, rhs.T).T @ system.S.T


def _on_grid(data: np.ndarray, rate: float, n: int) -> np.ndarray:
    """A sensor's stored rows (time first) on the grid k / rate, k < n: the write period's
    round-off can store one instant twice (a 310 s run gave one row too many)."""
    k = np.round(data[:, 0] * rate).astype(int)
    _, first = np.unique(k, return_index=True)
    rows = data[first]
    if rows.shape[0] < n or not np.array_equal(np.round(rows[:n, 0] * rate).astype(int), np.arange(n)):
        raise RuntimeError(f"exudyn stored {rows.shape[0]} distinct instants, not the {n} of the time grid")
    return rows[:n, 1:]


def _factors(s: StationarySettings, rng: np.random.Generator) -> dict:
    names = [f"{g}_{k}" for g in GROUPS for k in ("membrane", "bending")]
    f = np.clip(np.exp(rng.normal(0.0, s.factor_sigma, len(names))), *s.factor_clip)
    return {n: float(v) for n, v in zip(names, f)}


def _tuned_mount(m: CarbodyModes, node_ids, lo_hi, rng) -> tuple[int, float]:
    """The elastic mode in ``lo_hi`` [Hz] that moves the mount patch most vertically, and
    the mount frequency tuned to it (within EQUIPMENT_DETUNING)."""
    z = np.abs(m.at(node_ids)[2])
    ok = (np.array(m.kind) == "elastic") & (m.frequency_hz >= lo_hi[0]) & (m.frequency_hz <= lo_hi[1])
    k = int(np.flatnonzero(ok)[np.argmax(z[ok])])
    return k, float(m.frequency_hz[k] * (1 + rng.uniform(-EQUIPMENT_DETUNING, EQUIPMENT_DETUNING)))


def _chain(x: np.ndarray, gain: float, noise: float, offset: float, full_scale: float, s: StationarySettings,
           rng: np.random.Generator) -> np.ndarray:
    y = gain * x + noise * rng.standard_normal(x.size) + offset
    return quantise(decimate(y, s.sim_rate, s.fs), full_scale)


def sensor_chain(names: list[str], exciter: str, s: StationarySettings, rng: np.random.Generator,
                 effect: HiddenEffect | None = None) -> tuple[dict[str, float], dict[str, float]]:
    """Each sensor's gain and offset, drawn from ``rng``. A hidden ``force_calibration``
    multiplies the load cell's drawn gain after the draws, so that the campaign is the clean
    one's of the same seed but for its force column."""
    gains = {n: float(1 + rng.uniform(-s.acc_gain_error, s.acc_gain_error)) for n in names}
    gains[exciter] = float(1 + rng.uniform(-s.force_gain_error, s.force_gain_error))
    offsets = {n: float(rng.uniform(-s.acc_offset, s.acc_offset)) for n in names}
    offsets[exciter] = float(rng.uniform(-s.force_offset, s.force_offset))
    if effect is not None and effect.name == "force_calibration":
        gains[exciter] *= effect.magnitude
    return gains, offsets


def synth_excitation_independent(out, *, seed: int = 0, settings: StationarySettings = StationarySettings(),
                                 effect: tuple[HiddenEffect, ...] = (), fmt: str = "csv", overwrite: bool = False,
                                 car: ShellCar = ShellCar(), progress=None) -> dict:
    """Write a stationary excitation campaign of the independent truth to ``out`` and its
    truth to ``out.truth.json``; returns the truth."""
    t0 = time.perf_counter()
    out, s = Path(out), settings
    say = progress or (lambda msg: None)
    if len(effect) > 1:
        raise ValueError("the stationary truth hides one effect at a time")
    e = effect[0] if effect else None
    rng = np.random.default_rng(seed)
    erng = np.random.default_rng([seed, EFFECT_STREAM])
    accs, exciter = sensor_layout(car)
    factors = _factors(s, rng)
    details: dict = {}
    softened, bolted, bracket = None, (), None
    if e is not None and e.name == "local_panel_softening":
        name = SOFTENING_REGIONS[int(erng.integers(len(SOFTENING_REGIONS)))]
        softened = (name, e.magnitude)
        details = {"region": name, "group": region(car, name)[0], "x_range_m": list(region(car, name)[1])}
    elif e is not None and e.name == "rigid_equipment":
        x, y = float(erng.uniform(-7.0, 7.0)), float(0.8 * erng.choice([-1.0, 1.0]))
        bolted = ((round(x / car.step_x) * car.step_x, y, e.magnitude),)
        details = {"x_m": bolted[0][0], "y_m": y}
    say("meshing the shell carbody and solving its modes")
    shell = mesh(car, factors, softened, bolted)
    node = {a.name: shell.node_at(a.position) for a in accs}
    ex_node = shell.node_at(exciter.position)
    modes = carbody_modes(shell, s.max_mode_hz, ex_node)
    damping = np.where(np.array(modes.kind) == "rigid", 0.0,
                       rng.uniform(*s.elastic_damping, modes.frequency_hz.size))
    mounted = None
    if e is not None and e.name == "underfloor_equipment":
        x = float(round(erng.uniform(-7.0, 7.0) / car.step_x) * car.step_x)
        y = float(0.8 * erng.choice([-1.0, 1.0]))
        patch = shell.node_at((x, y, car.floor_z))
        k, f_mount = _tuned_mount(modes, [patch], EQUIPMENT_BAND, erng)
        mounted = Mounted(e.magnitude * float(shell.mass.sum()), x, y, f_mount, EQUIPMENT_DAMPING)
        details = {**asdict(mounted), "tuned_mode_hz": float(modes.frequency_hz[k]),
                   "carbody_mass_kg": float(shell.mass.sum())}
    elif e is not None and e.name == "sensor_bracket":
        far = [a.name for a in accs if np.hypot(a.position[0] - exciter.position[0],
                                                 a.position[1] - exciter.position[1]) >= 2.0]
        bracket = Bracket(far[int(erng.integers(len(far)))], e.magnitude, float(erng.uniform(0.03, 0.06)))
        details = asdict(bracket)
    system = assemble(car, shell, modes, damping, node, ex_node, mounted, bracket)
    names = [a.name for a in accs]
    gains, offsets = sensor_chain(names, exciter.name, s, rng, e)
    if e is not None and e.name == "force_calibration":
        details = {"sensor": exciter.name, "force_gain": e.magnitude, "with_tolerance": gains[exciter.name]}
    meta = CampaignMeta(
        kind="stationary_excitation", name=f"independent exudyn truth, stationary excitation test (seed {seed})",
        vehicle="Shinkansen-type test vehicle (independent truth: shell finite elements, exudyn)",
        sensors=(exciter,) + accs, sampling_rate=s.fs,
        geometry={"bogie_semi_spacing": car.bogie_x, "semi_wheelbase": car.semi_wheelbase, "length": car.length,
                  "width": car.width, "height": car.roof_z,
                  "windowed_length": car.window_x[1] - car.window_x[0]},
        excitation=Excitation(exciter.name, exciter.position))
    runs = []
    simulated, sim_wall = 0.0, 0.0
    step = round(s.sim_rate / s.fs)
    n_pre = round(s.pre_roll * s.fs) * step
    n_out = round(s.duration / s.runs * s.fs)
    with CampaignWriter(out, meta, fmt=fmt, overwrite=overwrite) as w:
        for r in range(s.runs):
            n = n_pre + n_out * step
            force = band_force(n + 1, s.sim_rate, s.band, s.force_rms, rng)
            t1 = time.perf_counter()
            acc = integrate(system, force, s.sim_rate)
            sim_wall += time.perf_counter() - t1
            simulated += n / s.sim_rate
            cols = {"time": np.arange(n_out) / s.fs}
            f = _chain(force[:acc.shape[0]], gains[exciter.name], s.force_noise, offsets[exciter.name],
                       s.force_full_scale, s, rng)
            cols[exciter.name] = f[n_pre // step:][:n_out]
            for j, name in enumerate(names):
                y = _chain(acc[:, j], gains[name], s.acc_noise, offsets[name], s.acc_full_scale, s, rng)
                cols[name] = y[n_pre // step:][:n_out]
            run_id = f"run_{r + 1:03d}"
            w.write_run(run_id, cols)
            runs.append({"run_id": run_id, "duration_s": n_out / s.fs, "force_rms_n": float(force.std())})
            say(f"{run_id}: {n_out / s.fs:g} s, force {force.std():.0f} N rms")
        w.commit()
    f_pole, zeta = system.poles()
    lo, hi = s.truth_band_hz
    listed = np.flatnonzero((f_pole >= lo) & (f_pole <= hi))
    truth = {
        "format": TRUTH_FORMAT, "kind": "stationary_excitation", "truth": "exudyn", "seed": seed,
        "campaign": out.name, "model": "shell finite elements (independent)",
        "frequencies_hz": {f"pole_{i + 1:02d}": float(f_pole[k]) for i, k in enumerate(listed)},
        "damping_ratios": {f"pole_{i + 1:02d}": float(zeta[k]) for i, k in enumerate(listed)},
        "carbody_free_free_hz": [float(x) for x, kd in zip(modes.frequency_hz, modes.kind) if kd == "elastic"
                                 and x <= hi],
        "carbody_mass_kg": float(shell.mass.sum()), "rigidity_factors": factors, "gains": gains,
        "offsets": offsets, "sensors": names, "exciter": {"sensor": exciter.name, "position": list(exciter.position)},
        "effect": None if e is None else {**e.to_json(), **details},
        "settings": asdict(s), "runs": runs,
        "performance": {"simulated_s": simulated, "integration_wall_s": sim_wall,
                        "real_time_factor": simulated / max(sim_wall, 1e-9), "wall_s": time.perf_counter() - t0},
    }
    write_json_atomic(Path(f"{out}.truth.json"), truth)
    return truth
