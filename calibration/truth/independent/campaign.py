"""``synth_in_service_independent``: an in-service campaign measured on the exudyn car.

Per campaign: one line (:mod:`.irregularity`), the vehicle's damping drawn around the
seed's Table 6 values, sensor gains, tilts and gyro offset drawn once (they belong to the
installation). Per journey: the payload (seed Table 5 ranges) and the floor load's centre,
the levelling valves re-set to them, a speed profile, the simulation and the sensor chain.
The truth (every drawn value, the effect, the clean car's linearised modes) goes to
``<out>.truth.json`` beside the campaign.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ... import checks
from ...data.metadata import CampaignMeta, Prior, Sensor
from ...data.outputs import CampaignWriter, write_json_atomic
from .hidden import HiddenEffect
from .irregularity import Line, LineSpec
from .model import build_car
from .parameters import CarParameters, TrackParameters, car_parameters
from .sensors import G, accelerometer, decimate, hermite, ou, quantise
from .simulate import linearise, run_in, settle, simulate
from .vehicles import VehicleSpec
from .vehicles import vehicle as library_vehicle

TRUTH_FORMAT = "railcal-truth/1"
AXLE_BOX_Y, SENSOR_HEIGHT, FLOOR_HEIGHT = 1.0, 0.7, 1.2  # [m]
#: Changes when a campaign of the same seed and settings would come out different (a kept
#: bench campaign of another revision is made again): 2, the axle boxes' roll term (it had
#: the same sign on both sides, so their mean carried the cross level); 3, a bending's
#: frequency is the carbody beam's own first free-free bending (it was a uniform beam's
#: closed form, 23 % under the beam's); 4, the floor sensors' worst offset is the effect's
#: magnitude (each was drawn within it, so the magnitude bounded the fault's size, not set it).
TRUTH_REVISION = 4
GAUGE = 1.5  # [m] between the rails' contact points: cross level / GAUGE is the roll angle


@dataclass(frozen=True)
class IndependentSettings:
    """What an independently simulated in-service campaign looks like (SI units)."""

    journeys: int = 4
    line: LineSpec = field(default_factory=lambda: LineSpec(length=8_000.0))
    fs: float = 500.0  # [Hz] logger rate (seed section 3)
    sim_rate: float = 1_000.0  # [Hz] simulation rate, a whole multiple of fs
    speed_range: tuple[float, float] = (20.0, 45.0)  # [m/s]
    damping_spread: tuple[float, float] = (0.8, 1.2)  # c_p, c_s drawn as Table 6 x U(spread)
    payload_centre: float = 1.5  # [m] floor payload centre drawn in +-this
    elements: int = 10
    carbody_sensors: bool = False
    sensor_offset: float = 0.45  # [m] bogie sensor block ahead of the bogie centre
    gain_error: float = 0.03  # sensor gains drawn in 1 +- this
    tilt_deg: float = 1.5  # [deg] accelerometer misalignment drawn in +- this
    gyro_offset: float = 0.3  # [deg/s] max |offset|
    gyro_drift: float = 0.1  # [deg/s] rms of the slow drift
    noise: tuple[float, float, float, float] = (0.1, 0.02, 0.01, 0.02)  # axle, bogie, floor [m/s^2], gyro [deg/s]
    gps_error: float = 1.5  # [m] rms of the slowly wandering GPS error
    speed_noise: float = 0.05  # [m/s]
    recording_noise: float = 0.05e-3  # [m]
    run_in: float = 2.0  # [s] simulated before each journey's recording starts
    line_seed: int | None = None  # the line's own seed: campaigns of other seeds over the same line

    def __post_init__(self):
        checks.whole(self, "journeys")
        checks.whole(self, "elements", minimum=4)
        checks.positive(self, "fs", "sim_rate", "run_in")
        checks.increasing(self, "speed_range", low=0.0)
        checks.increasing(self, "damping_spread", low=0.0)
        if self.speed_range[0] <= 0:
            raise ValueError(f"IndependentSettings.speed_range {self.speed_range} must have a low speed > 0")
        k = self.sim_rate / self.fs
        if k < 2 or abs(k - round(k)) > 1e-9:
            raise ValueError(f"IndependentSettings.sim_rate {self.sim_rate} Hz must be a whole multiple (>= 2) of "
                             f"fs {self.fs} Hz")
        checks.non_negative(self, "payload_centre", "sensor_offset", "gain_error", "tilt_deg", "gyro_offset",
                            "gyro_drift", "gps_error", "speed_noise", "recording_noise")
        if len(self.noise) != 4 or min(self.noise) < 0:
            raise ValueError(f"IndependentSettings.noise must be four rms values >= 0, got {self.noise!r}")


def roll_acceleration(y: float, cross_level: np.ndarray, dist: np.ndarray, v: np.ndarray,
                      a_x: np.ndarray) -> np.ndarray:
    """Vertical acceleration [m/s^2] of a point ``y`` [m] left of the wheelset's centre
    from the wheelset's roll as it follows the cross level (left rail minus right rail,
    along ``dist``) at speed ``v`` and longitudinal acceleration ``a_x``: y / GAUGE times
    d^2c/dt^2 = v^2 c'' + a_x c'. Its two axle boxes' mean carries none of it."""
    dc = np.gradient(cross_level, dist, edge_order=1)
    return y / GAUGE * (v ** 2 * np.gradient(dc, dist) + a_x * dc)


def campaign_sensors(spec: VehicleSpec, s: IndependentSettings) -> tuple[Sensor, ...]:
    """The seed's Table 1 sensors on the leading bogie (names as railcal's synthetic campaigns)."""
    xw = (spec.L_v + spec.L_b, spec.L_v - spec.L_b)
    out = [Sensor(f"axle{j + 1}_{side}_acc_z", "acceleration", "g", f"axle{j + 1}", "z", (float(xw[j]), y, 0.45))
           for j in (0, 1) for side, y in (("left", AXLE_BOX_Y), ("right", -AXLE_BOX_Y))]
    xs = spec.L_v + s.sensor_offset
    out.append(Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (xs, 0.6, SENSOR_HEIGHT)))
    out.append(Sensor("bogie1_gyro_pitch", "angular_velocity", "deg/s", "bogie1", "pitch", (xs, 0.6, SENSOR_HEIGHT)))
    if s.carbody_sensors:
        out += [Sensor(f"carbody_{w}_acc_z", "acceleration", "g", "carbody", "z", (x, 0.0, FLOOR_HEIGHT))
                for w, x in (("front", spec.L_v), ("centre", 0.0), ("rear", -spec.L_v))]
    return tuple(out)


def speed_profile(s: np.ndarray, rng: np.random.Generator, speed_range) -> np.ndarray:
    """Speed [m/s] along distance ``s`` [m]: a cruise speed and slow variations over kilometres,
    kept inside the range by a soft limit."""
    lo, hi = speed_range
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    v = np.full_like(s, rng.uniform(lo + 0.2 * half, hi - 0.2 * half))
    for _ in range(5):
        v += rng.uniform(0.5, 2.0) * np.sin(2 * np.pi * s / rng.uniform(2_000.0, 12_000.0) + rng.uniform(0, 6.3))
    return mid + half * np.tanh((v - mid) / half)


def _polygon(rng: np.random.Generator, amplitude: float, radius: float):
    """A polygonal wheel: radius deviation [m] as a function of rolled distance [m]."""
    order = int(rng.integers(1, 4))
    harmonics = [(order, amplitude, rng.uniform(0, 2 * np.pi))]
    harmonics += [(order * k, amplitude * rng.uniform(0.1, 0.4), rng.uniform(0, 2 * np.pi)) for k in (2, 3, 4)]
    return harmonics, (lambda d: sum(a * np.cos(n * d / radius + ph) for n, a, ph in harmonics))


class _Effects:
    """What the hidden effects change, drawn from their own generator."""

    def __init__(self, effects: tuple[HiddenEffect, ...], spec: VehicleSpec, rng: np.random.Generator):
        self.car: dict = {}
        self.bogie_dx = 0.0
        self.floor_dx = {}
        self.polygon = None
        self.load_variation = 0.0
        self.details: dict = {}
        for e in effects:
            d = self._apply(e, spec, rng)
            self.details[e.name] = d

    def _apply(self, e: HiddenEffect, spec: VehicleSpec, rng) -> dict:
        mag = e.magnitude
        if e.name == "carbody_bending":
            self.car["bending_hz"] = mag
            return {"bending_hz_free_free": mag}
        if e.name == "cog_offset":
            x = float(rng.choice([-1.0, 1.0])) * mag
            self.car["structure_centre"] = x
            return {"structure_centre_x_m": x}
        if e.name == "airspring_reservoir":
            corner = float(rng.uniform(1.5, 4.0))
            self.car["reservoir_ratio"] = mag
            self.car["orifice_corner_hz"] = corner
            return {"reservoir_to_bag_volume": mag, "corner_hz_at_10mm_s": corner}
        if e.name == "sensor_offset":
            self.bogie_dx = float(rng.choice([-1.0, 1.0])) * mag
            return {"x_error_m": self.bogie_dx}
        if e.name == "track_flexibility":
            t = TrackParameters()
            k_b = 1.0 / (1.0 / mag - 1.0 / t.k_pad)
            self.car["track"] = TrackParameters(k_b=k_b, c_b=t.c_b * np.sqrt(k_b / t.k_b))
            return {"track_stiffness_n_per_m": mag, "ballast_stiffness_n_per_m": k_b}
        if e.name == "wheel_out_of_round":
            j = int(rng.integers(0, 2))
            harmonics, fn = _polygon(rng, mag, spec.wheel_radius)
            self.polygon = (j, fn)
            return {"wheelset": j + 1, "harmonics": [{"order": n, "amplitude_m": a, "phase": p}
                                                     for n, a, p in harmonics]}
        if e.name == "floor_sensor_offset":
            # the worst-placed sensor (drawn) is MAGNITUDE off, the others anywhere within it: the
            # magnitude is the fault's size, as every other effect's is
            where = ("front", "centre", "rear")
            worst = int(rng.integers(3))
            self.floor_dx = {w: float(mag * rng.choice([-1.0, 1.0]) if i == worst else rng.uniform(-mag, mag))
                             for i, w in enumerate(where)}
            return {"x_error_m": self.floor_dx}
        if e.name == "rigid_equipment":
            x = float(rng.uniform(-spec.L_v, spec.L_v))
            self.car["extra_equipment"] = (("bolted_mass", mag, x, None, 0.0),)
            return {"mass_kg": mag, "x_m": x}
        if e.name == "load_variation":
            self.load_variation = mag
            return {"fraction_of_carbody_mass": mag}
        if e.name == "suspension_friction":
            self.car["secondary_friction"] = mag
            return {"secondary_friction_n_per_bogie": mag}
        raise ValueError(f"effect {e.name} is not simulated by the independent truth")


def _car(spec, s: IndependentSettings, fx: _Effects, payload, centre, c_p, c_s) -> CarParameters:
    kw = {k: v for k, v in fx.car.items() if k != "orifice_corner_hz"}
    p = car_parameters(spec, payload=payload, payload_centre=centre, elements=s.elements, c_p=c_p, c_s=c_s, **kw)
    if "orifice_corner_hz" in fx.car:  # restrict the orifice so the reservoir's transition is in band
        a = p.air
        k_res = a.n * p.air_pressure(0) * a.area ** 2 / a.v_res
        c_eq = k_res / (2 * np.pi * fx.car["orifice_corner_hz"])
        p = p.with_(air=type(a)(a.area, a.n, a.v_bag, a.v_res, c_eq / (8 / (3 * np.pi) * 0.01), 0.1 * c_eq,
                                a.m_pipe))
    return p


def _modes_json(p: CarParameters) -> dict:
    m = build_car(p)
    settle(m)
    by = linearise(m).by_label()
    return {"frequencies_hz": {k: v[0] for k, v in by.items()},
            "damped_frequencies_hz": {k: _finite(v[1]) for k, v in by.items()},
            "damping_ratios": {k: _finite(v[2]) for k, v in by.items()}}


def _finite(x: float) -> float | None:
    """``x``, or None for an overdamped mode's (NaN) damped frequency and damping ratio."""
    return float(x) if np.isfinite(x) else None


