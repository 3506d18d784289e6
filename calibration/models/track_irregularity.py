"""Track irregularity spectra: the German spectra for high-speed lines, and the synthesis of
a random profile with a given spectrum.

German track spectra for high-speed lines, vertical level and cross level, as
tabulated by Zhai (Vehicle-Track Coupled Dynamics, Springer 2020, section 2.5.2;
also Claus & Schiehlen, Vehicle System Dynamics 29 (1998) 223-244):

    S_v(W) = A_v W_c^2 / ((W^2 + W_r^2)(W^2 + W_c^2))              [m^2 / (rad/m)]
    S_c(W) = A_v/b^2 W_c^2 W^2 / ((W^2+W_r^2)(W^2+W_c^2)(W^2+W_s^2))  [rad^2/(rad/m)]

W the spatial angular frequency [rad/m], b = 0.75 m half the rail-centre distance,
W_c = 0.8246, W_r = 0.0206, W_s = 0.4380 rad/m; A_v = 4.032e-7 m rad (low
disturbance) or 1.080e-6 m rad (high disturbance). One-sided, so the variance is
the integral over W from 0 to infinity. The profile is synthesised by inverse FFT
with random phases over wavelengths ``min_wavelength`` .. ``max_wavelength``.
"""
from __future__ import annotations

import numpy as np
import scipy.fft

GERMAN_SPECTRA = {  # A_v [m rad], W_c, W_r, W_s [rad/m]
    "german_low": (4.032e-7, 0.8246, 0.0206, 0.4380),
    "german_high": (1.080e-6, 0.8246, 0.0206, 0.4380),
}
HALF_GAUGE = 0.75  # [m] b in the cross-level spectrum


def german_vertical_psd(W: np.ndarray, spectrum: str = "german_low") -> np.ndarray:
    """One-sided vertical-level PSD [m^2/(rad/m)] at spatial angular frequency W [rad/m]."""
    A, Wc, Wr, _ = GERMAN_SPECTRA[spectrum]
    W = np.asarray(W, float)
    return A * Wc**2 / ((W**2 + Wr**2) * (W**2 + Wc**2))


def german_cross_level_psd(W: np.ndarray, spectrum: str = "german_low") -> np.ndarray:
    """One-sided cross-level PSD [rad^2/(rad/m)] (angle = height difference / 2b)."""
    A, Wc, Wr, Ws = GERMAN_SPECTRA[spectrum]
    W = np.asarray(W, float)
    return (A / HALF_GAUGE**2) * Wc**2 * W**2 / ((W**2 + Wr**2) * (W**2 + Wc**2) * (W**2 + Ws**2))


def synthesise_profile(psd, length: float, dx: float, rng: np.random.Generator, *,
                       min_wavelength: float, max_wavelength: float) -> tuple[np.ndarray, np.ndarray]:
    """Random stationary profile with one-sided PSD ``psd(W)`` on a grid of spacing ``dx``.

    Returns (s, z). The variance of z equals the integral of psd over the band, to
    within the finite-length sampling of the spectrum.
    """
    n = int(np.ceil(length / dx)) + 1
    nfft = scipy.fft.next_fast_len(n)
    W = 2 * np.pi * np.fft.rfftfreq(nfft, dx)
    dW = W[1] - W[0]
    W_min = 2 * np.pi / min_wavelength
    band = (W >= 2 * np.pi / max_wavelength) & (W <= 2 * W_min)
    amp = np.zeros_like(W)
    amp[band] = np.sqrt(2.0 * psd(W[band]) / (1.0 + (W[band] / W_min) ** 8) * dW)
    phase = rng.uniform(0, 2 * np.pi, size=W.shape)
    spec = 0.5 * nfft * amp * np.exp(1j * phase)
    z = np.fft.irfft(spec, n=nfft)[:n]
    return np.arange(n) * dx, z
