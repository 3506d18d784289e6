"""From passes to the section's profile: the EN 13848-1 bands, many passes aligned and
combined, and the changes between two profiles of the same line.

**Bands.** Each pass's level is filtered to D1 (3-25 m) and D2 (25-70 m) on its own grid
(zero-phase 4th-order Butterworth, as validation and a recording car filter), and its
first and last two longest wavelengths of the band are dropped, where the filter meets
the pass's ends and the filter starts from its prior. The estimate's error draws
(:func:`~.kalman.infer_pass`) are filtered alike: their rms over the draws and over one
longest wavelength is the band's standard deviation from the model.

**Passes.** A journey's position is its GPS-anchored distance, which wanders by metres.
Every pass is aligned on the longest one by the cross-correlation of their D1 levels
within +-``max_offset``, then all are moved by the mean of those shifts, so the section's
position is the passes' mean rather than any one pass's. Where passes overlap, the levels
are averaged with weights 1 / variance. The standard deviation written is the larger of
the model's (the combination of the passes') and the scatter between the passes (their
standard error, over one longest wavelength), so a model error that differs from pass to
pass shows; one common to every pass (the same calibration) does not.

**Changes.** Two profiles of the same line (earlier, later) are aligned as passes are and
differenced in D1. A settled dip is a raised-cosine trough; the difference is scanned with
that shape, band-filtered alike, for lengths 4-24 m (a matched filter): its least-squares
depth at every position, over the robust spread of that depth along the line, is the
detection's score. The strongest change above ``threshold`` is taken, with its centre,
length and depth, and its fitted shape removed before the next is looked for, so that a
dip's band-filtered side lobes are not taken for rises beside it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.ndimage
import scipy.signal

from ..data.tracks import BAND_WAVELENGTHS_M
from ..signals.peaks import parabolic_shift
from .kalman import PassProfile

BANDS = ("D1", "D2")


def band_filter(x: np.ndarray, band: str, step: float, axis: int = 0) -> np.ndarray:
    lo, hi = BAND_WAVELENGTHS_M[band]
    sos = scipy.signal.butter(4, [1.0 / hi, 1.0 / lo], btype="bandpass", fs=1.0 / step, output="sos")
    return scipy.signal.sosfiltfilt(sos, x, axis=axis)


def _window(band: str, step: float) -> int:
    return max(1, int(round(BAND_WAVELENGTHS_M[band][1] / step)))


@dataclass(frozen=True)
class BandedPass:
    """One pass in a band on its own grid, ends dropped: level and the model's std [m]."""

    run_id: str
    distance: np.ndarray
    level: np.ndarray
    std: np.ndarray


def banded(pp: PassProfile, band: str, step: float) -> BandedPass | None:
    trim = 2 * _window(band, step)
    if pp.level.size <= 2 * trim + _window(band, step):
        return None
    keep = slice(trim, pp.level.size - trim)
    level = band_filter(pp.level, band, step)[keep]
    if pp.error_draws.shape[1]:
        e2 = np.mean(band_filter(pp.error_draws, band, step)[keep] ** 2, axis=1)
        std = np.sqrt(scipy.ndimage.uniform_filter1d(e2, _window(band, step), mode="nearest"))
    else:
        std = np.full(level.size, np.nan)
    return BandedPass(pp.run_id, pp.distance[keep], level, std)


