"""Synthetic railway line: vertical rail level with random irregularity, sleepers and welds.

Random irregularity
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

Sleepers
    The wheel sinks more between sleepers than over them: a periodic rail-level term of
    period ``sleeper_spacing`` (0.7 m, Irish Rail, seed section 4) and depth
    ``sleeper_depth``.

Welds
    Prefabricated panels of ``panel_length`` (39 m, seed section 4) joined by dipped
    welds: a raised-cosine dip of ``weld_length`` and a depth drawn per weld. They give
    the regular spikes of the seed's raw axle-box data.

All lengths in metres. ``level(s)`` returns z, dz/ds and d2z/ds2 at distances ``s``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.fft
import scipy.interpolate
import scipy.signal

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


@dataclass(frozen=True)
class LineSpec:
    """What the synthetic line is made of (metres)."""

    length: float = 90_000.0
    spectrum: str = "german_low"
    min_wavelength: float = 1.0
    max_wavelength: float = 250.0
    grid: float = 0.05
    sleeper_spacing: float = 0.7
    sleeper_depth: float = 4.0e-5
    panel_length: float = 39.0
    weld_length: float = 0.6
    weld_depth_range: tuple[float, float] = (0.5e-4, 2.5e-4)

    def __post_init__(self):
        if self.spectrum not in GERMAN_SPECTRA:
            raise ValueError(f"unknown irregularity spectrum {self.spectrum!r}; have {', '.join(GERMAN_SPECTRA)}")
        if not (0 < self.min_wavelength < self.max_wavelength):
            raise ValueError("need 0 < min_wavelength < max_wavelength")
        if self.grid * 16 > self.min_wavelength:
            raise ValueError(f"grid {self.grid} m too coarse for min_wavelength {self.min_wavelength} m")


class Line:
    """A synthetic line: vertical level (mean of both rails) and cross level."""

    def __init__(self, spec: LineSpec, rng: np.random.Generator):
        self.spec = spec
        margin = 100.0  # the vehicle's length either side of the line's ends
        s, z = synthesise_profile(lambda W: german_vertical_psd(W, spec.spectrum), spec.length + 2 * margin,
                                  spec.grid, rng, min_wavelength=spec.min_wavelength,
                                  max_wavelength=spec.max_wavelength)
        _, c = synthesise_profile(lambda W: german_cross_level_psd(W, spec.spectrum), spec.length + 2 * margin,
                                  spec.grid, rng, min_wavelength=spec.min_wavelength,
                                  max_wavelength=spec.max_wavelength)
        s = s - margin
        self._z = scipy.interpolate.CubicSpline(s, z)
        self._c = scipy.interpolate.CubicSpline(s, c * HALF_GAUGE)  # [m] half height difference
        self.s_min, self.s_max = float(s[0]), float(s[-1])
        first = rng.uniform(0, spec.panel_length)
        self.weld_positions = np.arange(first - margin, spec.length + margin, spec.panel_length)
        self.weld_depths = rng.uniform(*spec.weld_depth_range, size=self.weld_positions.size)

    # -- components -----------------------------------------------------------
    def _sleepers(self, s: np.ndarray):
        k = 2 * np.pi / self.spec.sleeper_spacing
        a = self.spec.sleeper_depth / 2
        # -a (1 - cos(k s)): zero over a sleeper, -depth mid-span
        return -a * (1 - np.cos(k * s)), -a * k * np.sin(k * s), -a * k**2 * np.cos(k * s)

    def _welds(self, s: np.ndarray):
        L = self.spec.weld_length
        z = np.zeros_like(s)
        dz = np.zeros_like(s)
        d2z = np.zeros_like(s)
        idx = np.searchsorted(self.weld_positions, s)
        for off in (-1, 0):
            j = np.clip(idx + off, 0, self.weld_positions.size - 1)
            u = s - self.weld_positions[j]
            inside = np.abs(u) < L / 2
            d = self.weld_depths[j]
            k = 2 * np.pi / L
            # dip: -d/2 (1 + cos(k u)) for |u| < L/2
            z += np.where(inside, -d / 2 * (1 + np.cos(k * u)), 0.0)
            dz += np.where(inside, d / 2 * k * np.sin(k * u), 0.0)
            d2z += np.where(inside, d / 2 * k**2 * np.cos(k * u), 0.0)
        return z, dz, d2z

    def irregularity(self, s: np.ndarray, deriv: int = 0) -> np.ndarray:
        """Random vertical irregularity only (no sleepers, no welds) [m, -, 1/m]."""
        return self._z(s, deriv)

    def level(self, s: np.ndarray, side: int = 0):
        """Rail level under a wheel at distance ``s``: (z [m], dz/ds [-], d2z/ds2 [1/m]).

        side = 0 for the mean of both rails (the 2D model's input), +1 left, -1 right.
        """
        s = np.asarray(s, float)
        if s.size and (s.min() < self.s_min or s.max() > self.s_max):
            raise ValueError(f"distance outside the line [{self.s_min}, {self.s_max}] m")
        out = [self._z(s, d) for d in range(3)]
        if side:
            out = [o + side * self._c(s, d) for d, o in enumerate(out)]
        for parts in (self._sleepers(s), self._welds(s)):
            out = [o + p for o, p in zip(out, parts)]
        return tuple(out)

    def recording(self, start: float, length: float, *, dx: float = 0.25, band=(3.0, 25.0),
                  noise: float = 0.05e-3, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """What a track recording car delivers: the level over [start, start + length],
        band-passed to wavelengths ``band`` [m] (D1 = 3-25 m, EN 13848-1) with zero-phase
        filtering, plus measurement noise ``noise`` [m] rms. Returns (distance, level)."""
        pad = 2 * band[1]
        s = np.arange(start - pad, start + length + pad + dx / 2, dx)
        z = self.level(s)[0] + rng.normal(0.0, noise, s.size)
        fs = 1.0 / dx  # samples per metre
        sos = scipy.signal.butter(4, [1.0 / band[1], 1.0 / band[0]], btype="bandpass", fs=fs, output="sos")
        zf = scipy.signal.sosfiltfilt(sos, z)
        keep = (s >= start) & (s <= start + length)
        return s[keep], zf[keep]
