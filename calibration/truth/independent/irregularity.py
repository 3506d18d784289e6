"""The line the journeys run over: vertical track irregularity of its own, generated from a
published spectrum with a seeded ``numpy.random.Generator``.

Longitudinal level follows the German (DB) vertical-profile spectrum,

    S_v(Omega) = A_v Omega_c^2 / ((Omega^2 + Omega_r^2)(Omega^2 + Omega_c^2))   [m^2/(rad/m)],

with the low-disturbance constants A_v = 4.032e-7 m rad, Omega_c = 0.8246 rad/m,
Omega_r = 0.0206 rad/m (high disturbance: A_v = 1.080e-6 m rad), and cross level its
companion S_c = A_c Omega_c^2 Omega^2 / ((Omega^2 + Omega_r^2)(Omega^2 + Omega_c^2)(Omega^2 + Omega_s^2))
with A_c = 4.032e-7 (low) or 1.080e-6 (high) and Omega_s = 0.4380 rad/m. Both as tabulated
by Zhai, Vehicle-Track Coupled Dynamics (Springer 2020), section 3.2, and used throughout
the vehicle-track literature; the spectra are one-sided in angular wavenumber.

The profile is a sum of cosines with random phases (Shinozuka's spectral representation,
evaluated by an inverse FFT) on a 0.05 m grid down to 200 m wavelengths, plus the welds of
39 m rail panels (the in-service seed's section 4) as short cosine dips of drawn depth, and
any settled dips the line is given (raised-cosine troughs of set centre, depth and length).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.signal

from ... import checks

SPECTRA = {  # A_v [m rad], Omega_c, Omega_r, Omega_s [rad/m]
    "german_low": (4.032e-7, 0.8246, 0.0206, 0.4380),
    "german_high": (1.080e-6, 0.8246, 0.0206, 0.4380),
}


def vertical_psd(omega, spectrum: str = "german_low"):
    """One-sided vertical-profile PSD [m^2/(rad/m)] at angular wavenumbers ``omega`` [rad/m]."""
    a, oc, orr, _ = SPECTRA[spectrum]
    w2 = np.asarray(omega, dtype=float) ** 2
    return a * oc ** 2 / ((w2 + orr ** 2) * (w2 + oc ** 2))


def cross_level_psd(omega, spectrum: str = "german_low"):
    """One-sided cross-level PSD [m^2/(rad/m)] (height difference of the two rails over the gauge)."""
    a, oc, orr, os_ = SPECTRA[spectrum]
    w2 = np.asarray(omega, dtype=float) ** 2
    return a * oc ** 2 * w2 / ((w2 + orr ** 2) * (w2 + oc ** 2) * (w2 + os_ ** 2))


def spectral_profile(n: int, dx: float, psd, rng: np.random.Generator, longest: float = 200.0) -> np.ndarray:
    """A stationary random profile [m] of ``n`` samples every ``dx`` [m] with the one-sided
    PSD ``psd(omega)``, wavelengths above ``longest`` [m] left out."""
    nfft = 1 << int(np.ceil(np.log2(n)))
    k = np.arange(nfft // 2 + 1)
    omega = 2 * np.pi * k / (nfft * dx)
    d_omega = 2 * np.pi / (nfft * dx)
    amp = np.sqrt(2 * psd(np.maximum(omega, 1e-12)) * d_omega)
    amp[omega < 2 * np.pi / longest] = 0.0
    amp[-1] = 0.0
    spec = amp * np.exp(1j * rng.uniform(0, 2 * np.pi, k.size)) * nfft / 2
    return np.fft.irfft(spec, nfft)[:n]


def dip_shape(x, depth: float, length: float) -> np.ndarray:
    """Depth [m] of a settled dip (a raised-cosine trough ``length`` [m] long, ``depth`` [m]
    deep at its centre) at ``x`` [m] from its centre; zero beyond half its length."""
    x = np.asarray(x, dtype=float)
    return np.where(np.abs(x) < 0.5 * length, depth * 0.5 * (1 + np.cos(2 * np.pi * x / length)), 0.0)


@dataclass(frozen=True)
class LineSpec:
    """The line: ``length`` [m] of recorded journeys, spectrum name, sleeper spacing and
    rail panel (weld) length [m], weld dip depth range [m], and settled ``dips``, each
    (centre [m], depth [m], length [m]) of a raised-cosine trough in the vertical level."""

    length: float = 8_000.0
    spectrum: str = "german_low"
    sleeper_spacing: float = 0.7
    panel_length: float = 39.0
    weld_depth: tuple[float, float] = (0.05e-3, 0.25e-3)
    dx: float = 0.05
    dips: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self):
        checks.positive(self, "length", "sleeper_spacing", "panel_length", "dx")
        checks.increasing(self, "weld_depth", low=0.0)
        if self.spectrum not in SPECTRA:
            raise ValueError(f"LineSpec.spectrum must be one of {', '.join(SPECTRA)}, got {self.spectrum!r}")
        try:
            dips = tuple((float(c), float(d), float(n)) for c, d, n in self.dips)
        except (TypeError, ValueError):
            raise ValueError(f"LineSpec.dips must be (centre, depth, length) triples, got {self.dips!r}") from None
        for c, d, n in dips:
            if not (math.isfinite(c) and math.isfinite(d) and math.isfinite(n) and d >= 0 and n > 0):
                raise ValueError(f"LineSpec.dips must be finite (centre, depth >= 0, length > 0) triples [m], "
                                 f"got {(c, d, n)!r}")
        # stored as plain float triples so that a spec read back from the truth JSON's lists compares equal
        object.__setattr__(self, "dips", dips)


class Line:
    """Vertical level and cross level [m] along the line, from -margin to length + margin."""

    def __init__(self, spec: LineSpec, rng: np.random.Generator, margin: float = 60.0):
        self.spec = spec
        self.s0 = -margin
        n = int(np.ceil((spec.length + 2 * margin) / spec.dx)) + 1
        self.s = self.s0 + spec.dx * np.arange(n)
        z = spectral_profile(n, spec.dx, lambda w: vertical_psd(w, spec.spectrum), rng)
        welds = np.arange(np.ceil(self.s[0] / spec.panel_length), self.s[-1] / spec.panel_length) * spec.panel_length
        for sw in welds:  # a cosine dip 0.8 m long at each weld
            depth = rng.uniform(*spec.weld_depth)
            near = np.abs(self.s - sw) < 0.4
            z[near] -= depth * 0.5 * (1 + np.cos(np.pi * (self.s[near] - sw) / 0.4))
        self.cross = spectral_profile(n, spec.dx, lambda w: cross_level_psd(w, spec.spectrum), rng)
        # the dips draw nothing and come after every draw, so the same seed gives the same line around them
        for centre, depth, length in spec.dips:
            near = np.abs(self.s - centre) < 0.5 * length
            z[near] -= dip_shape(self.s[near] - centre, depth, length)
        self.z = z

    def level(self, s) -> np.ndarray:
        """Vertical level [m] at distances ``s`` [m] (linear interpolation)."""
        return np.interp(s, self.s, self.z)

    def cross_level(self, s) -> np.ndarray:
        """Cross level [m] (left rail minus right rail) at ``s`` [m]."""
        return np.interp(s, self.s, self.cross)

    def recording(self, start: float, length: float, *, noise: float, rng: np.random.Generator,
                  step: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
        """A track recording car's D1 record (3-25 m wavelengths, zero-phase band-pass) of
        ``length`` [m] from ``start``, every ``step`` [m], with white measurement noise [m]."""
        d = np.arange(start, start + length, step)
        pad = 100.0
        dd = np.arange(start - pad, start + length + pad, step)
        sos = scipy.signal.butter(4, [1 / 25.0, 1 / 3.0], btype="bandpass", fs=1 / step, output="sos")
        zf = scipy.signal.sosfiltfilt(sos, self.level(dd))
        z = np.interp(d, dd, zf) + rng.normal(0, noise, d.size)
        return d, z
