"""Figures of a validation: measured against simulated responses in service, and measured
against model FRFs of an excitation test. They read result objects and compute nothing new."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import scipy.signal

from ..data.outputs import save_figure
from .excitation import FRFComparison
from .in_service import STEP_M, ValidationResult


def plot_validation(result: ValidationResult, path) -> Path:
    r = max(result.runs, key=lambda r: r.distance_range[1] - r.distance_range[0])
    names = list(r.measured)
    fig, axes = plt.subplots(len(names), 2, figsize=(12, 3 * len(names)), squeeze=False)
    for k, name in enumerate(names):
        ax = axes[k, 0]
        ax.plot(r.distance, r.measured[name], lw=0.8, label="measured")
        ax.plot(r.distance, r.simulated[name], lw=0.8, label="simulated")
        ax.set_title(f"{r.run_id}: {name}, band {result.band_m[0]:g}-{result.band_m[1]:g} m")
        unit = result.units.get(name, "SI")
        ax.set_xlabel("distance [m]")
        ax.set_ylabel(f"{name} [{unit}]", fontsize=8)
        ax.legend(fontsize=7)
        ax = axes[k, 1]
        nper = min(len(r.distance), int(4 * result.band_m[1] / STEP_M))
        for label, x in (("measured", r.measured[name]), ("simulated", r.simulated[name])):
            nu, P = scipy.signal.welch(x, fs=1 / STEP_M, nperseg=nper)
            sel = nu > 0
            ax.loglog(1 / nu[sel], P[sel], lw=0.8, label=label)
        ax.axvspan(*result.band_m, color="0.9")
        ax.set_xlabel("wavelength [m]")
        ax.set_ylabel(f"PSD [({unit})^2 m]", fontsize=8)
        ax.set_title("PSD over spatial frequency")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.set_dpi(100)
    return save_figure(fig, path)


def plot_frf_comparison(cmp: FRFComparison, path, channels: int = 9) -> Path:
    """|H| measured and model for up to ``channels`` accelerometers (as seed Figure 9)."""
    idx = np.linspace(0, len(cmp.sensors) - 1, min(channels, len(cmp.sensors))).round().astype(int)
    cols = 3
    rows = int(np.ceil(len(idx) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.6 * rows), sharex=True, squeeze=False)
    for ax, i in zip(axes.ravel(), idx):
        ax.semilogy(cmp.frequency, np.abs(cmp.measured[:, i]), "k-", lw=1, label="measured (H1)")
        ax.semilogy(cmp.frequency, np.abs(cmp.model[:, i]), "r--", lw=1, label="calibrated model")
        ax.set_title(f"{cmp.sensors[i]}: FRAC {cmp.frac[i]:.3f}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.ravel()[len(idx):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    axes[0, 0].set_ylabel("|a / F| [(m/s^2)/N]")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle("FRF gain from the exciter force to the floor accelerations")
    fig.tight_layout()
    return save_figure(fig, path)
