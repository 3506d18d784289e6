"""Irregularly sampled blocks onto a uniform grid.

The campaign format makes the time column authoritative and allows irregular sampling
(logger clocks jitter; some loggers timestamp each sample). Spectral estimates need equal
steps, so a contiguous block (no gap: the reader splits runs at gaps) is put onto a
uniform grid by a cubic spline through the samples at their recorded instants. For a
25 Hz sine at 500 Hz its error is 2.6e-5 of the amplitude with even steps ((2 pi f h)^4 /
384) and, measured, 5.6e-6 with +-0.05 and 4.4e-4 with +-0.45 sample jitter (uneven steps
raise the constant): the vehicle's band is reconstructed to 0.1 % with its timing. The
derived channels (a differentiated gyro, a rail signal delayed over distance) must be
formed on the uniform grid, not on the jittered samples: formed before, they cost the
carbody band so much coherence that a 0.91 Hz carbody bounce was fitted at 3.4 Hz.
Samples are never invented across a gap.

Times in s, rates in Hz.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.interpolate
import scipy.ndimage

# A step differing from the nominal one by less than this share of it counts as regular:
# times written with 9 significant digits (CSV) wobble by up to 0.5 % of a 500 Hz step in a
# run of 1000-10000 s, and 1 % of a step (20 us) turns a 25 Hz wave by 0.003 rad.
REGULAR_TOLERANCE = 1e-2


def is_regular(t: np.ndarray, fs: float) -> bool:
    """True if the steps of ``t`` [s] all equal 1 / ``fs`` to within REGULAR_TOLERANCE of a step."""
    return t.size < 2 or bool(np.max(np.abs(np.diff(t) * fs - 1.0)) <= REGULAR_TOLERANCE)


def to_uniform_grid(t: np.ndarray, x: np.ndarray, fs: float, *, axis: int = -1) -> tuple[np.ndarray, np.ndarray]:
    """Samples ``x`` taken at instants ``t`` [s] (strictly increasing, one gap-free block),
    re-sampled at ``t[0] + k / fs`` up to ``t[-1]`` by a cubic spline along ``axis``.

    Returns (t_uniform [s], x_uniform)."""
    t = np.asarray(t, float)
    if t.size < 4:
        raise ValueError(f"a block of {t.size} samples is too short to re-sample (4 needed)")
    n = int(np.floor((t[-1] - t[0]) * fs * (1 + 1e-12))) + 1
    t_uniform = t[0] + np.arange(n) / fs
    return t_uniform, scipy.interpolate.CubicSpline(t, x, axis=axis)(t_uniform)


def regular_run(run, fs: float):
    """``run`` (a :class:`calibration.data.campaign.Run`) with every irregularly sampled
    gap-free block re-sampled at ``fs`` [Hz] (or at its own median rate, where that differs
    from ``fs`` by more than 1 %), by :func:`to_uniform_grid`. Regular runs are returned
    as they are.

    Everything downstream (derived channels that differentiate a gyro or delay a rail
    signal over distance, filters, Welch) then works on equal steps, as with a regular
    logger. A re-sampled point is invalid if a missing or clipped sample lies within two
    samples of it (the spline's reach beyond that is under 10 % per sample and decaying);
    invalid samples are bridged linearly before the spline so that they spoil only their
    neighbours. Gaps stay gaps: each block is re-sampled on its own, and a block of fewer
    than 4 samples, too short for any analysis, is left out."""
    if all(is_regular(run.time[a:b], fs) for a, b in run.blocks):
        return run
    pieces = []
    for a, b in run.blocks:
        t = run.time[a:b]
        if is_regular(t, fs):
            idx = np.arange(a, b)
            pieces.append((t, {n: x[idx] for n, x in run.channels.items()},
                           {n: v[idx] for n, v in run.valid.items()},
                           None if run.distance is None else run.distance[idx],
                           None if run.speed is None else run.speed[idx]))
            continue
        if b - a < 4:
            continue
        rate = 1.0 / float(np.median(np.diff(t)))
        rate = fs if abs(rate / fs - 1) < 0.01 else rate
        tu, _ = to_uniform_grid(t, t, rate)
        j = np.clip(np.searchsorted(t, tu), 1, t.size - 1)  # t[j - 1] <= tu < t[j]
        channels, valid = {}, {}
        for name, x in run.channels.items():
            ok = run.valid[name][a:b] & np.isfinite(x[a:b])
            if not ok.any():
                channels[name], valid[name] = np.full(tu.size, np.nan), np.zeros(tu.size, bool)
                continue
            xb = np.where(ok, x[a:b], np.interp(t, t[ok], x[a:b][ok]))
            bad = scipy.ndimage.binary_dilation(~ok, iterations=2)
            channels[name] = to_uniform_grid(t, xb, rate)[1]
            valid[name] = ~(bad[j - 1] | bad[j])
        distance = None if run.distance is None else np.interp(tu, t, run.distance[a:b])
        speed = None
        if run.speed is not None:
            v = run.speed[a:b]
            fin = np.isfinite(v)
            speed = np.interp(tu, t[fin], v[fin]) if fin.any() else np.full(tu.size, np.nan)
        pieces.append((tu, channels, valid, distance, speed))
    sizes = np.cumsum([0] + [p[0].size for p in pieces])
    cat = lambda k: np.concatenate([p[k] for p in pieces])  # noqa: E731
    return dataclasses.replace(
        run, time=cat(0),
        channels={n: np.concatenate([p[1][n] for p in pieces]) for n in run.channels},
        valid={n: np.concatenate([p[2][n] for p in pieces]) for n in run.valid},
        blocks=tuple((int(sizes[k]), int(sizes[k + 1])) for k in range(len(pieces))),
        distance=None if run.distance is None else cat(3), speed=None if run.speed is None else cat(4))
