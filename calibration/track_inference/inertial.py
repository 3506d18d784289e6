"""The classic inertial method: the rail's level from the axle boxes' vertical
acceleration integrated twice over distance.

A wheelset on the rail follows its level r(s): its acceleration is v^2 r'' + a r'. On the
distance grid, r'' = (acc - a r') / v^2, and r' is taken from the previous estimate (one
fixed-point pass; a r' is a few per cent of v^2 r'' at the train's accelerations). The
double integral is done in the wavenumber domain, inside the band asked for, where it is
a division by -(2 pi k)^2, over twice the band's wavelengths, then filtered to the band as
every other estimate is; the offset (gravity) and the longest waves go.
Each axle's estimate is placed at its own wheelset's position and the two are averaged.

It needs no vehicle model, which is its strength; the axle box also carries what the
model leaves out (the track's own give under the wheel, sleeper passing, the wheel's
roundness), and at long wavelengths v^2 r'' is tiny beside the sensor's noise.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.signal

from ..data.tracks import BAND_WAVELENGTHS_M
from .kalman import PassProfile
from .passes import Pass
from .profile import band_filter


def _integrate_twice(x: np.ndarray, step: float, band: tuple[float, float]) -> np.ndarray:
    n = x.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    k = np.fft.rfftfreq(nfft, step)  # [cycles/m]
    spec = np.fft.rfft(x - x.mean(), nfft)
    inside = (k >= 1.0 / band[1]) & (k <= 1.0 / band[0])
    out = np.zeros_like(spec)
    out[inside] = -spec[inside] / (2 * np.pi * k[inside]) ** 2
    return np.fft.irfft(out, nfft)[:n]


def _axle_level(ps: Pass, wheel_x: np.ndarray, limits: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """(distance [m], level [m]): the axle boxes' double integral within the wavelengths
    ``limits`` [m], each axle placed at its wheelset and the two averaged, on the grid of
    wheelset 1's positions."""
    axles = [c for c in ps.channels if c.kind == "axle"]
    if not axles:
        raise ValueError("the pass has no axle-box channel (read it with axle_boxes=True)")
    step = float(ps.s[1] - ps.s[0])
    grid = ps.s + wheel_x[0]
    levels = []
    for c in axles:
        acc = c.values - np.mean(c.values)
        r = _integrate_twice(acc / ps.v ** 2, step, limits)
        r = _integrate_twice((acc - ps.a * np.gradient(r, step)) / ps.v ** 2, step, limits)
        levels.append(np.interp(grid, ps.s + wheel_x[c.wheelset - 1], r))
    return grid, np.mean(levels, axis=0)


def inertial_level(ps: Pass, wheel_x: np.ndarray, band: str = "D1") -> tuple[np.ndarray, np.ndarray]:
    """(distance [m], level [m]) in ``band`` from the pass's axle-box channels; ``wheel_x``
    [m] the wheelsets' positions from the car's centre (wheelset 1 leads)."""
    step = float(ps.s[1] - ps.s[0])
    lo, hi = BAND_WAVELENGTHS_M[band]
    # integrated wide, then filtered as every other estimate
    grid, level = _axle_level(ps, wheel_x, (max(lo / 2, 2 * step), 2 * hi))
    return grid, band_filter(level, band, step)


def _lowpass_distance(x: np.ndarray, wavelength: float, step: float) -> np.ndarray:
    sos = scipy.signal.butter(4, 1.0 / wavelength, fs=1.0 / step, output="sos")
    return scipy.signal.sosfiltfilt(sos, x)


def blend(pp: PassProfile, ps: Pass, wheel_x: np.ndarray, crossover: float) -> PassProfile:
    """``pp`` (the filter's level of pass ``ps``) with its wavelengths under ``crossover`` [m]
    taken from the axle boxes' double integral instead: the seed's "axle boxes at short
    wavelengths, the model at long ones". The split is complementary (a zero-phase low-pass
    L of the filter's level plus the integral minus L of it), so nothing is counted twice.
    The error draws stay the filter's: the standard deviation does not cover the change."""
    step = float(ps.s[1] - ps.s[0])
    grid, level = _axle_level(ps, wheel_x, (max(1.5, 2 * step), 4 * crossover))
    short = np.interp(pp.distance, grid, level)
    short = short - _lowpass_distance(short, crossover, step)
    return replace(pp, level=_lowpass_distance(pp.level, crossover, step) + short)
