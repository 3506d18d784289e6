"""Synthetic railway line: vertical rail level with random irregularity, sleepers and welds.

Random irregularity
    The German spectra for high-speed lines, vertical level and cross level
    (:mod:`calibration.models.track_irregularity`), synthesised by inverse FFT with random
    phases over wavelengths ``min_wavelength`` .. ``max_wavelength``.

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
import scipy.interpolate
import scipy.signal

from ..models.track_irregularity import (GERMAN_SPECTRA, HALF_GAUGE, german_cross_level_psd, german_vertical_psd,
                                         synthesise_profile)

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
