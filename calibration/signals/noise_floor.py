"""Noise floors of measured channels: the spectral density below which a channel resolves nothing.

Two estimates of a channel's noise power spectral density G_nn [unit^2/Hz], each reported
with its root, the amplitude spectral density [unit/sqrt(Hz)], and the rms a white noise
of that density has over the band:

* **spectral floor** (:func:`spectral_floor`; any channel, no reference needed): a low
  percentile, over the lines of a band, of the channel's Welch PSD averaged over every
  gap-free stretch of valid samples. The band lies above the vehicle's modes and below the
  anti-alias filter's roll-off, where a channel holds sensor noise, the track's lines and
  little else; averaged over many segments a white noise's PSD scatters by a few per cent
  from line to line, so the low percentile picks the quietest lines, between the lines of
  the excitation. Where the channel carries signal over the whole band it is an upper bound.
* **non-coherent output** (:func:`non_coherent_floor`; a response to a measured force):
  (1 - gamma^2) G_yy = G_yy - |G_fy|^2 / G_ff, the response power not coherent with the
  force, a low percentile of it over the band's lines. Besides sensor noise it holds
  whatever the force does not explain linearly, above all the bias of a Welch H1 near
  lightly damped resonances (the response outlasts a segment's window): the lines away
  from the resonances, which the low percentile picks, are the noise's.

Both correct the statistic for its own sampling: a Welch average of K independent segments
of white noise is G chi^2_2K / 2K at every line, and the one-input residual spectrum of K
segments is G chi^2_2(K-1) / 2K (Bendat & Piersol, *Random data*, 4th ed. 2010, sec.
9.1.4), so their percentile over the lines is divided by that chi^2 distribution's. The
segments here are Hann windows overlapping by half, so 2K is replaced by the equivalent
degrees of freedom (:func:`welch_dof`); counting them as independent would bias the floor
low by 1.5 % at K = 10 and 3-4 % at K = 4-8.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.signal
import scipy.stats

from .. import checks
from .resample import is_regular

SPECTRAL_FLOOR = "psd_percentile"
NON_COHERENT = "non_coherent_output"


@dataclass(frozen=True)
class NoiseFloorSettings:
    """Where and how a spectral floor is read (:func:`spectral_floor`)."""

    percentile: float = 10.0  # [%] of the PSD's lines over the band
    segment_s: float = 2.0  # [s] Welch segment (0.5 Hz lines), halves overlapping
    # The band's top as a share of the sampling rate: a logger's anti-alias low-pass cuts at
    # 0.4 fs or above, and an 8th-order Butterworth at 0.4 fs is 0.5 dB down at 0.35 fs.
    top_fraction: float = 0.35

    def __post_init__(self):
        checks.positive(self, "segment_s")
        if not 0 < self.percentile < 100:
            raise ValueError(f"NoiseFloorSettings.percentile must be in (0, 100) [%], got {self.percentile!r}")
        if not 0 < self.top_fraction <= 0.5:
            raise ValueError(f"NoiseFloorSettings.top_fraction must be in (0, 0.5] (of the sampling rate), "
                             f"got {self.top_fraction!r}")


@dataclass(frozen=True)
class NoiseFloor:
    """A channel's noise floor: ``psd`` [unit^2/Hz] over ``band_hz`` [Hz], by ``method``
    from ``segments`` Welch segments; ``unit`` is the channel's SI unit."""

    channel: str
    unit: str
    psd: float
    band_hz: tuple[float, float]
    method: str
    segments: int

    @property
    def asd(self) -> float:
        """[unit/sqrt(Hz)] amplitude spectral density."""
        return float(np.sqrt(self.psd))

    @property
    def rms_in_band(self) -> float:
        """[unit] rms of a white noise at this density over the band."""
        return float(np.sqrt(self.psd * (self.band_hz[1] - self.band_hz[0])))

    def to_json(self) -> dict:
        how = {SPECTRAL_FLOOR: "low percentile of the Welch PSD over the band (an upper bound where the channel "
                               "carries signal over the whole band)",
               NON_COHERENT: "low percentile over the band of the response power not coherent with the force, "
                             "(1 - coherence^2) G_yy"}[self.method]
        return {"channel": self.channel, "unit": self.unit, "psd_si_per_hz": self.psd,
                "asd_si_per_sqrt_hz": self.asd, "rms_in_band_si": self.rms_in_band,
                "band_hz": list(self.band_hz), "method": self.method, "welch_segments": self.segments,
                "how": how}


def _in_band(f: np.ndarray, band: tuple[float, float]) -> np.ndarray:
    sel = (f >= band[0]) & (f <= band[1])
    if np.count_nonzero(sel) < 3:
        raise ValueError(f"band {band} Hz holds {np.count_nonzero(sel)} spectral lines; at least 3 are needed")
    return sel


#: correlation of two Hann-windowed segments overlapping by half (Welch, IEEE Trans. Audio
#: Electroacoust. 15 (1967) 70-73; Harris, Proc. IEEE 66 (1978) 51-83, table 1): every Welch
#: average here is of such segments, so it has fewer than 2K degrees of freedom
HANN_HALF_OVERLAP_RHO = 0.167


