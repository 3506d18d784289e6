"""Wheel-fixed excitation: what one wheelset of the leading bogie carries and the other not.

The consistency channel (:mod:`.records`) removes the rail: on round wheels it is sensor
noise. Divided by v^2 and resampled to distance it is a *rail curvature* signal [1/m] in
which anything fixed to a wheel's circumference (a polygonal wheel, a wheel flat's
periodic part) is a line at a fixed wavenumber, whatever the speed, while sensor noise is
spread. The extension (:class:`WheelPolygon`) is a radius deviation on one wheelset: the
strongest line, A cos(2 pi s / lambda + phi), and the other lines of the same wheel. A
wheel's out-of-roundness repeats once per revolution, so its lines are harmonics of one
circumference C (a real wheel's polygon has several orders at once, and the strongest line
in curvature, which grows with the order squared, is rarely the largest radius deviation):
C is the multiple of lambda, within a wheel's circumferences, whose harmonics stand out
of the floor most often, and each harmonic that does is fitted too. Since no sensor tells
the wheel's angle, each line's phase is a nuisance re-estimated per distance segment; the
amplitudes and wavelengths are the extension's parameters (fitted on training runs).

Which wheelset carries it: the line's power in that wheelset's own axle-box spectrum
stands above the other's (both see the rail's power at that wavenumber equally).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.interpolate
import scipy.ndimage

from .records import Record


@dataclass(frozen=True, kw_only=True)
class WheelSettings:
    """The distance grid and segments of the wavenumber spectra, and the wavelengths searched."""

    step_m: float = 0.05  # [m] distance grid step
    segment_m: float = 100.0  # [m] distance segment (Hann; phase re-estimated per segment)
    wavelengths_m: tuple[float, float] = (0.4, 5.0)  # [m] wavelengths searched (shortest, longest)
    floor_width: float = 0.25  # width of the running-median floor, relative to the median wavenumber
    # [m] a wheel's circumference: radii of 0.3-0.6 m (light rail to locomotive wheels)
    circumference_m: tuple[float, float] = (1.8, 3.8)
    harmonic_over_floor: float = 30.0  # a harmonic's line power over floor to count as the wheel's

    def __post_init__(self):
        for name in ("step_m", "segment_m", "floor_width"):
            if not getattr(self, name) > 0:
                raise ValueError(f"WheelSettings.{name} must be positive, got {getattr(self, name)}")
        lo, hi = self.wavelengths_m
        if not 2 * self.step_m <= lo < hi <= self.segment_m:
            raise ValueError(f"WheelSettings.wavelengths_m must be (shortest, longest) with 2 step_m <= shortest "
                             f"< longest <= segment_m, got {self.wavelengths_m}")


def _distance_series(rec: Record, row: int, ds: float):
    """The record's channel ``row`` divided by v^2 on a uniform distance grid."""
    s = np.arange(rec.distance[0], rec.distance[-1], ds)
    # cubic, not linear: at 30 m/s the 200 Hz samples are 0.15 m apart, and a straight line
    # between them takes 14 % off a 0.66 m line's amplitude (a cubic 1 %)
    d, keep = np.unique(rec.distance, return_index=True)
    x = scipy.interpolate.CubicSpline(d, rec.z[row][keep] / np.maximum(rec.speed[keep], 1.0) ** 2)(s)
    return s, x


def _segments(records, row, settings: WheelSettings):
    """(run id, distance [m], de-meaned channel ``row`` / v^2) per whole segment of each record."""
    n = int(round(settings.segment_m / settings.step_m))
    for rec in records:
        s, x = _distance_series(rec, row, settings.step_m)
        for a in range(0, x.size - n + 1, n):
            yield rec.run_id, s[a:a + n], x[a:a + n] - x[a:a + n].mean()


