"""Truth simulator for in-service campaigns (the in-service seed's test, sections 3-4).

A 2D car (wheelsets on a rigid rail) runs journeys over one synthetic line
(:mod:`calibration.truth.track`) at speeds that vary within and between journeys; its
exact response (:mod:`calibration.models.simulate`) is measured by the seed's Table 1
sensors on the leading bogie:

* four axle-box accelerometers (wheelsets 1 and 2, left and right), in g;
* a bogie vertical accelerometer mounted ``sensor_offset`` ahead of the bogie centre, so
  it sees pitch as well as bounce, in g (reads +1 g at rest, as accelerometers do);
* a bogie pitch gyrometer in deg/s whose raw output is ``1/gyro_scale`` of the true rate
  (campaign.toml carries ``scale = gyro_scale``, the seed's post-measurement factor),
  with an offset, a slow temperature drift and a speed-independent 77.64 Hz tone picked
  up from the E-TPWS unit it is mounted on (seed section 4);
* distance from 5 Hz GPS fixes (slowly wandering error plus jitter), linearly
  interpolated to the logger's rate, and speed from GPS Doppler.

With ``carbody_sensors`` the carbody carries three floor accelerometers (above each bogie
centre and at the car centre, the EN 12299 ride-comfort positions), in g.

Logger drop-outs leave gaps (rows missing) and short NaN bursts. Everything random comes
from one seeded ``numpy.random.Generator``. Options give test rides at one constant speed
per journey (``constant_speed``) and irregular sampling (``time_jitter``: the logger samples
at jittered instants and records them in the time column).

A hidden effect (:mod:`calibration.truth.effects`) changes the car (:class:`TruthCar`):
its assembly (:class:`calibration.models.car2d.CarExtras`), where the bogie sensors
really sit, or a wheelset's roundness. The effect's details are drawn from a second
generator seeded by ``[seed, 7]``, so the effect-free campaign of a seed is unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.interpolate
import scipy.signal

from .. import checks
from ..data.campaign import CampaignMeta, Prior, Sensor
from ..data.outputs import CampaignWriter, write_json_atomic
from ..data.units import STANDARD_GRAVITY
from ..models.assembly import Assembly, Attachment, Body, SpringDamper
from ..models.car2d import (CarExtras, Output, build_car, damped_modes, frequencies_by_label, state_space,
                            undamped_modes, wheel_level_gain, wheelset_positions)
from ..models.parameters import CarParameters
from ..models.simulate import ModalSimulator
from ..models.vehicles import INTERCITY_TRAILER, SEED_PRIOR_RANGES
from .effects import EffectChoice
from .track import Line, LineSpec

TRUTH_FORMAT = "railcal-truth/1"


@dataclass(frozen=True)
class InServiceSettings:
    """What a synthetic in-service campaign looks like (SI units)."""

    journeys: int = 10
    line: LineSpec = field(default_factory=lambda: LineSpec(length=40_000.0))
    fs: float = 500.0  # [Hz] logger rate (seed section 3)
    speed_range: tuple[float, float] = (20.0, 45.0)  # [m/s]
    vehicle: CarParameters = INTERCITY_TRAILER
    perturb: float = 0.08  # truth parameters drawn within +-perturb of nominal (inside the priors)
    sensor_offset: float = 0.45  # [m] bogie accelerometer/gyro ahead of the bogie centre
    gyro_scale: float = 23.9  # seed section 4
    gyro_tone_hz: float = 77.64  # seed section 4 / Figure 7(a)
    gyro_tone_raw: float = 0.03  # [deg/s] raw amplitude of the tone
    gyro_noise_raw: float = 0.004  # [deg/s] raw rms
    gyro_offset_raw: float = 0.4  # [deg/s] max |offset|
    gyro_drift_raw: float = 0.15  # [deg/s] rms of the slow drift
    bogie_acc_noise: float = 0.03  # [m/s^2] rms
    axle_acc_noise: float = 0.15  # [m/s^2] rms
    gps_error: float = 1.5  # [m] rms of the slowly wandering GPS error
    gps_jitter: float = 0.2  # [m] rms per fix
    gps_rate: float = 5.0  # [Hz]
    speed_noise: float = 0.05  # [m/s] GPS Doppler speed rms
    recording_noise: float = 0.05e-3  # [m] rms of the track recording car's level
    gap_probability: float = 0.5  # per journey: a logger drop-out of 1-4 s
    nan_probability: float = 0.3  # per journey: a 0.2 s NaN burst in one channel
    carbody_sensors: bool = False  # floor accelerometers above the bogies and at the centre
    carbody_acc_noise: float = 0.02  # [m/s^2] rms
    # a test ride: every journey at one speed drawn from speed_range (a narrow range puts
    # them all at nearly the same speed), instead of speed varying along the line
    constant_speed: bool = False
    # [s] the logger samples at t_k + u_k, u_k uniform in +-time_jitter, and records those
    # instants in the time column (irregular sampling, campaign-format.md); drawn from a
    # generator of its own so the campaign is otherwise the one without jitter
    time_jitter: float = 0.0
    chunk: int = 1 << 17

    def __post_init__(self):
        checks.whole(self, "journeys")
        checks.whole(self, "chunk")
        checks.increasing(self, "speed_range", low=0.0)
        if self.speed_range[0] == 0:
            raise ValueError(f"InServiceSettings.speed_range {self.speed_range} must have a low speed > 0")
        checks.positive(self, "fs", "gyro_scale", "gyro_tone_hz", "gps_rate")
        checks.non_negative(self, "perturb", "sensor_offset", "gyro_tone_raw", "gyro_noise_raw", "gyro_offset_raw",
                            "gyro_drift_raw", "bogie_acc_noise", "axle_acc_noise", "gps_error", "gps_jitter",
                            "speed_noise", "recording_noise", "carbody_acc_noise")
        checks.fraction(self, "perturb", "gap_probability", "nan_probability", closed=True)
        if not 0 <= self.time_jitter < 0.5 / self.fs:
            raise ValueError(f"time_jitter {self.time_jitter} s must lie in [0, half a sample interval "
                             f"{0.5 / self.fs} s) so that the time column stays strictly increasing")


# --------------------------------------------------------------------------- sensors
AXLE_BOX_Y = 1.0  # [m] lateral position of the axle boxes
SENSOR_HEIGHT = 0.7  # [m] above rail


def default_sensors(p: CarParameters, settings: InServiceSettings) -> tuple[Sensor, ...]:
    """Seed Table 1 sensors on the leading bogie (bogie 1)."""
    xw = wheelset_positions(p)
    sensors = []
    for j in (0, 1):
        for side, y in (("left", AXLE_BOX_Y), ("right", -AXLE_BOX_Y)):
            sensors.append(Sensor(f"axle{j + 1}_{side}_acc_z", "acceleration", "g", f"axle{j + 1}", "z",
                                  (float(xw[j]), y, 0.45)))
    xs = p.L_v + settings.sensor_offset
    sensors.append(Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (xs, 0.6, SENSOR_HEIGHT)))
    sensors.append(Sensor("bogie1_gyro_pitch", "angular_velocity", "deg/s", "bogie1", "pitch",
                          (xs, 0.6, SENSOR_HEIGHT), settings.gyro_scale))
    if settings.carbody_sensors:
        for where, x in (("front", p.L_v), ("centre", 0.0), ("rear", -p.L_v)):
            sensors.append(Sensor(f"carbody_{where}_acc_z", "acceleration", "g", "carbody", "z",
                                  (x, 0.0, CARBODY_FLOOR_HEIGHT)))
    return tuple(sensors)


# ------------------------------------------------------------------ the car measured
WHEEL_RADIUS = 0.42  # [m] nominal running radius of the truth car's wheels (0.84 m wheels)
CARBODY_FLOOR_HEIGHT = 1.2  # [m] above rail


@dataclass(frozen=True)
class TruthCar:
    """The car a campaign is measured on: the assembly, where each sensor really sits
    (vehicle-frame x; the declared position is campaign.toml's), and an out-of-round wheel
    (``oor``: wheelset index 0-3, polygon order, radius amplitude [m], phase [rad]) or None."""

    parameters: CarParameters
    assembly: Assembly
    sensor_x: dict
    oor: tuple | None = None
    details: dict = field(default_factory=dict)
    level_gain: float = 0.0  # on a flexible track: the wheelsets ride this x their rail level above their coordinate

    def wheel_deviation(self, j: int, s: np.ndarray):
        """Radius deviation of wheelset j at distance s and its first two s-derivatives."""
        if self.oor is None or self.oor[0] != j:
            z = np.zeros_like(s)
            return z, z, z
        _, order, amp, phase = self.oor
        k = order / WHEEL_RADIUS
        arg = k * s + phase
        return amp * np.cos(arg), -amp * k * np.sin(arg), -amp * k * k * np.cos(arg)


def truth_car(p: CarParameters, sensors: tuple[Sensor, ...], effect: EffectChoice | None,
              rng: np.random.Generator) -> TruthCar:
    """Apply ``effect`` (drawing its undetermined details from ``rng``) to the car ``p``."""
    sensor_x = {x.name: float(x.position[0]) for x in sensors}
    name = None if effect is None else effect.spec.name
    mag = None if effect is None else effect.magnitude
    extras, oor, details = CarExtras(), None, {}
    if name == "carbody_bending":
        zeta = float(rng.uniform(0.015, 0.03))
        extras = CarExtras(bending_hz=mag, bending_damping=zeta)
        details = {"bending_hz": mag, "damping_ratio": zeta, "modal_mass_ratio": extras.bending_mass_ratio}
    elif name == "cog_offset":
        sign = float(rng.choice([-1.0, 1.0]))
        extras = CarExtras(cog_offset=sign * mag)
        details = {"cog_x_m": sign * mag}
    elif name == "airspring_reservoir":
        corner = float(rng.uniform(1.5, 4.0))
        extras = CarExtras(reservoir_ratio=mag, reservoir_corner_hz=corner)
        details = {"reservoir_stiffness_n_per_m": mag * p.k_s, "corner_hz": corner,
                   "orifice_damping_n_s_per_m": mag * p.k_s / (2 * np.pi * corner)}
    elif name == "track_flexibility":
        extras = CarExtras(track_stiffness=mag)
        details = {"track_stiffness_n_per_m": mag, "track_mass_kg": extras.track_mass,
                   "damping_ratio": extras.track_damping_ratio,
                   "track_frequency_hz": float(np.sqrt(mag / extras.track_mass) / (2 * np.pi))}
    elif name == "sensor_offset":
        sign = float(rng.choice([-1.0, 1.0]))
        for x in sensors:
            if x.body == "bogie1":
                sensor_x[x.name] += sign * mag
        details = {"x_error_m": sign * mag, "sensors": [x.name for x in sensors if x.body == "bogie1"]}
    elif name == "wheel_out_of_round":
        j, order, phase = int(rng.integers(0, 2)), int(rng.integers(1, 4)), float(rng.uniform(0, 2 * np.pi))
        oor = (j, order, mag, phase)
        details = {"wheelset": j + 1, "order": order, "radius_amplitude_m": mag,
                   "wavelength_m": float(2 * np.pi * WHEEL_RADIUS / order)}
    elif name == "bogie_equipment":
        f_m, zeta, x = float(rng.uniform(20.0, 30.0)), 0.04, p.L_v + 0.6
        k = mag * (2 * np.pi * f_m) ** 2
        extras = CarExtras(bodies=(Body("equipment", mag, x),),
                           elements=(SpringDamper("equipment_mount", Attachment("bogie1", x), Attachment("equipment", x),
                                                  k, 2 * zeta * np.sqrt(k * mag)),))
        details = {"mass_kg": mag, "mount_hz": f_m, "damping_ratio": zeta, "x_m": x}
    elif name is not None:
        raise NotImplementedError(f"effect {name} is not simulated in in-service campaigns")
    return TruthCar(p, build_car(p, extras=extras), sensor_x, oor, details, wheel_level_gain(p, extras))


def draw_truth_parameters(settings: InServiceSettings, rng: np.random.Generator) -> CarParameters:
    """The car the campaign was 'measured' on: nominal values perturbed inside the priors."""
    base = settings.vehicle
    changes = {}
    for name, (lo, hi) in SEED_PRIOR_RANGES.items():
        v = getattr(base, name) * (1 + rng.uniform(-settings.perturb, settings.perturb))
        changes[name] = float(np.clip(v, lo + 0.02 * (hi - lo), hi - 0.02 * (hi - lo)))
    for name in ("c_p", "c_s"):
        changes[name] = getattr(base, name) * rng.uniform(0.85, 1.15)
    return base.replace(**changes)


def campaign_priors(settings: InServiceSettings) -> dict[str, Prior]:
    return {n: Prior(getattr(settings.vehicle, n), lo, hi) for n, (lo, hi) in SEED_PRIOR_RANGES.items()}


# -------------------------------------------------------------------------- journeys
def speed_profile(s: np.ndarray, rng: np.random.Generator, speed_range: tuple[float, float], *,
                  constant: bool = False) -> np.ndarray:
    """Speed [m/s] along distance ``s`` [m]: a cruise speed per journey plus smooth
    variations over kilometres (speed restrictions, gradients), kept inside the range
    with a soft limit so the acceleration stays below about 0.5 m/s^2. With ``constant``
    the cruise speed alone, held over the whole journey."""
    lo, hi = speed_range
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    cruise = rng.uniform(lo + 0.2 * half, hi - 0.2 * half)
    v = np.full_like(s, cruise)
    if constant:
        return v
    for _ in range(6):
        wavelength = rng.uniform(2_000.0, 15_000.0)
        v += rng.uniform(0.5, 2.5) * np.sin(2 * np.pi * s / wavelength + rng.uniform(0, 2 * np.pi))
    # soft limit into (lo, hi)
    return mid + half * np.tanh((v - mid) / half)


def _ou(n: int, dt: float, tau: float, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Ornstein-Uhlenbeck process sampled every dt (exact discretisation)."""
    a = np.exp(-dt / tau)
    e = rng.normal(0.0, sigma * np.sqrt(1 - a * a), n)
    e[0] = rng.normal(0.0, sigma)
    return scipy.signal.lfilter([1.0], [1.0, -a], e)


@dataclass(frozen=True)
class JourneyTruth:
    run_id: str
    mean_speed: float
    min_speed: float
    max_speed: float
    duration: float
    gaps: list
    nan_bursts: list
    gyro_offset_raw: float


def simulate_journey(run_id: str, line: Line, car: TruthCar, sensors: tuple[Sensor, ...],
                     settings: InServiceSettings, rng: np.random.Generator,
                     jitter_rng: np.random.Generator | None = None) -> tuple[dict, JourneyTruth]:
    """One journey over the whole line: returns raw columns (sensor units) and its truth.
    ``jitter_rng`` draws the sample-time jitter when ``settings.time_jitter`` > 0."""
    fs = settings.fs
    p = car.parameters
    xw = wheelset_positions(p)
    s_start = max(0.0, float(xw.max()) - line.s_min + 1.0) if line.s_min > -1 else 0.0
    s_end = line.spec.length
    s_grid = np.arange(s_start, s_end, 1.0)
    v_grid = speed_profile(s_grid, rng, settings.speed_range, constant=settings.constant_speed)
    t_grid = np.concatenate([[0.0], np.cumsum(np.diff(s_grid) / (0.5 * (v_grid[1:] + v_grid[:-1])))])
    n = int(t_grid[-1] * fs)
    t = np.arange(n) / fs
    s = np.interp(t, t_grid, s_grid)
    v = np.interp(s, s_grid, v_grid)
    dvds = np.interp(s, s_grid, np.gradient(v_grid, s_grid))
    acc_train = v * dvds

    flexible = any(b.name.startswith("wheelset") for b in car.assembly.bodies)
    outputs = [Output("bogie1_acc_z", "acceleration", "bogie1", car.sensor_x["bogie1_acc_z"]),
               Output("bogie1_pitch_rate", "pitch_rate", "bogie1")]
    outputs += [Output(x.name, "acceleration", "carbody", car.sensor_x[x.name]) for x in sensors
                if x.body == "carbody"]
    if flexible:
        outputs += [Output(f"wheelset{j + 1}", "acceleration", f"wheelset{j + 1}", float(xw[j])) for j in range(4)]
    index = {o.name: k for k, o in enumerate(outputs)}
    sim = ModalSimulator(state_space(car.assembly, outputs), 1.0 / fs, x0="static")
    y_all = np.empty((n, len(outputs)))
    for a in range(0, n, settings.chunk):
        b = min(n, a + settings.chunk)
        sc, vc = s[a:b], v[a:b]
        w = np.empty((b - a, 8))
        for j in range(4):
            z, dz, _ = line.level(sc + xw[j])
            r, dr, _ = car.wheel_deviation(j, sc)
            w[:, j] = z + r
            w[:, 4 + j] = vc * (dz + dr)
        y_all[a:b] = sim.step_chunk(w)
    t_true, s_m, v_m, acc_m = t, s, v, acc_train  # the instants sampled, where the train was then
    if settings.time_jitter > 0:
        # the motion is simulated on the uniform grid (exact stepping needs one step size)
        # and read at the instants actually sampled by a cubic spline, exact to ~1e-4 of the
        # amplitude up to 50 Hz at 500 Hz; the axle boxes, functions of the rail under the
        # wheel, are evaluated there exactly (a spline would smear the weld impulses)
        jitter_rng = rng if jitter_rng is None else jitter_rng
        t_true = t + jitter_rng.uniform(-settings.time_jitter, settings.time_jitter, n)
        t_true[0], t_true[-1] = t[0], t[-1]  # stay inside the simulated interval
        y_all = scipy.interpolate.CubicSpline(t, y_all, axis=0)(t_true)
        s_m = np.interp(t_true, t_grid, s_grid)
        v_m = np.interp(s_m, s_grid, v_grid)
        acc_m = v_m * np.interp(s_m, s_grid, np.gradient(v_grid, s_grid))
    axle = {x.name: np.empty(n) for x in sensors if x.body.startswith("axle")}
    gain = car.level_gain
    for a in range(0, n, settings.chunk):
        b = min(n, a + settings.chunk)
        sc, vc, ac = s_m[a:b], v_m[a:b], acc_m[a:b]
        for x in sensors:
            if x.body.startswith("axle"):
                j = int(x.body[4:]) - 1
                side = 1 if "left" in x.name else -1
                if flexible:  # the wheelset's own motion, plus the rails' cross level (rigid in roll)
                    _, dz0, d2z0 = line.level(sc + x.position[0])
                    _, dz1, d2z1 = line.level(sc + x.position[0], side=side)
                    _, dr, d2r = car.wheel_deviation(j, sc)
                    # the wheelset's coordinate is its and its track mass's centre; it rides gain x its input above
                    axle[x.name][a:b] = (y_all[a:b, index[f"wheelset{j + 1}"]] + vc * vc * (d2z1 - d2z0)
                                         + ac * (dz1 - dz0) + gain * (vc * vc * (d2z0 + d2r) + ac * (dz0 + dr)))
                else:
                    _, dz, d2z = line.level(sc + x.position[0], side=side)
                    _, dr, d2r = car.wheel_deviation(j, sc)
                    axle[x.name][a:b] = vc * vc * (d2z + d2r) + ac * (dz + dr)
    bogie_acc = y_all[:, index["bogie1_acc_z"]]
    pitch_rate = y_all[:, index["bogie1_pitch_rate"]]

    g = STANDARD_GRAVITY
    cols: dict[str, np.ndarray] = {"time": t_true}
    # GPS: 5 Hz fixes of distance (wandering error + jitter) and Doppler speed
    t_fix = np.arange(0.0, t[-1] + 1.0 / settings.gps_rate, 1.0 / settings.gps_rate)
    s_fix = np.interp(t_fix, t, s) + _ou(t_fix.size, 1 / settings.gps_rate, 30.0, settings.gps_error, rng) \
        + rng.normal(0, settings.gps_jitter, t_fix.size)
    cols["distance"] = np.maximum.accumulate(np.interp(t_true, t_fix, s_fix))
    v_fix = np.interp(t_fix, t, v) + rng.normal(0, settings.speed_noise, t_fix.size)
    cols["speed"] = np.interp(t_true, t_fix, v_fix)
    for x in sensors:
        if x.body.startswith("axle"):
            cols[x.name] = (axle[x.name] + rng.normal(0, settings.axle_acc_noise, n)) / g + 1.0
    cols["bogie1_acc_z"] = (bogie_acc + rng.normal(0, settings.bogie_acc_noise, n)) / g + 1.0
    for x in sensors:
        if x.body == "carbody":
            cols[x.name] = (y_all[:, index[x.name]] + rng.normal(0, settings.carbody_acc_noise, n)) / g + 1.0
    offset = rng.uniform(-settings.gyro_offset_raw, settings.gyro_offset_raw)
    drift = _ou(n, 1 / fs, 600.0, settings.gyro_drift_raw, rng)
    tone = settings.gyro_tone_raw * np.sin(2 * np.pi * settings.gyro_tone_hz * t_true + rng.uniform(0, 2 * np.pi))
    gyro = next(x for x in sensors if x.name == "bogie1_gyro_pitch")
    cols["bogie1_gyro_pitch"] = (np.degrees(pitch_rate) / gyro.scale + offset + drift + tone
                                 + rng.normal(0, settings.gyro_noise_raw, n))

    nan_bursts = []
    if rng.uniform() < settings.nan_probability:
        ch = str(rng.choice([x.name for x in sensors]))
        i0 = int(rng.integers(0, n - int(0.2 * fs)))
        cols[ch][i0:i0 + int(0.2 * fs)] = np.nan
        nan_bursts.append({"channel": ch, "time": float(t_true[i0]), "duration": 0.2})
    keep = np.ones(n, bool)
    gaps = []
    if rng.uniform() < settings.gap_probability:
        i0 = int(rng.integers(int(0.1 * n), int(0.9 * n)))
        length = int(rng.uniform(1.0, 4.0) * fs)
        keep[i0:i0 + length] = False
        gaps.append({"after_time": float(t_true[i0 - 1]), "before_time": float(t_true[min(n - 1, i0 + length)])})
    cols = {k: c[keep] for k, c in cols.items()}
    truth = JourneyTruth(run_id, float(v.mean()), float(v.min()), float(v.max()), float(t[-1]), gaps,
                         nan_bursts, float(offset))
    return cols, truth


# -------------------------------------------------------------------------- campaign
def modal_truth(p: CarParameters) -> dict:
    """Frequencies, damped frequencies and damping ratios by label; of a pair sharing a label
    the lowest mode (the in-phase one, the seed's convention, see ``frequencies_by_label``)."""
    asm = build_car(p)
    damped = damped_modes(asm)
    lowest: dict = {}
    for m in damped:
        if m.label not in lowest or m.frequency_hz < lowest[m.label].frequency_hz:
            lowest[m.label] = m
    return {
        "frequencies_hz": frequencies_by_label(undamped_modes(asm)),
        "damped_frequencies_hz": {k: m.damped_frequency_hz for k, m in lowest.items()},
        "damping_ratios": {k: m.damping_ratio for k, m in lowest.items()},
        "modes": [{"label": m.label, "frequency_hz": m.frequency_hz, "damped_frequency_hz": m.damped_frequency_hz,
                   "damping_ratio": m.damping_ratio} for m in damped],
    }


def synth_in_service(out, *, seed: int = 0, settings: InServiceSettings = InServiceSettings(),
                     effect: EffectChoice | None = None, fmt: str = "csv", overwrite: bool = False,
                     progress=None) -> dict:
    """Write a synthetic in-service campaign to ``out`` and its truth to ``out.truth.json``."""
    out = Path(out)
    rng = np.random.default_rng(seed)
    p = draw_truth_parameters(settings, rng)
    line = Line(settings.line, rng)
    sensors = default_sensors(settings.vehicle, settings)
    car = truth_car(p, sensors, effect, np.random.default_rng([seed, 7]))
    meta = CampaignMeta(
        kind="in_service", name=f"synthetic in-service campaign (seed {seed})",
        vehicle="intercity trailer car (railcal truth simulator)", sensors=sensors, sampling_rate=settings.fs,
        geometry={"bogie_semi_spacing": settings.vehicle.L_v, "semi_wheelbase": settings.vehicle.L_b,
                  "length": 23.0, "width": 2.85, "height": 3.8},
        priors=campaign_priors(settings))
    journeys = []
    jitter_rng = np.random.default_rng([seed, 11])
    with CampaignWriter(out, meta, fmt=fmt, overwrite=overwrite) as w:
        for k in range(settings.journeys):
            run_id = f"journey_{k + 1:03d}"
            cols, jt = simulate_journey(run_id, line, car, sensors, settings, rng, jitter_rng)
            w.write_run(run_id, cols)
            journeys.append(jt.__dict__)
            if progress:
                progress(f"{run_id}: {jt.duration:.0f} s at {jt.mean_speed:.1f} m/s mean")
        # the track recording car's D1 record of one section
        rec_len = min(2_000.0, 0.5 * settings.line.length)
        start = float(rng.uniform(0.1 * settings.line.length, 0.9 * settings.line.length - rec_len))
        d, z = line.recording(start, rec_len, noise=settings.recording_noise, rng=rng)
        w.write_track("trv_d1", d, z, band="D1")
        w.commit()
    truth = {
        "format": TRUTH_FORMAT, "kind": "in_service", "seed": seed, "campaign": out.name,
        "parameters": p.as_dict(), **modal_truth(p),
        "effect": None if effect is None else {**effect.to_json(), "details": car.details},
        "sensors": {"bogie1_gyro_pitch": {"scale_true": settings.gyro_scale, "scale_declared": settings.gyro_scale,
                                          "tone_hz": settings.gyro_tone_hz},
                    "bogie1_acc_z": {"x_offset_from_bogie_m": settings.sensor_offset}},
        "noise_rms_si": {"bogie1_acc_z": settings.bogie_acc_noise, "carbody": settings.carbody_acc_noise,
                         "bogie1_gyro_pitch": float(np.radians(settings.gyro_noise_raw) * settings.gyro_scale),
                         "axle_boxes": settings.axle_acc_noise, "white_up_to_hz": settings.fs / 2,
                         "track_recording_m": settings.recording_noise},
        "non_vehicle_tones_hz": {"bogie1_gyro_pitch": [settings.gyro_tone_hz]},
        "speed_dependent_wavelengths_m": {"sleeper": settings.line.sleeper_spacing,
                                          "rail_panel": settings.line.panel_length},
        "line": {"length_m": settings.line.length, "spectrum": settings.line.spectrum,
                 "track_recording": {"start_m": start, "length_m": rec_len, "band": "D1"}},
        "journeys": journeys,
    }
    write_json_atomic(Path(f"{out}.truth.json"), truth)
    return truth