def _journey(p: CarParameters, line: Line, s: IndependentSettings, sensors, fx: _Effects, inst: dict,
             rng: np.random.Generator) -> tuple[dict, dict]:
    h = 1.0 / s.sim_rate
    m = build_car(p)
    margin = p.L_v + p.L_b + 1.0
    s_grid = np.arange(margin, s.line.length - margin, 1.0)
    v_grid = speed_profile(s_grid, rng, s.speed_range)
    t_grid = np.concatenate([[0.0], np.cumsum(np.diff(s_grid) / (0.5 * (v_grid[1:] + v_grid[:-1])))])
    n = int(t_grid[-1] * s.sim_rate)
    t = np.arange(n) * h
    dist = np.interp(t, t_grid, s_grid)
    v = np.interp(dist, s_grid, v_grid)
    a_x = v * np.interp(dist, s_grid, np.gradient(v_grid, s_grid))
    inputs = np.empty((n, 8))
    for j, xw in enumerate(m.wheel_x):
        inputs[:, j] = line.level(dist + xw)
        inputs[:, 4 + j] = np.cos(2 * np.pi * (dist + xw) / p.track.sleeper_spacing)
    if fx.polygon is not None:
        j, fn = fx.polygon
        inputs[:, j] += fn(dist)
    k0 = int(s.run_in * s.sim_rate)
    nodes = {"bogie1": m.bogie_nodes[0], "axle1": m.wheel_nodes[0], "axle2": m.wheel_nodes[1]}
    nodes.update({f"beam{i}": nb for i, nb in enumerate(m.beam_nodes)})
    out = simulate(m, run_in(inputs, k0), h, nodes)
    out = {k: tuple(a[k0:k0 + n] for a in vals) for k, vals in out.items()}

    raw: dict = {}
    xb = p.L_v
    for x in sensors:
        if x.body.startswith("axle"):
            j = int(x.body[4:]) - 1
            c = line.cross_level(dist + m.wheel_x[j])
            a_z = out[f"axle{j + 1}"][2][:, 1] + roll_acceleration(x.position[1], c, dist, v, a_x)
            raw[x.name] = accelerometer(a_z, a_x, 0.0, inst["tilt"][x.name]) / G
        elif x.name == "bogie1_acc_z":
            q, _, acc = out["bogie1"]
            d = x.position[0] + fx.bogie_dx - xb
            raw[x.name] = accelerometer(acc[:, 1] + d * acc[:, 2], a_x, -q[:, 2], inst["tilt"][x.name]) / G
        elif x.name == "bogie1_gyro_pitch":
            raw[x.name] = -np.degrees(out["bogie1"][1][:, 2])
        elif x.body == "carbody":
            where = x.name.split("_")[1]
            xs = x.position[0] + fx.floor_dx.get(where, 0.0)
            xn = np.asarray(p.x_nodes)
            ys = [np.column_stack([out[f"beam{i}"][k][:, col] for i in range(len(xn))]) for k, col in
                  ((2, 1), (2, 2), (0, 2))]
            a_z = hermite(xn, ys[0], ys[1], xs)
            theta = -ys[2][:, int(np.argmin(np.abs(xn - xs)))]
            raw[x.name] = accelerometer(a_z, a_x, theta, inst["tilt"][x.name]) / G
    cols: dict = {}
    t_out = t[::int(round(s.sim_rate / s.fs))]
    cols["time"] = t_out
    n_out = t_out.size
    # GPS: 5 Hz fixes of distance (wandering error + jitter) and Doppler speed
    t_fix = np.arange(0.0, t[-1] + 0.2, 0.2)
    s_fix = np.interp(t_fix, t, dist) + ou(t_fix.size, 0.2, 30.0, s.gps_error, rng) + rng.normal(0, 0.2, t_fix.size)
    cols["distance"] = np.maximum.accumulate(np.interp(t_out, t_fix, s_fix))
    cols["speed"] = np.interp(t_out, t_fix, np.interp(t_fix, t, v) + rng.normal(0, s.speed_noise, t_fix.size))
    noise = {"axle": s.noise[0], "bogie1": s.noise[1], "carbody": s.noise[2]}
    for x in sensors:
        y = decimate(raw[x.name], s.sim_rate, s.fs) * inst["gain"][x.name]
        if x.quantity == "angular_velocity":
            y = y + inst["gyro_offset"] + ou(n_out, 1 / s.fs, 600.0, s.gyro_drift, rng) + rng.normal(0, s.noise[3], n_out)
            y = quantise(y, 200.0)
        else:
            key = "axle" if x.body.startswith("axle") else x.body
            y = y + rng.normal(0, noise[key] / G, n_out)
            y = quantise(y, {"axle": 50.0, "bogie1": 15.0, "carbody": 5.0}[key])
        cols[x.name] = y
    info = {"duration_s": float(t[-1]), "mean_speed": float(v.mean()), "min_speed": float(v.min()),
            "max_speed": float(v.max()), "steps": int(n + k0)}
    return cols, info


