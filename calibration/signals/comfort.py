"""Ride comfort: the frequency weightings of EN 12299 and ISO 2631, and the indices built on them.

A weighting is the product of four stages in s = j 2 pi f (ISO 8041-1 section 5, ISO 2631-1
Annex A; EN 12299 writes the same stages):

* band-limiting high-pass  s^2 / (s^2 + w1 s / Q1 + w1^2),
* band-limiting low-pass   w2^2 / (s^2 + w2 s / Q2 + w2^2),
* acceleration-velocity transition  (1 + s / w3) / (1 + s / (Q4 w4) + s^2 / w4^2),
* upward step  (s^2 + w5 s / Q5 + w5^2) / (s^2 + w6 s / Q6 + w6^2), unity at high frequency,

times a gain K, with w_i = 2 pi f_i and Q1 = Q2 = 1 / sqrt(2). EN 12299 and BS 6841 write the
step as unity at low frequency with K = 0.4; the product is the same.

Wb's step and transition are given two ways. ISO 2631-4 and ISO 8041-1 use Q4 = 0.55, Q5 = 0.9,
Q6 = 0.95 (:data:`WB_ISO`); the EN 12299:2009 implementations use 0.63, 0.8, 0.8
(:data:`WB_EN`). They differ by up to 1.1 dB near 16 Hz. EN 12299's comfort indices use
:data:`WB_EN`. Its parameters come from two independently written codes that cite
EN 12299:2009; they were not read in the standard itself.

The weightings act on whole records in the frequency domain, with the analogue response at
each frequency. A recursive filter from the bilinear transform loses 0.3 dB at 80 Hz even at
1 kHz sampling.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Q_BUTTERWORTH = 1.0 / np.sqrt(2.0)


@dataclass(frozen=True)
class Weighting:
    """One frequency weighting's parameters [Hz]; None for a stage it does not have."""

    name: str
    f1: float | None  # band-limiting high-pass corner
    f2: float  # band-limiting low-pass corner
    f3: float  # a-v transition: zero
    f4: float  # a-v transition: pole pair
    q4: float
    f5: float | None = None  # upward step: zero pair
    q5: float | None = None
    f6: float | None = None  # upward step: pole pair
    q6: float | None = None
    k: float = 1.0  # gain, the step unity at high frequency
    source: str = ""

    def response(self, f) -> np.ndarray:
        """Complex response H(j 2 pi f) at frequencies ``f`` [Hz]."""
        s = 2j * np.pi * np.asarray(f, float)
        h = self.k * np.ones_like(s)
        w2 = 2 * np.pi * self.f2
        h = h * w2 ** 2 / (s * s + w2 * s / Q_BUTTERWORTH + w2 ** 2)
        if self.f1 is not None:
            w1 = 2 * np.pi * self.f1
            h = h * s * s / (s * s + w1 * s / Q_BUTTERWORTH + w1 ** 2)
        w3, w4 = 2 * np.pi * self.f3, 2 * np.pi * self.f4
        h = h * (1 + s / w3) / (1 + s / (self.q4 * w4) + (s / w4) ** 2)
        if self.f5 is not None:
            w5, w6 = 2 * np.pi * self.f5, 2 * np.pi * self.f6
            h = h * (s * s + w5 * s / self.q5 + w5 ** 2) / (s * s + w6 * s / self.q6 + w6 ** 2)
        return h

    def magnitude(self, f) -> np.ndarray:
        """|H| at frequencies ``f`` [Hz]."""
        return np.abs(self.response(f))


_ISO8041 = "ISO 8041-1:2017 section 5 (the ISO 2631-1 / 2631-4 weightings)"
#: vertical, seated/standing/recumbent, as ISO 2631-4 and ISO 8041-1 give it
WB_ISO = Weighting("Wb (ISO 2631-4)", 0.4, 100.0, 16.0, 16.0, 0.55, 2.5, 0.9, 4.0, 0.95, 1.024, _ISO8041)
#: vertical, as EN 12299:2009 is implemented (comfpy's filters.py and janiex's env12299.m,
#: written independently of each other, both citing EN 12299): the comfort indices' Wb
WB_EN = Weighting("Wb (EN 12299)", 0.4, 100.0, 16.0, 16.0, 0.63, 2.5, 0.8, 4.0, 0.8, 1.024,
                  "EN 12299:2009 as implemented by comfpy and by janiex/SimulinkMatlab")
#: seat back, longitudinal
WC = Weighting("Wc", 0.4, 100.0, 8.0, 8.0, 0.63, source=_ISO8041)
#: horizontal (longitudinal and lateral, floor and seat)
WD = Weighting("Wd", 0.4, 100.0, 2.0, 2.0, 0.63, source=_ISO8041)
#: vertical, ISO 2631-1 health and comfort (not EN 12299's; for comparison)
WK = Weighting("Wk", 0.4, 100.0, 12.5, 12.5, 0.63, 2.37, 0.91, 3.35, 0.91, 1.0, _ISO8041)


