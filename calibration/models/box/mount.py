"""A rigid mass on a vertical spring-damper under a floor point (underfloor equipment on
its mounts), coupled to a modal model of the carbody through the modes' values at the mount:
the form the excitation-test diagnosis fits, and validation compares, for the extension
``underfloor_equipment`` (:mod:`.extended` builds the same mass into the vehicle)."""
from __future__ import annotations

import numpy as np


def mount_impedance(w, mass: float, frequency_hz: float, damping_ratio: float) -> np.ndarray:
    """kappa(omega) [N/m] of a rigid mass ``mass`` [kg] on a vertical spring-damper
    (``frequency_hz`` = sqrt(k_e / m_e) / 2 pi, ``damping_ratio`` = c_e / (2 sqrt(k_e m_e))),
    seen from its mount: f_m = -kappa u_m with kappa = -omega^2 m k* / (k* - omega^2 m),
    k* = k_e + i omega c_e; ``w`` [rad/s] of any shape."""
    k = mass * (2 * np.pi * frequency_hz) ** 2
    kstar = k + 1j * w * 2 * damping_ratio * np.sqrt(k * mass)
    return -w**2 * mass * kstar / (kstar - w**2 * mass)


def equipment_accelerance(f, omega, zeta, sensor_shapes, exciter_shape, mount_shape, mass: float,
                          frequency_hz: float, damping_ratio: float) -> np.ndarray:
    """Accelerance of a modal model (M-normalised modes, modal damping) carrying a rigid mass
    ``mass`` [kg] on a vertical spring-damper (:func:`mount_impedance`) at a point where the
    modes' vertical displacements are ``mount_shape`` (r,) [1/sqrt(kg)].

    The equipment is a point impedance kappa; the structure's modal dynamic stiffness
    Z = diag(omega_k^2 - omega^2 + 2 i zeta_k omega_k omega) with kappa a a^T added is
    inverted by Sherman-Morrison, line by line: exact for the coupled system (the same as
    re-diagonalising it with the mount's damper coupling the modes, as the truth
    simulator's ``add_equipment`` does)."""
    w = 2 * np.pi * np.asarray(f, float)[:, None]
    Z = omega**2 - w**2 + 2j * zeta * omega * w  # (n_f, r)
    kappa = mount_impedance(w[:, 0], mass, frequency_hz, damping_ratio)
    a = np.asarray(mount_shape, float)
    G_se = (exciter_shape / Z) @ sensor_shapes.T  # (n_f, n_s) receptances
    G_sm = (a / Z) @ sensor_shapes.T
    G_me = (a * exciter_shape / Z).sum(axis=1)
    G_mm = (a * a / Z).sum(axis=1)
    U = G_se - (kappa * G_me / (1 + kappa * G_mm))[:, None] * G_sm
    return -w**2 * U