def interp_gapped(at: np.ndarray, d: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` (on ``d``) at ``at``, NaN outside ``d`` and inside its gaps (a spacing over 1.5
    times its median): a profile is not drawn across what it does not cover."""
    y = np.interp(at, d, x, left=np.nan, right=np.nan)
    if d.size > 2:
        i = np.clip(np.searchsorted(d, at), 1, d.size - 1)
        y[(d[i] - d[i - 1]) > 1.5 * np.median(np.diff(d))] = np.nan
    return y


def best_offset(ref_d: np.ndarray, ref: np.ndarray, d: np.ndarray, x: np.ndarray, step: float,
                max_offset: float) -> tuple[float, float]:
    """(offset [m], correlation): the sample of ``x`` at ``d`` lies at ``d + offset`` on
    ``ref``'s axis ``ref_d`` (the shift within +-``max_offset`` that best matches them,
    over what both cover); correlation NaN where they overlap by under 4 ``max_offset``."""
    lo, hi = max(ref_d[0], d[0]), min(ref_d[-1], d[-1])
    if hi - lo < 4 * max_offset:
        return 0.0, float("nan")
    grid = np.arange(lo + max_offset, hi - max_offset, step)
    r = np.nan_to_num(interp_gapped(grid, ref_d, ref))
    lags = np.arange(-int(max_offset / step), int(max_offset / step) + 1)
    score = np.array([np.dot(r, np.nan_to_num(interp_gapped(grid - lag * step, d, x))) for lag in lags])
    norm = np.linalg.norm(r) * np.linalg.norm(np.nan_to_num(interp_gapped(grid, d, x))) + 1e-300
    k = int(np.argmax(score))
    shift = parabolic_shift(score, k) if 0 < k < lags.size - 1 else 0.0
    return float((lags[k] + shift) * step), float(score[k] / norm)


@dataclass(frozen=True)
class SectionProfile:
    """The combined level [m] per band on ``distance`` [m] (NaN where no pass covers it),
    its standard deviation, the number of passes at each point, and each pass's shift [m]
    and correlation with the reference pass."""

    distance: np.ndarray
    level: dict
    std: dict
    passes: dict
    offsets: dict
    correlation: dict


def combine(profiles: list[PassProfile], step: float, *, max_offset: float = 10.0) -> SectionProfile:
    d1 = [b for b in (banded(pp, "D1", step) for pp in profiles) if b is not None]
    if not d1:
        raise ValueError("no pass is long enough for the D1 band")
    ref = max(d1, key=lambda b: b.distance.size)
    offsets, corr = {}, {}
    for b in d1:
        offsets[b.run_id], corr[b.run_id] = (
            (0.0, 1.0) if b is ref else best_offset(ref.distance, ref.level, b.distance, b.level, step, max_offset))
    # a pass that could not be aligned (too little overlap) keeps its own GPS position
    aligned = [k for k in offsets if np.isfinite(corr[k])]
    mean_offset = float(np.mean([offsets[k] for k in aligned]))
    offsets = {k: v - mean_offset if k in aligned else v for k, v in offsets.items()}
    lo = min(pp.distance[0] for pp in profiles) - max_offset
    hi = max(pp.distance[-1] for pp in profiles) + max_offset
    grid = np.arange(np.floor(lo / step) * step, hi, step)
    level, std, count = {}, {}, {}
    for band in BANDS:
        bands = [b for b in (banded(pp, band, step) for pp in profiles) if b is not None and b.run_id in offsets]
        num, den, n = np.zeros(grid.size), np.zeros(grid.size), np.zeros(grid.size, int)
        vals = []
        for b in bands:
            d = b.distance + offsets[b.run_id]
            inside = (grid >= d[0]) & (grid <= d[-1])
            lev = np.where(inside, np.interp(grid, d, b.level), 0.0)
            w = np.where(inside, 1.0 / np.maximum(np.interp(grid, d, b.std), 1e-9) ** 2, 0.0)
            num += w * lev
            den += w
            n += inside
            vals.append((lev, w))
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(n > 0, num / den, np.nan)
            formal = np.where(n > 0, 1.0 / np.sqrt(den), np.nan)
            spread = sum(w * (lev - np.nan_to_num(mean)) ** 2 for lev, w in vals) / den if vals else formal * 0
            scatter = np.sqrt(scipy.ndimage.uniform_filter1d(np.nan_to_num(spread / np.maximum(n - 1, 1)),
                                                             _window(band, step), mode="nearest"))
        level[band] = mean
        std[band] = np.where(n >= 2, np.maximum(formal, scatter), formal)
        count[band] = n
    return SectionProfile(grid, level, std, count, offsets, corr)


@dataclass(frozen=True)
class Change:
    """A settled dip (``depth`` > 0 [m]) or a rise (< 0) found between two profiles."""

    centre: float
    length: float
    depth: float
    score: float

    def to_json(self) -> dict:
        return {"centre_m": self.centre, "length_m": self.length, "depth_mm": 1e3 * self.depth,
                "score": self.score}


def _dip(length: float, step: float) -> np.ndarray:
    x = np.arange(-np.ceil(length / 2 / step), np.ceil(length / 2 / step) + 1) * step
    return np.where(np.abs(x) < length / 2, 0.5 * (1 + np.cos(2 * np.pi * x / length)), 0.0)


def changes(distance: np.ndarray, before: np.ndarray, after: np.ndarray, step: float, *,
            lengths=(4.0, 6.0, 8.0, 10.0, 12.0, 16.0, 20.0, 24.0), threshold: float = 6.0,
            most: int = 50) -> tuple[list[Change], np.ndarray]:
    """Dips and rises in ``after - before`` (D1 levels on ``distance``, NaN where not covered):
    the changes found and the difference. The strongest is taken and its fitted shape
    removed before the next is looked for, so a dip's band-filtered side lobes are not
    reported as rises beside it."""
    diff = after - before
    ok = np.isfinite(diff)
    d = np.where(ok, diff, 0.0)
    pad = 4 * _window("D1", step)
    templates = [(length, band_filter(np.pad(_dip(length, step), pad), "D1", step)) for length in lengths]
    # a position counts where the shape and one longest D1 wavelength either side are covered
    valid = []
    for length, _ in templates:
        half = int((length / 2 + BAND_WAVELENGTHS_M["D1"][1]) / step)
        valid.append(scipy.ndimage.minimum_filter1d(ok.astype(np.int8), 2 * half + 1, mode="constant") > 0)
    if not any(v.any() for v in valid):
        return [], diff
    spreads = []
    for (_, t), v in zip(templates, valid):  # the robust spread of each length's depth estimate along the line
        amp = -scipy.signal.correlate(d, t, mode="same")[v] / np.dot(t, t)
        spreads.append(max(1.4826 * np.median(np.abs(amp - np.median(amp))), 1e-12) if amp.size else np.inf)
    found = []
    for _ in range(most):
        best = (0.0, 0, 0, 0.0)  # score, position, template, depth
        for j, (length, t) in enumerate(templates):
            amp = -scipy.signal.correlate(d, t, mode="same") / np.dot(t, t)
            score = np.where(valid[j], amp / spreads[j], 0.0)
            i = int(np.argmax(np.abs(score)))
            if abs(score[i]) > abs(best[0]):
                best = (float(score[i]), i, j, float(amp[i]))
        score, i, j, depth = best
        if abs(score) < threshold:
            break
        # the shape that explains most of the difference there: the score favours short shapes
        # (their depth is the less certain, but the spread is measured along the whole line)
        near = slice(max(0, i - int(6.0 / step)), i + int(6.0 / step) + 1)
        fits = []
        for jj, (_, t) in enumerate(templates):
            amp = np.where(valid[jj], -scipy.signal.correlate(d, t, mode="same") / np.dot(t, t), 0.0)[near]
            ii = int(np.argmax(np.abs(amp)))
            fits.append((amp[ii] ** 2 * np.dot(t, t), near.start + ii, jj, float(amp[ii])))
        _, i, j, depth = max(fits)
        found.append(Change(float(distance[i]), templates[j][0], depth, score))
        t = templates[j][1]
        half = t.size // 2
        lo, hi = max(0, i - half), min(d.size, i + half + 1)
        d[lo:hi] += depth * t[half - (i - lo):half + (hi - i)]
    return found, diff
