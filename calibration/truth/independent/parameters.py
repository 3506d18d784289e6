"""The numbers one simulated car is built from (:class:`CarParameters`), made from a library
vehicle (:mod:`.vehicles`), a journey's payload and the drawn damping and track.

Everything here is SI. Masses along the carbody are per beam element; the static forces in
every suspension element follow from the masses by statics (two bogies carry a carbody,
two wheelsets a bogie: both statically determinate), so the model starts at its
equilibrium with the air springs at their levelled height.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ... import checks
from .components import bending_stiffness_for, hertz_constant, volume_for_stiffness
from .vehicles import VehicleSpec

GRAVITY = 9.81  # [m/s^2]


@dataclass(frozen=True)
class TrackParameters:
    """Track under one wheelset (both rails): rail mass m_r [kg] on pads (k_pad [N/m],
    c_pad [N s/m]) on sleeper mass m_s [kg] on ballast (k_b, c_b); the pad stiffness
    varies by +-``modulation`` at the sleeper-passing wavelength ``sleeper_spacing`` [m]."""

    m_r: float = 150.0
    k_pad: float = 6.0e8
    c_pad: float = 1.0e5
    m_s: float = 800.0
    k_b: float = 2.0e8
    c_b: float = 2.5e5
    modulation: float = 0.05
    sleeper_spacing: float = 0.7

    def __post_init__(self):
        checks.positive(self, "m_r", "k_pad", "m_s", "k_b", "sleeper_spacing")
        checks.non_negative(self, "c_pad", "c_b")
        checks.fraction(self, "modulation")


@dataclass(frozen=True)
class AirSpring:
    """The two air springs of a bogie lumped: effective area [m^2], polytropic index,
    bag and reservoir volumes [m^3], orifice damping (quadratic [N s^2/m^2], linear
    [N s/m]) and the pipe's air mass [kg]."""

    area: float
    n: float
    v_bag: float
    v_res: float
    c_quadratic: float
    c_linear: float
    m_pipe: float

    def __post_init__(self):
        checks.positive(self, "area", "n", "v_bag", "v_res", "m_pipe")
        checks.non_negative(self, "c_quadratic", "c_linear")


@dataclass(frozen=True)
class CarParameters:
    """One simulated car (one journey). Beam: ``x_nodes`` [m], ``mu`` [kg/m] per element,
    ``EI`` [N m^2]; ``equipment`` as (name, mass [kg], x [m], mount_hz or None, damping
    ratio); bogie 1 leads at x = +L_v."""

    x_nodes: tuple
    mu: tuple
    EI: float
    bending_damping_ratio: float
    equipment: tuple
    m_b: tuple
    J_b: float
    m_w: float
    k_p: float
    c_p: float
    c_p_high_ratio: float
    v_knee: float
    k_s: float  # quasi-static air-spring stiffness per bogie at the nominal load [N/m]
    c_s: float
    air: AirSpring
    L_v: float
    L_b: float
    wheel_radius: float
    track: TrackParameters = field(default_factory=TrackParameters)
    secondary_friction: float = 0.0  # dry friction across each bogie's air springs [N] (a fault)

    def __post_init__(self):
        checks.positive(self, "EI", "J_b", "m_w", "k_p", "k_s", "L_v", "L_b", "wheel_radius", "v_knee")
        checks.non_negative(self, "c_p", "c_s", "bending_damping_ratio", "secondary_friction")
        checks.fraction(self, "c_p_high_ratio", closed=True)
        if len(self.mu) != len(self.x_nodes) - 1 or min(self.mu) < 0:
            raise ValueError("CarParameters.mu must give a non-negative mass per length for each beam element")

    # ------------------------------------------------------------------ statics
    def carbody_mass(self) -> tuple[float, float]:
        """Total carbody mass [kg] (beam and equipment) and its centre x [m]."""
        x = np.asarray(self.x_nodes)
        le = np.diff(x)
        xm = 0.5 * (x[1:] + x[:-1])
        m = np.asarray(self.mu) * le
        masses = np.concatenate([m, [e[1] for e in self.equipment]])
        xs = np.concatenate([xm, [e[2] for e in self.equipment]])
        return float(masses.sum()), float((masses * xs).sum() / masses.sum())

    def carbody_pitch_inertia(self) -> float:
        """Pitch inertia [kg m^2] of the carbody about its centre of mass (elements as slender rods)."""
        x = np.asarray(self.x_nodes)
        le = np.diff(x)
        xm = 0.5 * (x[1:] + x[:-1])
        m = np.asarray(self.mu) * le
        M, xg = self.carbody_mass()
        J = float((m * ((xm - xg) ** 2 + le ** 2 / 12)).sum())
        return J + sum(e[1] * (e[2] - xg) ** 2 for e in self.equipment)

    def bogie_loads(self) -> tuple[float, float]:
        """Static secondary forces [N] on bogie 1 (x = +L_v) and bogie 2 (x = -L_v)."""
        M, xg = self.carbody_mass()
        W = M * GRAVITY
        return W * (self.L_v + xg) / (2 * self.L_v), W * (self.L_v - xg) / (2 * self.L_v)

    def air_pressure(self, bogie: int) -> float:
        """Absolute pressure [Pa] the levelling valve sets in bogie ``bogie``'s (0, 1) springs."""
        from .components import levelled_pressure
        return levelled_pressure(self.bogie_loads()[bogie], self.air.area)

    def hertz_G(self) -> float:
        return hertz_constant(self.wheel_radius)

    def with_(self, **changes) -> "CarParameters":
        return replace(self, **changes)