def welch_dof(segments: int) -> float:
    """Equivalent degrees of freedom of a Welch PSD averaged over ``segments`` Hann segments
    overlapping by half: 2K / (1 + 2 (1 - 1/K) rho^2), only neighbours overlapping."""
    return 2 * segments / (1 + 2 * (1 - 1 / segments) * HANN_HALF_OVERLAP_RHO**2)


def spectral_floor(f: np.ndarray, psd: np.ndarray, band: tuple[float, float], segments: int,
                   percentile: float = 10.0) -> np.ndarray:
    """[unit^2/Hz] the ``percentile``-th percentile over the lines of ``band`` [Hz] of a Welch
    PSD ``psd`` (n_f,) or (n_f, n_ch) [unit^2/Hz] averaged over ``segments`` segments,
    divided by that percentile of chi^2_nu / nu (nu: :func:`welch_dof`): white noise of
    density G gives G."""
    if segments < 1:
        raise ValueError(f"segments must be >= 1, got {segments}")
    sel = _in_band(np.asarray(f, float), band)
    dof = welch_dof(segments)
    return np.percentile(np.asarray(psd, float)[sel], percentile, axis=0) * dof / scipy.stats.chi2.ppf(
        percentile / 100, dof)


def non_coherent_floor(f: np.ndarray, Gff: np.ndarray, Gfy: np.ndarray, Gyy: np.ndarray,
                       band: tuple[float, float], segments: int, percentile: float = 10.0) -> np.ndarray:
    """[unit^2/Hz] of each response: the ``percentile``-th percentile over the lines of
    ``band`` [Hz] of (1 - gamma^2) G_yy from Welch spectra averaged over ``segments`` (>= 2)
    segments (``Gff`` (n_f,) [N^2/Hz], ``Gfy`` and ``Gyy`` (n_f, n_out)), divided by that
    percentile of chi^2_nu' / nu with nu' = nu (K - 1) / K (nu: :func:`welch_dof`; the fit of
    one transfer function takes a K-th): a response plus white noise of density G gives G."""
    if segments < 2:
        raise ValueError(f"segments must be >= 2 (one segment is fully coherent whatever the data), got {segments}")
    sel = _in_band(np.asarray(f, float), band)
    Gff = np.maximum(np.asarray(Gff, float)[sel], np.finfo(float).tiny)
    residual = np.maximum(np.real(np.asarray(Gyy)[sel]) - np.abs(np.asarray(Gfy)[sel]) ** 2 / Gff[:, None], 0.0)
    dof = welch_dof(segments)
    return np.percentile(residual, percentile, axis=0) * dof / scipy.stats.chi2.ppf(
        percentile / 100, dof * (segments - 1) / segments)


class WelchSums:
    """Welch PSDs of named channels summed over stretches of valid samples, record by record:
    a stretch of ``n`` samples adds its segments' average times their count, so every
    segment counts once (streaming: nothing of a run is kept)."""

    def __init__(self, channels: tuple[str, ...], fs: float, nperseg: int):
        if nperseg < 8:
            raise ValueError(f"nperseg must be >= 8, got {nperseg}")
        self.channels, self.fs, self.nperseg = tuple(channels), float(fs), int(nperseg)
        self.f = np.fft.rfftfreq(self.nperseg, 1.0 / self.fs)
        self.sums = {ch: np.zeros(self.f.size) for ch in self.channels}
        self.segments = dict.fromkeys(self.channels, 0)

    def add(self, channel: str, x: np.ndarray) -> None:
        """Add one gap-free stretch of valid samples of ``channel`` (no NaN), sampled at ``fs``."""
        step = self.nperseg - self.nperseg // 2
        n = 1 + (x.size - self.nperseg) // step if x.size >= self.nperseg else 0
        if n < 1:
            return
        _, p = scipy.signal.welch(np.asarray(x, float), fs=self.fs, nperseg=self.nperseg, detrend="linear")
        self.sums[channel] += n * p
        self.segments[channel] += n

    def add_run(self, run) -> None:
        """Every gap-free stretch of valid samples of every channel of ``run`` (a
        :class:`calibration.data.campaign.Run` on equal steps of 1 / ``fs``; a block sampled at
        another rate, which :func:`~calibration.signals.resample.regular_run` leaves at its own,
        is left out: its lines would not be these)."""
        blocks = [(a, b) for a, b in run.blocks if is_regular(run.time[a:b], self.fs)]
        for ch in self.channels:
            ok = run.valid[ch]
            for a, b in blocks:
                edges = np.flatnonzero(np.diff(np.concatenate([[0], ok[a:b].astype(int), [0]])))
                for s, e in zip(edges[::2], edges[1::2]):
                    self.add(ch, run.channels[ch][a + s:a + e])

    def floors(self, units: dict, band: tuple[float, float], percentile: float) -> list[NoiseFloor]:
        """The spectral floor of every channel with at least one segment (``units``: SI unit by channel)."""
        out = []
        for ch in self.channels:
            k = self.segments[ch]
            if k > 0:
                psd = float(spectral_floor(self.f, self.sums[ch] / k, band, k, percentile))
                out.append(NoiseFloor(ch, units.get(ch, ""), psd, (float(band[0]), float(band[1])), SPECTRAL_FLOOR, k))
        return out
