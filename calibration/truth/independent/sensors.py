"""The measurement chain: what the logger records of the simulated motion.

Each channel is formed at the simulation's rate, passes a causal anti-alias filter (an
elliptic low-pass, 0.1 dB ripple, 60 dB stop band, edge at 0.4 x the output rate, as a
logger's analogue front end) and is decimated to the output rate; it carries a gain error,
white noise, quantisation over its range (16 bit, the seed's Table 1 ranges) and, for an
accelerometer, misalignment: tilted by alpha in the pitch plane it reads
(a_z + g) cos(alpha + theta) + a_x sin(alpha + theta), theta the body's pitch and a_x the
train's longitudinal acceleration. Gyros drift slowly (an Ornstein-Uhlenbeck process).
"""
from __future__ import annotations

import numpy as np
import scipy.signal

G = 9.80665  # [m/s^2] standard gravity: accelerometers are calibrated in g


def anti_alias(fs_in: float, fs_out: float) -> np.ndarray:
    """Second-order sections of the anti-alias low-pass for decimating ``fs_in`` to ``fs_out`` [Hz]."""
    return scipy.signal.ellip(6, 0.1, 60.0, 0.4 * fs_out, btype="low", fs=fs_in, output="sos")


def decimate(x: np.ndarray, fs_in: float, fs_out: float) -> np.ndarray:
    """Anti-alias filter (causal) a 1-D signal and keep every (fs_in / fs_out)-th sample."""
    k = int(round(fs_in / fs_out))
    if abs(k * fs_out - fs_in) > 1e-9 * fs_in:
        raise ValueError(f"the simulation rate {fs_in} Hz must be a whole multiple of the output rate {fs_out} Hz")
    sos = anti_alias(fs_in, fs_out)
    # start the filter settled on the first sample (the logger was running before the record)
    y, _ = scipy.signal.sosfilt(sos, x, zi=scipy.signal.sosfilt_zi(sos) * x[0])
    return y[::k]


def quantise(x: np.ndarray, full_scale: float, bits: int = 16) -> np.ndarray:
    """Round to the converter's steps over +-``full_scale`` and clip there."""
    lsb = 2 * full_scale / 2 ** bits
    return np.clip(np.round(x / lsb) * lsb, -full_scale, full_scale - lsb)


def ou(n: int, dt: float, tau: float, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Ornstein-Uhlenbeck process of time constant tau [s] and rms sigma, n samples every dt [s]."""
    a = np.exp(-dt / tau)
    e = rng.normal(0.0, sigma * np.sqrt(1 - a * a), n)
    e[0] = rng.normal(0.0, sigma)
    return scipy.signal.lfilter([1.0], [1.0, -a], e)


def accelerometer(a_z: np.ndarray, a_x: np.ndarray, theta: np.ndarray, tilt: float) -> np.ndarray:
    """Specific force [m/s^2] along a sensing axis tilted by ``tilt`` [rad] from the body's
    z axis, on a body pitched by ``theta`` [rad] (front down positive), with vertical
    acceleration ``a_z`` and longitudinal acceleration ``a_x`` [m/s^2]."""
    b = tilt + theta
    return (a_z + G) * np.cos(b) + a_x * np.sin(b)


def hermite(x_nodes: np.ndarray, y: np.ndarray, slope: np.ndarray, x: float) -> np.ndarray:
    """Beam displacement (or its time derivatives) at ``x`` from nodal values ``y`` and
    slopes ``slope`` (columns: nodes), cubic Hermite within the element."""
    i = int(np.clip(np.searchsorted(x_nodes, x) - 1, 0, len(x_nodes) - 2))
    le = x_nodes[i + 1] - x_nodes[i]
    s = (x - x_nodes[i]) / le
    h00, h10, h01, h11 = 2 * s ** 3 - 3 * s ** 2 + 1, s ** 3 - 2 * s ** 2 + s, -2 * s ** 3 + 3 * s ** 2, s ** 3 - s ** 2
    return h00 * y[:, i] + h10 * le * slope[:, i] + h01 * y[:, i + 1] + h11 * le * slope[:, i + 1]