def beam_mesh(spec: VehicleSpec, elements: int) -> np.ndarray:
    """Node positions [m]: uniform, the nodes nearest +-L_v and 0 moved onto them (the air
    springs act at nodes; the centre carries the longitudinal restraint)."""
    x = np.linspace(-spec.length / 2, spec.length / 2, elements + 1)
    for target in (-spec.L_v, 0.0, spec.L_v):
        x[np.argmin(np.abs(x - target))] = target
    return x


def mass_shape(spec: VehicleSpec, elements: int) -> float:
    """The shape factor beta of the structure's mass per length m/L (1 + beta (12 x^2/L^2 - 1))
    that gives the nominal carbody the pitch inertia ``spec.J_v``, within [-0.5, 1] (non-negative mass)."""
    L, m = spec.length, spec.m_structure
    nominal = spec.nominal_payload()
    eq = [(e.mass + sum(nominal[p.name] for p in spec.payloads if p.where == e.name), e.x) for e in spec.equipment]
    floor = sum(nominal[p.name] for p in spec.payloads if p.where == "floor")
    J_rest = sum(me * xe ** 2 for me, xe in eq) + floor * L ** 2 / 12
    beta = 15 * ((spec.J_v - J_rest) / (m * L ** 2) - 1 / 12)
    return float(np.clip(beta, -0.5, 1.0))


def element_masses(x: np.ndarray, total: float, beta: float = 0.0, centre: float = 0.0) -> np.ndarray:
    """Mass per length [kg/m] of each element for ``total`` [kg] spread as
    (1 + beta (12 x^2/L^2 - 1) + 12 centre x / L^2) / L (clipped at zero), exactly ``total``."""
    L = x[-1] - x[0]
    xm = 0.5 * (x[1:] + x[:-1])
    shape = np.maximum(1 + beta * (12 * xm ** 2 / L ** 2 - 1) + 12 * centre * xm / L ** 2, 0.0)
    le = np.diff(x)
    return total * shape / (shape * le).sum()


def beam_stiffness(spec: VehicleSpec, x: np.ndarray, beta: float, f1: float) -> float:
    """EI [N m^2] of the carbody beam (nodes ``x``, structure mass shape ``beta``) whose first
    free-free bending with the structure's and the nominal floor payload's mass is ``f1``
    [Hz], by the beam elements' own eigenvalues: a property of the structure, the same on
    every journey. (The uniform beam's closed form at the mean mass per length put the
    intercity car's at 17.2 Hz for 14 Hz asked: its mass is not uniform.)"""
    from .model import free_beam_frequencies  # the beam is built there, and that module imports this one

    nominal = spec.nominal_payload()
    floor = sum(nominal[p.name] for p in spec.payloads if p.where == "floor")
    mu = element_masses(x, spec.m_structure, beta)
    if floor > 0:
        mu = mu + element_masses(x, floor)
    EI = bending_stiffness_for(f1, float((mu * np.diff(x)).sum() / spec.length), spec.length)
    for _ in range(4):  # f goes as sqrt(EI) but for the elements' rotary inertia: a few fixed-point steps
        f = free_beam_frequencies(x, mu, EI, count=1)[0]
        if abs(f / f1 - 1) < 1e-9:
            break
        EI *= (f1 / f) ** 2
    return EI


