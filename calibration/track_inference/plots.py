"""The inferred profile's figure: D1 and D2 levels with their 2-sigma bands over the line,
and a 200 m close-up of D1. It reads the result and computes nothing new."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..data.outputs import save_figure
from .profile import BANDS


def plot_profile(result, path) -> Path:
    s = result.section
    fig, axes = plt.subplots(3, 1, figsize=(12, 9))
    for ax, band in zip(axes, BANDS):
        ok = s.passes[band] > 0
        d, z, e = s.distance[ok], 1e3 * s.level[band][ok], 1e3 * s.std[band][ok]
        ax.fill_between(d, z - 2 * e, z + 2 * e, color="0.8", lw=0, label="+-2 standard deviations")
        ax.plot(d, z, lw=0.6, label=f"{band} level")
        ax.set_xlabel("distance [m]")
        ax.set_ylabel(f"{band} level [mm]")
        ax.legend(fontsize=7, loc="upper right")
    ok = s.passes["D1"] > 0
    mid = s.distance[ok][ok.sum() // 2]
    near = ok & (np.abs(s.distance - mid) < 100.0)
    ax = axes[2]
    ax.fill_between(s.distance[near], 1e3 * (s.level["D1"][near] - 2 * s.std["D1"][near]),
                    1e3 * (s.level["D1"][near] + 2 * s.std["D1"][near]), color="0.8", lw=0)
    ax.plot(s.distance[near], 1e3 * s.level["D1"][near], lw=0.8)
    for c in result.changes or ():
        for a in axes[:1]:
            a.axvline(c.centre, color="C3", lw=0.8)
    ax.set_xlabel("distance [m]")
    ax.set_ylabel("D1 level, 200 m [mm]")
    fig.suptitle(f"track level under the leading bogie, {len(result.passes)} passes ({', '.join(result.sensors)})",
                 fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)
