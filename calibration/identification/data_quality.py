"""What an identification found of its campaign's data: each run's size, gaps and invalid
samples, and each channel's noise floor (:mod:`calibration.signals.noise_floor`)."""
from __future__ import annotations

import numpy as np

from ..signals.noise_floor import NoiseFloorSettings


def run_report(run) -> dict:
    """What the reader found in one run: size, gaps (never interpolated), invalid samples."""
    speed = run.speed
    return {
        "run": run.run_id, "samples": len(run), "duration_s": float(run.time[-1] - run.time[0]),
        "distance_m": None if run.distance is None else [float(run.distance[0]), float(run.distance[-1])],
        "speed_m_s": None if speed is None else [float(np.nanmin(speed)), float(np.nanmax(speed))],
        "gaps": [{"after_time_s": g.after_time, "before_time_s": g.before_time, "duration_s": g.duration}
                 for g in run.gaps],
        "invalid_samples": {ch: int((~ok).sum()) for ch, ok in run.valid.items() if (~ok).any()},
    }


def noise_band(low_hz: float, fs: float, settings: NoiseFloorSettings,
               resolution_hz: float | None = None) -> tuple[float, float] | None:
    """[Hz] the band a spectral floor is read over: from ``low_hz`` (above the modes analysed)
    to ``settings.top_fraction`` of the sampling rate ``fs`` [Hz] (below the anti-alias
    filter's roll-off), with at least four lines of the spectrum it is read from (line spacing
    ``resolution_hz``; default: ``settings.segment_s``'s) in it; None when there is no such band."""
    top = settings.top_fraction * fs
    step = 1.0 / settings.segment_s if resolution_hz is None else resolution_hz
    return (float(low_hz), float(top)) if top - low_hz >= 4.0 * step else None
