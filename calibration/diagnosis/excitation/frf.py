"""Frequency responses of a modal model (with an underfloor mass:
:mod:`calibration.models.box.mount`), and the normalised error of a model against measured
FRFs.

Error of a model on one channel o, in units of the noise:

    E_o = mean over lines in the band of |log(H_model / H_meas)|^2 / (2 (sigma^2 + floor^2))

with sigma^2 the variance of log|H1| (:class:`.data.MeasuredFRF`) and ``floor`` the model's
accuracy floor: E is about 1 when a model explains the channel within the noise. FRAC and
the rms log-magnitude error are those of :mod:`calibration.signals.modal`.
"""
from __future__ import annotations

import numpy as np

from .data import MeasuredFRF


def modal_accelerance(f, omega, zeta, sensor_shapes, exciter_shape) -> np.ndarray:
    """Accelerance H[i, o] = a_o / F [(m/s^2)/N] at ``f[i]`` [Hz] of M-normalised modes:
    natural frequencies ``omega`` (r,) [rad/s], damping ratios ``zeta`` (r,), values at the
    sensors ``sensor_shapes`` (n_s, r) and at the exciter ``exciter_shape`` (r,) [1/sqrt(kg)];
    time dependence exp(+i omega t)."""
    w = 2 * np.pi * np.asarray(f, float)[:, None]
    Z = omega**2 - w**2 + 2j * zeta * omega * w
    return (-w**2 * exciter_shape / Z) @ sensor_shapes.T


def normalised_error_lines(meas: MeasuredFRF, H_model: np.ndarray, floor: float) -> np.ndarray:
    """The summand of E_o (module docstring) per spectral line and channel (n_f, n_s) [-]."""
    r = np.log(H_model / meas.H)
    r = r.real**2 + np.angle(H_model / meas.H) ** 2
    return r / (2 * (meas.sigma2 + floor**2))


def level_offsets(meas: MeasuredFRF, H_model: np.ndarray, floor: float) -> tuple[float, np.ndarray, np.ndarray]:
    """(the common level offset, each channel's (n_s,), each channel's weight (n_s,)): means
    of log|H_model / H_meas| weighted as E weighs each line [-]."""
    w = 1.0 / (2 * (meas.sigma2 + floor**2))
    r = np.log(np.abs(H_model / meas.H))
    W = np.sum(w, axis=0)
    return float(np.sum(w * r) / np.sum(w)), np.sum(w * r, axis=0) / W, W


def level_scatter(meas: MeasuredFRF, H_model: np.ndarray, floor: float) -> float:
    """The rms of the channels' level offsets (:func:`level_offsets`) about their common one,
    weighted by channel [-]: zero where a model's level is off by one factor everywhere."""
    common, per, W = level_offsets(meas, H_model, floor)
    return float(np.sqrt(np.sum(W * (per - common) ** 2) / np.sum(W)))


def normalised_error(meas: MeasuredFRF, H_model: np.ndarray, floor: float) -> np.ndarray:
    """E_o per channel (module docstring) [-]: about 1 when the model is within the noise."""
    return np.mean(normalised_error_lines(meas, H_model, floor), axis=0)