def synth_in_service_independent(out, *, seed: int = 0, settings: IndependentSettings = IndependentSettings(),
                                 effect: tuple[HiddenEffect, ...] = (), vehicle: str | VehicleSpec = "intercity",
                                 fmt: str = "csv", overwrite: bool = False, progress=None) -> dict:
    """Write an in-service campaign simulated by the independent exudyn truth to ``out`` and
    its truth to ``out.truth.json``; returns the truth."""
    import time
    out = Path(out)
    spec = library_vehicle(vehicle) if isinstance(vehicle, str) else vehicle
    s = settings
    rng = np.random.default_rng(seed)
    fx = _Effects(tuple(effect), spec, np.random.default_rng([seed, 7]))
    line = Line(s.line, rng if s.line_seed is None else np.random.default_rng(s.line_seed))
    c_p = spec.c_p * float(rng.uniform(*s.damping_spread))
    c_s = spec.c_s * float(rng.uniform(*s.damping_spread))
    sensors = campaign_sensors(spec, s)
    inst = {"gain": {x.name: float(1 + rng.uniform(-s.gain_error, s.gain_error)) for x in sensors},
            "tilt": {x.name: float(np.radians(rng.uniform(-s.tilt_deg, s.tilt_deg))) for x in sensors},
            "gyro_offset": float(rng.uniform(-s.gyro_offset, s.gyro_offset))}
    clean = car_parameters(spec, elements=s.elements, c_p=c_p, c_s=c_s)
    M_clean, _ = clean.carbody_mass()
    priors = {"m_v": Prior(M_clean, 0.9 * M_clean, 1.1 * M_clean),
              "J_v": Prior(clean.carbody_pitch_inertia(), 0.7 * clean.carbody_pitch_inertia(),
                           1.3 * clean.carbody_pitch_inertia()),
              "m_b": Prior(spec.m_b[0], 0.9 * spec.m_b[0], 1.25 * spec.m_b[0]),
              "J_b": Prior(spec.J_b, 0.7 * spec.J_b, 1.3 * spec.J_b),
              "k_p": Prior(spec.k_p, 0.92 * spec.k_p, 1.25 * spec.k_p),
              "k_s": Prior(spec.k_s, 0.75 * spec.k_s, 1.5 * spec.k_s),
              # what a user has from the data sheets: the dampers' and wheelsets' published values (the
              # dampers drawn around them), so that no diagnosis falls back on another car's
              "c_p": Prior(spec.c_p, 0.6 * spec.c_p, 1.5 * spec.c_p),
              "c_s": Prior(spec.c_s, 0.6 * spec.c_s, 1.5 * spec.c_s),
              "m_w": Prior(spec.m_w, 0.95 * spec.m_w, 1.05 * spec.m_w)}
    meta = CampaignMeta(kind="in_service", name=f"independent exudyn truth, {spec.name} (seed {seed})",
                        vehicle=f"{spec.name} (independent exudyn truth)", sensors=sensors, sampling_rate=s.fs,
                        geometry={"bogie_semi_spacing": spec.L_v, "semi_wheelbase": spec.L_b, "length": spec.length},
                        priors=priors)
    journeys = []
    t0 = time.perf_counter()
    simulated = 0.0
    with CampaignWriter(out, meta, fmt=fmt, overwrite=overwrite) as w:
        for k in range(s.journeys):
            payload = {pl.name: pl.capacity * float(rng.uniform(*pl.fill)) for pl in spec.payloads}
            if fx.load_variation and spec.payloads:
                extra = fx.load_variation * M_clean * float(rng.uniform(-1, 1))
                first = spec.payloads[0].name
                payload[first] = max(0.0, payload[first] + extra)
            centre = float(rng.uniform(-s.payload_centre, s.payload_centre))
            p = _car(spec, s, fx, payload, centre, c_p, c_s)
            run_id = f"journey_{k + 1:03d}"
            cols, info = _journey(p, line, s, sensors, fx, inst, rng)
            w.write_run(run_id, cols)
            simulated += info["duration_s"]
            M, xg = p.carbody_mass()
            journeys.append({"run_id": run_id, **info, "payload_kg": payload, "floor_payload_centre_m": centre,
                             "carbody_mass_kg": M, "carbody_cog_x_m": xg,
                             "air_pressure_pa": [p.air_pressure(0), p.air_pressure(1)]})
            if progress:
                progress(f"{run_id}: {info['duration_s']:.0f} s at {info['mean_speed']:.1f} m/s mean")
        rec_len = min(2_000.0, 0.5 * s.line.length)
        start = float(rng.uniform(0.1 * s.line.length, 0.9 * s.line.length - rec_len))
        d, z = line.recording(start, rec_len, noise=s.recording_noise, rng=rng)
        w.write_track("trv_d1", d, z, band="D1")
        w.commit()
    wall = time.perf_counter() - t0
    nominal = _car(spec, s, _Effects((), spec, np.random.default_rng(0)), None, 0.0, c_p, c_s)
    truth = {
        "format": TRUTH_FORMAT, "kind": "in_service", "simulator": "independent exudyn truth",
        "revision": TRUTH_REVISION, "seed": seed,
        "campaign": out.name, "vehicle": {"name": spec.name, "reference": spec.reference, "notes": spec.notes},
        **_modes_json(nominal),
        "rigid_frequencies_hz": {k: v[0] for k, v in _rigid(nominal).items()},
        "parameters": {"c_p": c_p, "c_s": c_s, "k_p": spec.k_p, "k_s_nominal": spec.k_s, "m_b": list(spec.m_b),
                       "J_b": spec.J_b, "m_w": spec.m_w, "L_v": spec.L_v, "L_b": spec.L_b,
                       "carbody_mass_nominal": nominal.carbody_mass()[0],
                       "carbody_pitch_inertia_nominal": nominal.carbody_pitch_inertia(), "EI": nominal.EI,
                       "track": nominal.track.__dict__, "air_spring": nominal.air.__dict__},
        "effect": [{**e.to_json(), "details": fx.details[e.name]} for e in effect] or None,
        "sensors": {"gain": inst["gain"], "tilt_rad": inst["tilt"], "gyro_offset_deg_s": inst["gyro_offset"],
                    "bogie1_x_offset_from_bogie_m": s.sensor_offset + fx.bogie_dx},
        "noise_rms_si": {"axle_boxes": s.noise[0], "bogie1_acc_z": s.noise[1], "carbody": s.noise[2],
                         "bogie1_gyro_pitch": float(np.radians(s.noise[3]))},
        "speed_dependent_wavelengths_m": {"sleeper": s.line.sleeper_spacing, "rail_panel": s.line.panel_length},
        "line": {**_line_json(s.line), "seed": s.line_seed,
                 "track_recording": {"start_m": start, "length_m": rec_len, "band": "D1"}},
        "performance": {"simulated_s": simulated, "wall_s": wall, "real_time_factor": simulated / wall},
        "journeys": journeys,
    }
    write_json_atomic(Path(f"{out}.truth.json"), truth)
    return truth