def weighted(a: np.ndarray, fs: float, weighting: Weighting) -> np.ndarray:
    """Acceleration record ``a`` (sampled at ``fs`` [Hz]) through ``weighting``, applied in
    the frequency domain. The record is zero-padded to twice its length at least, so the
    weighting's response (its 0.4 Hz high-pass rings for a few seconds) does not wrap round."""
    a = np.asarray(a, float)
    if a.ndim != 1 or a.size < 2:
        raise ValueError(f"weighted: a record of at least two samples is needed, got shape {a.shape}")
    if not fs > 0:
        raise ValueError(f"weighted: the sampling rate must be positive, got {fs}")
    n = 1 << int(np.ceil(np.log2(2 * a.size)))
    spectrum = np.fft.rfft(a, n) * weighting.response(np.fft.rfftfreq(n, 1.0 / fs))
    return np.fft.irfft(spectrum, n)[:a.size]


def block_rms(a: np.ndarray, fs: float, seconds: float = 5.0) -> np.ndarray:
    """Rms of consecutive, non-overlapping blocks of ``seconds`` (EN 12299's 5 s); a last,
    incomplete block is left out."""
    m = int(round(seconds * fs))
    if m < 1 or a.size < m:
        raise ValueError(f"block_rms: a record of {a.size} samples at {fs} Hz holds no {seconds} s block")
    k = a.size // m
    return np.sqrt(np.mean(np.asarray(a[:k * m], float).reshape(k, m) ** 2, axis=1))


def n_mv(fs: float, *, x: np.ndarray | None = None, y: np.ndarray | None = None, z: np.ndarray | None = None,
         seconds: float = 5.0) -> dict:
    """EN 12299's simplified mean comfort index N_MV = 6 sqrt(a_XP95^2 + a_YP95^2 + a_ZP95^2):
    each a_iP95 the 95th percentile of the 5 s rms of the floor acceleration [m/s^2], x and y
    weighted Wd, z weighted Wb. A direction not given is left out of the sum, and the result
    says which were used (a vertical-plane model gives z alone: a partial index)."""
    parts = {}
    for axis, a, w in (("x", x, WD), ("y", y, WD), ("z", z, WB_EN)):
        if a is not None:
            parts[axis] = float(np.percentile(block_rms(weighted(a, fs, w), fs, seconds), 95))
    if not parts:
        raise ValueError("n_mv: give at least one of x, y, z")
    return {"n_mv": 6.0 * float(np.sqrt(sum(v * v for v in parts.values()))),
            "p95_m_per_s2": parts, "directions": tuple(parts), "block_s": seconds}


def sperling_b(f, direction: str = "vertical") -> np.ndarray:
    """Sperling's weighting B(f) (f in Hz): vertical 0.588 sqrt((1.911 f^2 + (0.25 f^2)^2) /
    ((1 - 0.277 f^2)^2 + (1.563 f - 0.0368 f^3)^2)), lateral 1.25 times it."""
    f = np.asarray(f, float)
    b = 0.588 * np.sqrt((1.911 * f ** 2 + (0.25 * f ** 2) ** 2)
                        / ((1 - 0.277 * f ** 2) ** 2 + (1.563 * f - 0.0368 * f ** 3) ** 2))
    if direction == "vertical":
        return b
    if direction == "lateral":
        return 1.25 * b
    raise ValueError(f"sperling_b: direction must be 'vertical' or 'lateral', got {direction!r}")


def sperling_wz(a: np.ndarray, fs: float, direction: str = "vertical") -> float:
    """Sperling's ride index Wz = (2 sum B(f)^2 G(f) df)^0.15 (the exponent often written
    1 / 6.67) of acceleration ``a`` [m/s^2], G its one-sided power spectrum in (cm/s^2)^2/Hz.
    The factor 2 takes rms to a sine's amplitude, Sperling's own measure: a sine of amplitude
    A [cm/s^2] at f gives (B(f) A)^0.3, his 0.896 (A^3 F(f) / f)^0.1."""
    a = np.asarray(a, float)
    spectrum = np.fft.rfft(a * 100.0)
    f = np.fft.rfftfreq(a.size, 1.0 / fs)
    power = np.abs(spectrum) ** 2 / a.size ** 2
    power[1:] *= 2.0  # one-sided: the mean square of each positive frequency's sine
    if a.size % 2 == 0:
        power[-1] /= 2.0
    return float((2.0 * np.sum(sperling_b(f, direction) ** 2 * power)) ** 0.15)
