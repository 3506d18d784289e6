"""Figures of an excitation-test diagnosis (:class:`.result.ExcitationDiagnosis`): the
held-out FRFs measured and modelled before and after the extension on the channels the
baseline misses most, and the MAC of the identified modes against the model's."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ...data.outputs import save_figure
from .result import ExcitationDiagnosis


def plot_excitation_diagnosis(result: ExcitationDiagnosis, stem, channels: int = 6) -> list[Path]:
    """Write ``<stem>_frf.png`` (the ``channels`` the baseline misses most) and
    ``<stem>_mac.png``; returns their paths."""
    stem = Path(stem)
    return [_frf(result, stem.with_name(stem.name + "_frf.png"), channels),
            _mac(result, stem.with_name(stem.name + "_mac.png"))]


def _frf(result: ExcitationDiagnosis, path: Path, channels: int) -> Path:
    f = result.measured.frequency
    ext = result.extension
    before = np.asarray(result.evidence.heldout.error)
    order = np.argsort(-before)[:channels]  # the channels the baseline misses most
    cols = 2 if len(order) > 1 else 1
    rows = int(np.ceil(len(order) / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(12, 2.8 * rows), sharex=True, squeeze=False)
    for ax, i in zip(axes.ravel(), order):
        ax.semilogy(f, np.abs(result.measured.H[:, i]), "k-", lw=1.0, label="measured, held out (H1)")
        ax.semilogy(f, np.abs(result.evidence.heldout.H[:, i]), "--", color="tab:red", lw=0.9,
                    label="calibrated box model")
        title = f"{result.sensors[i]}: error {before[i]:.1f}"
        if ext is not None:
            ax.semilogy(f, np.abs(ext.heldout.H[:, i]), "-", color="tab:blue", lw=0.9, label=f"with {ext.name}")
            title += f" -> {ext.heldout.error[i]:.2f}"
        ax.set_title(title + " x noise", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes.ravel()[len(order):]:
        ax.axis("off")
    for ax in axes[-1]:
        ax.set_xlabel("frequency [Hz]")
    for ax in axes.ravel()[:len(order)]:  # each panel its own scale: each channel its own level
        ax.set_ylabel("|a / F| [(m/s^2)/N]", fontsize=8)
    axes[0, 0].legend(fontsize=7)
    fig.suptitle(f"held-out FRFs, exciter force to floor accelerations; cause: {result.cause}", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def _mac(result: ExcitationDiagnosis, path: Path) -> Path:
    base = result.evidence.modes
    panels = [("calibrated box model", base.mac, base.cols)]
    if result.extension_modes is not None:
        panels.append((f"with {result.extension.name}", result.extension_modes.mac, result.extension_modes.cols))
    rows = base.rows
    width = sum(1.5 + 0.45 * len(c) for _, _, c in panels)
    fig, axes = plt.subplots(1, len(panels), figsize=(max(width, 5), 1.5 + 0.45 * max(len(rows), 1)), squeeze=False)
    for ax, (title, mac, cols) in zip(axes[0], panels):
        mac = np.asarray(mac, float)
        ax.imshow(mac, cmap="Greys", vmin=0, vmax=1, aspect="auto")
        for (i, j), v in np.ndenumerate(mac):
            if v >= 0.1:
                ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=6, color="w" if v > 0.5 else "k")
        ax.set_xticks(range(len(cols)), cols, rotation=60, ha="right", fontsize=7)
        ax.set_yticks(range(len(rows)), rows, fontsize=7)
        ax.set_xlabel("model mode")
        ax.set_ylabel("identified mode")
        ax.set_title(f"MAC, identified (training) x {title}", fontsize=9)
    fig.tight_layout()
    return save_figure(fig, path)
