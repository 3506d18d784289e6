"""Zero-phase Butterworth filtering in second-order sections (seed section 4).

The seed removes drift with a 6th-order high-pass at 0.25 Hz and keeps the vehicle's
band with a 6th-order band-pass 0.25-25 Hz. ``order`` is the order of the designed
filter; applied forwards and backwards (``sosfiltfilt``) its magnitude is squared and
its phase zero. Vocabulary follows scipy.signal: ``fs`` [Hz], ``axis``.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.signal

SEED_HIGHPASS_HZ = 0.25
SEED_BAND_HZ = (0.25, 25.0)
SEED_ORDER = 6


@lru_cache(maxsize=64)
def butter_sos(order: int, cutoff, btype: str, fs: float) -> np.ndarray:
    """Butterworth design as second-order sections (cached; cutoff a float or a pair)."""
    nyq = fs / 2
    edges = np.atleast_1d(cutoff)
    if np.any(edges <= 0) or np.any(edges >= nyq):
        raise ValueError(f"cut-off {cutoff} Hz must lie inside (0, fs/2 = {nyq}) Hz")
    return scipy.signal.butter(order, cutoff, btype=btype, fs=fs, output="sos")


def _padlen(sos: np.ndarray, n: int) -> int:
    return min(n - 1, 3 * (2 * len(sos) + 1))


def highpass(x: np.ndarray, fs: float, cutoff: float = SEED_HIGHPASS_HZ, *, order: int = SEED_ORDER,
             axis: int = -1) -> np.ndarray:
    """Zero-phase high-pass [same units as x]."""
    sos = butter_sos(order, float(cutoff), "highpass", float(fs))
    return scipy.signal.sosfiltfilt(sos, x, axis=axis, padlen=_padlen(sos, np.shape(x)[axis]))


def bandpass(x: np.ndarray, fs: float, band=SEED_BAND_HZ, *, order: int = SEED_ORDER, axis: int = -1) -> np.ndarray:
    """Zero-phase band-pass [same units as x]."""
    sos = butter_sos(order, (float(band[0]), float(band[1])), "bandpass", float(fs))
    return scipy.signal.sosfiltfilt(sos, x, axis=axis, padlen=_padlen(sos, np.shape(x)[axis]))


def lowpass(x: np.ndarray, fs: float, cutoff: float, *, order: int = SEED_ORDER, axis: int = -1) -> np.ndarray:
    sos = butter_sos(order, float(cutoff), "lowpass", float(fs))
    return scipy.signal.sosfiltfilt(sos, x, axis=axis, padlen=_padlen(sos, np.shape(x)[axis]))


def band_random(n: int, fs: float, band: tuple[float, float], rms: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian random signal of ``n`` samples at ``fs`` [Hz] with a flat spectrum in
    ``band`` [Hz] and none outside (FFT synthesis, so stationary from its first sample),
    scaled to ``rms``."""
    spectrum = np.fft.rfft(rng.standard_normal(n))
    nu = np.fft.rfftfreq(n, 1.0 / fs)
    spectrum[(nu < band[0]) | (nu > band[1])] = 0.0
    x = np.fft.irfft(spectrum, n)
    return x * (rms / x.std())
