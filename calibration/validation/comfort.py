"""Ride comfort of the car run over the track recording (EN 12299), beside the measured one.

The validation's simulation (:mod:`.in_service`) also gives the carbody floor's vertical
acceleration: at each floor accelerometer the campaign declares, or, without any, above the
two bogie centres and at the car's centre (EN 12299's floor positions). Model and
measurement are taken over the same stretch, filtered to the recording's wavelengths alike,
and weighted with EN 12299's Wb (:mod:`calibration.signals.comfort`). From them:

* ``n_mv_z``: 6 a_ZP95, the vertical part of the simplified comfort index N_MV (a_ZP95 the
  95th percentile of the 5 s rms). The car's model moves in the vertical plane only, so the
  lateral and longitudinal parts are absent: this is not the whole N_MV;
* ``wz``: Sperling's ride index, vertical.

Both cover only the recording's band (3-25 m for D1: 1.2-10 Hz at 30 m/s), not the full
ride; EN 12299 evaluates 5 min windows, these stretches are what the recording covers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..signals.comfort import n_mv, sperling_wz

BLOCK_S = 5.0  # [s] EN 12299's rms block
MIN_BLOCKS = 4  # fewer whole blocks in a stretch: no comfort figure for it


@dataclass(frozen=True)
class FloorComfort:
    """Comfort at one floor position over one run's stretch."""

    position: str
    x: float  # [m] ahead of the carbody centre
    model: dict  # {"n_mv_z": -, "wz": -}
    measured: dict | None  # the same from the floor accelerometer there; None: none there

    def to_json(self) -> dict:
        return {"x_m": self.x, "model": self.model, "measured": self.measured}


def floor_comfort(position: str, x: float, fs: float, model: np.ndarray,
                  measured: np.ndarray | None) -> FloorComfort | None:
    """Comfort figures of a floor position from its simulated (and measured) vertical
    acceleration [m/s^2] sampled at ``fs`` [Hz]; None when the stretch holds fewer than
    :data:`MIN_BLOCKS` blocks of 5 s."""
    if model.size < MIN_BLOCKS * BLOCK_S * fs:
        return None

    def figures(a):
        return {"n_mv_z": n_mv(fs, z=a, seconds=BLOCK_S)["n_mv"], "wz": sperling_wz(a, fs)}

    return FloorComfort(position, float(x), figures(model), None if measured is None else figures(measured))


def comfort_summary(runs) -> dict:
    """Per floor position: the median over runs of each figure, model and measured, and how
    many runs gave it. ``runs``: each a sequence of :class:`FloorComfort`."""
    out: dict = {}
    for run in runs:
        for c in run:
            out.setdefault(c.position, {"x_m": c.x, "model": [], "measured": []})
            out[c.position]["model"].append(c.model)
            if c.measured is not None:
                out[c.position]["measured"].append(c.measured)
    return {pos: {"x_m": v["x_m"], "runs": len(v["model"]),
                  "model": {k: float(np.median([m[k] for m in v["model"]])) for k in ("n_mv_z", "wz")},
                  "measured": ({k: float(np.median([m[k] for m in v["measured"]])) for k in ("n_mv_z", "wz")}
                               if v["measured"] else None)}
            for pos, v in out.items()}
