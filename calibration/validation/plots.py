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


def plot_every_run(result: ValidationResult, path, window_m: float = 150.0) -> Path:
    """One panel per run: its first channel measured and simulated, and their difference,
    over ``window_m`` in the middle of the compared stretch (a whole run's waves would merge
    into a band), with the run's speed and its NRMSE over the whole stretch."""
    runs = result.runs
    fig, axes = plt.subplots(len(runs), 1, figsize=(12, 1.9 * len(runs) + 0.6), squeeze=False)
    for ax, r in zip(axes[:, 0], runs):
        name = next(iter(r.measured))
        unit = result.units.get(name, "SI")
        comp = next(c for c in r.channels if c.channel == name)
        mid = 0.5 * (r.distance[0] + r.distance[-1])
        w = np.abs(r.distance - mid) <= window_m / 2
        s, m, y = r.distance[w], r.measured[name][w], r.simulated[name][w]
        ax.plot(s, m, lw=0.8, color="0.3", label="measured")
        ax.plot(s, y, lw=0.8, color="tab:red", ls="--", label="simulated")
        ax.plot(s, y - m, lw=0.7, color="tab:blue", label="simulated - measured")
        ax.set_title(f"{r.run_id} at {r.mean_speed:.1f} m/s: {name}, NRMSE {comp.nrmse:.3f}", fontsize=8)
        ax.set_ylabel(f"[{unit}]", fontsize=8)
        ax.set_xlabel("distance along the track recording [m]", fontsize=7)
        ax.tick_params(labelsize=7)
    axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right")
    fig.tight_layout()
    fig.set_dpi(90)
    return save_figure(fig, path)


def plot_frf_phase(cmp: FRFComparison, path, channels: int = 3) -> Path:
    """For the channels of lowest, median and highest FRAC: |H|, its phase and the measured
    coherence, measured against model."""
    order = np.argsort(cmp.frac)
    picks = list(dict.fromkeys(order[np.linspace(0, len(order) - 1, min(channels, len(order))).round().astype(int)]))
    fig, axes = plt.subplots(3, len(picks), figsize=(4 * len(picks), 7), sharex=True, squeeze=False)
    for col, i in enumerate(picks):
        top, mid, low = axes[:, col]
        top.semilogy(cmp.frequency, np.abs(cmp.measured[:, i]), "k-", lw=1, label="measured (H1)")
        top.semilogy(cmp.frequency, np.abs(cmp.model[:, i]), "r--", lw=1, label="calibrated model")
        top.set_title(f"{cmp.sensors[i]}: FRAC {cmp.frac[i]:.3f}", fontsize=9)
        top.set_ylabel("|a / F| [(m/s^2)/N]", fontsize=8)
        mid.plot(cmp.frequency, np.degrees(np.angle(cmp.measured[:, i])), "k-", lw=1)
        mid.plot(cmp.frequency, np.degrees(np.angle(cmp.model[:, i])), "r--", lw=1)
        mid.set_ylabel("phase [deg]", fontsize=8)
        mid.set_ylim(-180, 180)
        if cmp.coherence is not None:
            low.plot(cmp.frequency, cmp.coherence[:, i], "k-", lw=1)
        low.set_ylim(0, 1.05)
        low.set_ylabel("coherence [-]", fontsize=8)
        low.set_xlabel("frequency [Hz]")
        for ax in (top, mid, low):
            ax.grid(True, alpha=0.3)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("FRF from the exciter force: magnitude, phase and the measurement's coherence")
    fig.tight_layout()
    return save_figure(fig, path)