@dataclass(frozen=True)
class LineSpectrum:
    wavenumber: np.ndarray  # [1/m]
    power: np.ndarray  # [(1/m)^2] mean power per bin (consistency channel, curvature units)
    floor: np.ndarray  # running median of ``power``
    axle1: np.ndarray  # the same for the two axle-box means
    axle2: np.ndarray

    @property
    def ratio(self) -> np.ndarray:
        return self.power / np.maximum(self.floor, 1e-300)

    def strongest(self, settings: WheelSettings) -> tuple[int, float]:
        """(bin, line power over floor) of the strongest line within the searched wavelengths."""
        k = self.wavenumber
        inside = (k >= 1 / settings.wavelengths_m[1]) & (k <= 1 / settings.wavelengths_m[0])
        i = int(np.flatnonzero(inside)[np.argmax(self.ratio[inside])])
        return i, float(self.ratio[i])


def line_spectrum(records: list[Record], rows: dict, runs, settings: WheelSettings = WheelSettings()) -> LineSpectrum:
    """Mean wavenumber power spectra (Hann segments) of the consistency channel and the two
    axle-box means over the records of ``runs``. ``rows``: channel name -> row in Record.z."""
    n = int(round(settings.segment_m / settings.step_m))
    win = np.hanning(n)
    k = np.fft.rfftfreq(n, settings.step_m)
    out = {}
    for name in ("consistency", "axle1_mean", "axle2_mean"):
        acc, count = np.zeros(k.size), 0
        for run_id, _, x in _segments([r for r in records if r.run_id in runs], rows[name], settings):
            acc += np.abs(np.fft.rfft(x * win)) ** 2
            count += 1
        out[name] = acc / max(count, 1)
    p = out["consistency"]
    size = max(5, int(settings.floor_width * np.median(k[1:]) / (k[1] - k[0])) | 1)
    floor = scipy.ndimage.median_filter(p, size=size, mode="nearest")
    return LineSpectrum(k, p, floor, out["axle1_mean"], out["axle2_mean"])


@dataclass(frozen=True)
class WheelPolygon:
    """Fitted wheel-fixed line: wavelength [m], curvature amplitude [1/m] in the consistency
    channel, the wheelset carrying it and the equivalent radius deviation [m]."""

    wavelength: float
    curvature_amplitude: float
    wheelset: int
    radius_amplitude: float  # the largest radius deviation over the harmonics [m]
    line_ratio: float  # line power over floor in the training spectrum
    # every line fitted, the strongest first: (wavelength [m], curvature amplitude [1/m])
    harmonics: tuple[tuple[float, float], ...] = ()
    circumference: float | None = None  # [m] the wheel's, when harmonics of one were found

    @property
    def lines(self) -> tuple[tuple[float, float], ...]:
        return self.harmonics or ((self.wavelength, self.curvature_amplitude),)

    def to_json(self) -> dict:
        return {"wheelset": self.wheelset, "wavelength_m": self.wavelength,
                "radius_amplitude_m": self.radius_amplitude, "line_over_floor": self.line_ratio,
                "circumference_m": self.circumference,
                "harmonics": [{"wavelength_m": w, "radius_amplitude_m": a * (w / (2 * np.pi)) ** 2}
                              for w, a in self.lines]}


def fit_polygon(records, rows, train_runs, settings: WheelSettings = WheelSettings(), *,
                pad: int = 16) -> WheelPolygon:
    """The strongest wheel-fixed line of the training runs' consistency channel as a wheel
    polygon: its wavenumber refined on spectra zero-padded ``pad`` times, its amplitude the
    rms over segments, its wheelset the one whose axle boxes carry more of it."""
    spec = line_spectrum(records, rows, train_runs, settings)
    i, ratio = spec.strongest(settings)
    chosen = [r for r in records if r.run_id in train_runs]
    k = _refined(chosen, rows, settings, spec.wavenumber[i], pad)
    amp = _amplitude(chosen, rows, settings, k)
    # which wheelset: the line's excess power in that wheelset's own axle-box spectrum
    wheelset = 1 if spec.axle1[i] >= spec.axle2[i] else 2
    lines, circumference = [(float(1 / k), amp)], None
    found = _harmonics(spec, k, settings)
    if found:
        circumference, ks = found
        lines += [(float(1 / kh), _amplitude(chosen, rows, settings, kh))
                  for kh in (_refined(chosen, rows, settings, kk, pad) for kk in ks)]
    radius = max(a / (2 * np.pi / w) ** 2 for w, a in lines)
    return WheelPolygon(float(1 / k), amp, wheelset, float(radius), ratio,
                        tuple(lines) if found else (), circumference)


