"""Figures of a calibration's global search, from its result file's content: the
Cross-Entropy runs' parameter means and convergence measure per generation (the in-service
seed's Figures 10 and 11), or the particle swarm's best evaluation value per iteration (the
carbody seed's Figure 7)."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from .data.outputs import save_figure


def plot_convergence(calibration: dict, path) -> Path | None:
    """The search's convergence figure at ``path``; None when the result holds no history."""
    runs = [r for r in calibration.get("runs") or [] if r.get("history", {}).get("best_objective")]
    if runs and all(r["history"].get("mean") for r in runs):
        return _cross_entropy(calibration, runs, path)
    if runs:
        return _best_per_iteration(runs, path)
    history = (calibration.get("pso") or {}).get("history_pct")
    if history:
        return _swarm(calibration, history, path)
    return None


def _best_per_iteration(runs: list, path) -> Path:
    """The car's swarm runs: each one's best objective per iteration."""
    fig, ax = plt.subplots(figsize=(9, 4))
    for r in runs:
        best = np.maximum(r["history"]["best_objective"], 1e-300)
        ax.semilogy(np.arange(len(best)), best, lw=0.8, alpha=0.7)
    ax.set_xlabel("iteration [-]")
    ax.set_ylabel("best objective [-]")
    ax.set_title(f"particle swarm: {len(runs)} runs, each one's best objective", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def _cross_entropy(calibration: dict, runs: list, path) -> Path:
    names = list(runs[0]["parameters"])
    final = calibration["parameters"]
    fig, axes = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    colours = plt.get_cmap("tab10")
    for k, r in enumerate(runs):
        mean = np.array(r["history"]["mean"])  # (generations, parameters)
        g = np.arange(1, mean.shape[0] + 1)
        for j, name in enumerate(names):
            axes[0].plot(g, mean[:, j] / final[name], color=colours(j), lw=0.8, alpha=1.0 if k == 0 else 0.35,
                         label=name if k == 0 else None)
        axes[1].semilogy(g, np.maximum(r["history"]["change"], 1e-300), color="0.3", lw=0.7, alpha=0.6,
                         label="C_g, change of the sampling mean" if k == 0 else None)
        axes[1].semilogy(g, np.maximum(r["history"]["best_objective"], 1e-300), color="tab:red", lw=0.7, alpha=0.6,
                         label="best objective of the elite" if k == 0 else None)
    axes[0].set_ylabel("sampling mean / calibrated value [-]")
    axes[0].set_title(f"Cross-Entropy: {len(runs)} runs (the first bold); each parameter's sampling mean", fontsize=9)
    axes[0].legend(fontsize=7, ncol=3)
    axes[1].set_ylabel("C_g [SI], objective [-]")
    axes[1].set_xlabel("generation [-]")
    axes[1].legend(fontsize=7)
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)


def _swarm(calibration: dict, history: list, path) -> Path:
    pso = calibration["pso"]
    fig, ax = plt.subplots(figsize=(9, 4))
    ax.semilogy(np.arange(len(history)), history, color="tab:blue", lw=1, label="best evaluation value")
    ax.axhline(pso.get("done_pct", pso.get("stop_pct")), color="k", ls="--", lw=0.8, label="done at")
    if calibration.get("refinement"):
        ax.axhline(calibration["max_error_pct"], color="tab:red", ls=":", lw=1, label="after the refinement")
    ax.set_xlabel("iteration [-]")
    ax.set_ylabel("largest frequency error [%]")
    ax.set_title(f"particle swarm: {pso['particles']} particles; the kept swarm's best value "
                 f"({len(pso.get('swarms') or [1])} swarm(s) in all)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    return save_figure(fig, path)
