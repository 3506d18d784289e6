"""Component physics of the independent truth, as plain functions of arrays (SI units).

The exudyn model (:mod:`.model`) evaluates the same laws as symbolic user functions; these
functions are its reference for tests and for the static equilibrium:

* the free-free Euler-Bernoulli beam's first bending frequency (closed form);
* the air spring: force = gauge pressure x effective area, the pressure from the
  polytropic law p V^n = const of the bag, in series with a reservoir behind an orifice
  (quadratic, turbulent-flow damping) -- the mechanical two-volume model of Docquier et
  al., Vehicle System Dynamics 48 (2010) 1477-1491, with the pipe's air as a small mass;
* the bi-linear primary damper (one coefficient below the knee velocity, a lower one
  above: the blow-off valve opening);
* the Hertzian wheel-rail contact, F = (delta/G)^1.5 with Zhai's contact constant
  G = 4.57 R^-0.149 x 1e-8 m/N^(2/3) (Zhai, Wang & Cai, Vehicle System Dynamics 47 (2009)
  1349-1376);
* the track under each wheelset: rail mass on pads on sleeper mass on ballast, whose
  receptance has the two resonances of a discretely supported rail.
"""
from __future__ import annotations

import numpy as np

ATMOSPHERE = 101_325.0  # [Pa]
BEAM_FREE_FREE_1 = 22.373  # (beta L)^2 of the first free-free bending mode


def free_free_bending_hz(EI: float, mu: float, length: float) -> float:
    """First free-free bending frequency [Hz] of a uniform beam: EI [N m^2], mu [kg/m], length [m]."""
    return BEAM_FREE_FREE_1 / (2 * np.pi * length ** 2) * np.sqrt(EI / mu)


def bending_stiffness_for(f1: float, mu: float, length: float) -> float:
    """EI [N m^2] that puts the uniform free-free beam's first bending at ``f1`` [Hz]."""
    return mu * (2 * np.pi * f1 * length ** 2 / BEAM_FREE_FREE_1) ** 2


# ------------------------------------------------------------------------ air spring
def gas_force(compression, p0: float, volume: float, area: float, n: float):
    """Force [N] of a closed air volume under a piston of ``area`` [m^2] compressed by
    ``compression`` [m] from the volume [m^3] it has at absolute pressure ``p0`` [Pa]:
    (p - p_atm) A with p = p0 (V / (V - A z))^n."""
    z = np.asarray(compression, dtype=float)
    return (p0 * (volume / (volume - area * z)) ** n - ATMOSPHERE) * area


def gas_stiffness(compression, p0: float, volume: float, area: float, n: float):
    """d(gas_force)/d(compression) [N/m]: n p A^2 / (V - A z), rising with compression and load."""
    z = np.asarray(compression, dtype=float)
    p = p0 * (volume / (volume - area * z)) ** n
    return n * p * area ** 2 / (volume - area * z)


def levelled_pressure(load: float, area: float) -> float:
    """Absolute pressure [Pa] the levelling valve sets so that the spring carries ``load`` [N]
    at its nominal height."""
    return load / area + ATMOSPHERE


def volume_for_stiffness(k: float, load: float, area: float, n: float) -> float:
    """Total volume [m^3] (bag plus reservoir) whose quasi-static stiffness at ``load`` [N] is ``k`` [N/m]."""
    return n * levelled_pressure(load, area) * area ** 2 / k


def orifice_force(velocity, c_quadratic: float, c_linear: float):
    """Orifice damping force [N] at the equivalent piston velocity [m/s]: turbulent flow
    c_q v|v| plus a small laminar part c_l v that keeps it smooth at rest."""
    v = np.asarray(velocity, dtype=float)
    return c_quadratic * v * np.abs(v) + c_linear * v


# ---------------------------------------------------------------- primary damper
def bilinear_damper_force(velocity, c_low: float, c_high: float, v_knee: float):
    """Bi-linear damper force [N]: c_low v below the knee velocity [m/s], c_high above it."""
    v = np.asarray(velocity, dtype=float)
    a = np.abs(v)
    return np.sign(v) * np.where(a <= v_knee, c_low * a, c_low * v_knee + c_high * (a - v_knee))


# ------------------------------------------------------------------------ contact
def hertz_constant(wheel_radius: float) -> float:
    """Zhai's contact constant G [m/N^(2/3)] for a conical tread of rolling radius [m]."""
    return 4.57e-8 * wheel_radius ** -0.149


def hertz_force(compression, G: float, wheels: int = 2):
    """Contact force [N] of ``wheels`` wheels at ``compression`` [m] (zero when they lift off)."""
    d = np.maximum(np.asarray(compression, dtype=float), 0.0)
    return wheels * (d / G) ** 1.5


def hertz_compression(force: float, G: float, wheels: int = 2) -> float:
    """Static compression [m] under ``force`` [N] shared by ``wheels`` wheels."""
    return G * (force / wheels) ** (2.0 / 3.0)


# -------------------------------------------------------------------------- track
def track_receptance(f, m_r: float, k_pad: float, c_pad: float, m_s: float, k_b: float, c_b: float):
    """Rail receptance [m/N] of rail mass m_r on pads (k_pad, c_pad) on sleeper mass m_s
    on ballast (k_b, c_b), at frequencies ``f`` [Hz] (complex)."""
    w = 2 * np.pi * np.asarray(f, dtype=float)
    zp = k_pad + 1j * w * c_pad
    zb = k_b + 1j * w * c_b
    a_r = -w ** 2 * m_r + zp
    a_s = -w ** 2 * m_s + zp + zb
    return a_s / (a_r * a_s - zp ** 2)


def track_resonances_hz(m_r: float, k_pad: float, m_s: float, k_b: float) -> tuple[float, float]:
    """Undamped natural frequencies [Hz] of the track's two masses on their rigid base:
    sleeper on ballast (lower) and rail on pad (upper)."""
    M = np.diag([m_r, m_s])
    K = np.array([[k_pad, -k_pad], [-k_pad, k_pad + k_b]])
    w2 = np.sort(np.linalg.eigvals(np.linalg.solve(M, K)).real)
    return float(np.sqrt(w2[0]) / (2 * np.pi)), float(np.sqrt(w2[1]) / (2 * np.pi))