def _harmonics(spec: LineSpectrum, k1: float, settings: WheelSettings) -> tuple[float, list[float]] | None:
    """The wheel's circumference C = n / k1 (n = 1, 2, ..., C within ``circumference_m``)
    whose other harmonics m / C (within the searched wavelengths) stand above the floor by
    ``harmonic_over_floor`` most often, and those harmonics' wavenumbers; None when no other
    line does (ties: the smallest C)."""
    lo, hi = settings.circumference_m
    k_lo, k_hi = 1 / settings.wavelengths_m[1], 1 / settings.wavelengths_m[0]
    dk = spec.wavenumber[1] - spec.wavenumber[0]
    best = None
    for n in range(1, int(np.floor(hi * k1)) + 1):
        c = n / k1
        if not lo <= c <= hi:
            continue
        ks = []
        for m in range(1, int(np.floor(k_hi * c)) + 1):
            km = m / c
            if m == n or km < k_lo or abs(km - k1) < 2 * dk:
                continue
            near = np.abs(spec.wavenumber - km) <= dk  # the harmonic's bin and its neighbours
            if np.any(near) and spec.ratio[near].max() >= settings.harmonic_over_floor:
                ks.append(float(spec.wavenumber[near][np.argmax(spec.ratio[near])]))
        if ks and (best is None or len(ks) > len(best[1])):
            best = (c, ks)
    return best


def _refined(records, rows, settings: WheelSettings, k0: float, pad: int) -> float:
    """A line's wavenumber near bin wavenumber ``k0``, refined on the segments' mean power
    zero-padded ``pad`` times (parabolic interpolation of the log power at the peak)."""
    n = int(round(settings.segment_m / settings.step_m))
    win = np.hanning(n)
    k_fine = np.fft.rfftfreq(pad * n, settings.step_m)
    dk = 1 / settings.segment_m
    lo, hi = np.searchsorted(k_fine, [k0 - dk, k0 + dk])
    power = np.zeros(hi - lo)
    for _, s, x in _segments(records, rows["consistency"], settings):
        power += np.abs(np.fft.rfft(x * win, pad * n)[lo:hi]) ** 2
    j = int(np.argmax(power))
    k = k_fine[lo + j]
    if 0 < j < power.size - 1:
        a, b, c = np.log(power[j - 1:j + 2])
        k += 0.5 * (a - c) / (a - 2 * b + c) * (k_fine[1] - k_fine[0])
    return float(k)


def _amplitude(records, rows, settings: WheelSettings, k: float) -> float:
    """A line's curvature amplitude at wavenumber ``k``: the rms over segments of each one's."""
    amps = [2 * abs(np.mean(x * np.exp(-2j * np.pi * k * s)))
            for _, s, x in _segments(records, rows["consistency"], settings)]
    return float(np.sqrt(np.mean(np.square(amps)))) if amps else 0.0


def polygon_error(records, rows, runs, poly: WheelPolygon | None, settings: WheelSettings = WheelSettings()):
    """Mean square of the consistency channel [(1/m)^2] over the segments of ``runs``,
    after removing the polygon's lines (amplitudes fixed, phases fitted per segment)."""
    tot, n = 0.0, 0
    for _, s, x in _segments([r for r in records if r.run_id in runs], rows["consistency"], settings):
        if poly is not None:
            for wavelength, amplitude in poly.lines:
                k = 1 / wavelength
                phase = np.angle(np.mean(x * np.exp(-2j * np.pi * k * s)))
                x = x - amplitude * np.cos(2 * np.pi * k * s + phase)
        tot += float(np.mean(x * x))
        n += 1
    return tot / max(n, 1)