def _line_json(spec: LineSpec) -> dict:
    """The line's whole spec [SI], enough with the seed to draw its line again (:func:`truth_line`)."""
    return {"length_m": spec.length, "spectrum": spec.spectrum, "sleeper_spacing": spec.sleeper_spacing,
            "panel_length": spec.panel_length, "weld_depth": list(spec.weld_depth), "dx": spec.dx,
            "dips": [{"centre_m": c, "depth_m": d, "length_m": n} for c, d, n in spec.dips]}


def truth_line(truth: dict) -> Line:
    """The line a campaign's journeys ran over, drawn again from its truth (``out.truth.json``
    as read by ``json.load``): its seed and line spec. The line is the first draw of the
    campaign's generator (or of its own, with a line seed), so nothing else of the campaign is needed."""
    if truth.get("simulator") != "independent exudyn truth" or truth.get("kind") != "in_service":
        raise ValueError("truth_line takes the truth of an in-service campaign of the independent exudyn truth, "
                         f"got simulator {truth.get('simulator')!r}, kind {truth.get('kind')!r}")
    j = truth["line"]
    missing = [k for k in ("sleeper_spacing", "panel_length", "weld_depth", "dx", "dips") if k not in j]
    if missing:
        raise ValueError(f"the truth's line has no {', '.join(missing)}: it does not hold the whole line spec, so its "
                         "line cannot be drawn again; synthesise the campaign again")
    spec = LineSpec(length=j["length_m"], spectrum=j["spectrum"], sleeper_spacing=j["sleeper_spacing"],
                    panel_length=j["panel_length"], weld_depth=tuple(j["weld_depth"]), dx=j["dx"],
                    dips=tuple((d["centre_m"], d["depth_m"], d["length_m"]) for d in j["dips"]))
    seed = j.get("seed")
    return Line(spec, np.random.default_rng(truth["seed"] if seed is None else seed))


def _rigid(p: CarParameters) -> dict:
    """The seed's 2D model's modes of car ``p``: stiff carbody, wheelsets on a rigid rail."""
    m = build_car(p, stiff_carbody=True, rigid_track=True)
    settle(m)
    return {k: v for k, v in linearise(m).by_label().items() if k != "carbody_bending"}