def car_parameters(spec: VehicleSpec, *, payload: dict | None = None, payload_centre: float = 0.0,
                   elements: int = 10, c_p: float | None = None, c_s: float | None = None,
                   bending_hz: float | None = None, reservoir_ratio: float = 1.0,
                   orifice_quadratic: float = 2.0e4, rigid_equipment: bool = False,
                   track: TrackParameters | None = None, bending_damping_ratio: float = 0.02,
                   structure_centre: float = 0.0, extra_equipment: tuple = (),
                   secondary_friction: float = 0.0) -> CarParameters:
    """The car ``spec`` with ``payload`` [kg] by name (default: mid-range), the floor's
    payload centred at ``payload_centre`` [m], damping [N s/m] and bending [Hz] (default:
    the library's), the air springs' reservoir volume as ``reservoir_ratio`` x the bag's,
    the structure's mass centre at ``structure_centre`` [m], ``extra_equipment`` added as
    (name, mass, x, mount_hz or None, damping ratio), ``secondary_friction`` [N] across each
    bogie's air springs."""
    payload = spec.nominal_payload() if payload is None else payload
    x = beam_mesh(spec, elements)
    beta = mass_shape(spec, elements)
    floor = sum(payload.get(p.name, 0.0) for p in spec.payloads if p.where == "floor")
    mu = element_masses(x, spec.m_structure, beta, structure_centre)
    if floor > 0:
        mu = mu + element_masses(x, floor, 0.0, payload_centre)
    equipment = []
    for e in spec.equipment:
        m = e.mass + sum(payload.get(p.name, 0.0) for p in spec.payloads if p.where == e.name)
        if m > 0:
            equipment.append((e.name, float(m), float(e.x), None if rigid_equipment else e.mount_hz,
                              float(e.damping_ratio)))
    equipment.extend(extra_equipment)
    # equipment acts at the beam node nearest its position (statics and the model agree on it)
    equipment = [(n_, m_, float(x[np.argmin(np.abs(x - xe))]), f_, z_) for n_, m_, xe, f_, z_ in equipment]
    EI = beam_stiffness(spec, x, beta, spec.bending_hz if bending_hz is None else bending_hz)
    # air springs: volumes fixed by the vehicle so that the quasi-static stiffness is k_s at the
    # nominal load; a journey's load changes the pressure and so the stiffness
    nominal = car_parameters_nominal_load(spec)
    area = 2 * 0.15  # two springs of 0.15 m^2 effective area per bogie (typical intercity air spring)
    n = 1.3
    v_total = volume_for_stiffness(spec.k_s, nominal, area, n)
    v_bag = v_total / (1 + reservoir_ratio)
    air = AirSpring(area=area, n=n, v_bag=v_bag, v_res=v_total - v_bag, c_quadratic=orifice_quadratic,
                    c_linear=2.0e3, m_pipe=8.0)
    return CarParameters(
        x_nodes=tuple(float(v) for v in x), mu=tuple(float(v) for v in mu), EI=float(EI),
        bending_damping_ratio=bending_damping_ratio, equipment=tuple(equipment), m_b=tuple(spec.m_b),
        J_b=spec.J_b, m_w=spec.m_w, k_p=spec.k_p, c_p=spec.c_p if c_p is None else c_p, c_p_high_ratio=0.3,
        v_knee=0.08, k_s=spec.k_s, c_s=spec.c_s if c_s is None else c_s, air=air, L_v=spec.L_v, L_b=spec.L_b,
        wheel_radius=spec.wheel_radius, track=TrackParameters() if track is None else track,
        secondary_friction=secondary_friction)


def car_parameters_nominal_load(spec: VehicleSpec) -> float:
    """Mean static force [N] on one bogie's air springs with the nominal payload."""
    total = spec.m_structure + sum(e.mass for e in spec.equipment) + sum(spec.nominal_payload().values())
    return total * GRAVITY / 2
