"""Figures of an identification: in service (FDD) and of an excitation test (stabilisation
diagram, MAC matrix). They read result objects and compute nothing new."""
from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib.pyplot as plt
from matplotlib.ticker import LogLocator, NullLocator
import numpy as np

from ..data.outputs import save_figure  # noqa: F401  (the one saver; others import it from here too)
from .ema import Mode, Stabilisation, band_lines
from .in_service import InServiceIdentification
from .shapes import SHAPE_ANALYSIS

_COLOURS = {"carbody_bounce": "tab:blue", "carbody_pitch": "tab:orange", "bogie_bounce": "tab:green",
            "bogie_pitch": "tab:red"}


def plot_identification(result: InServiceIdentification, path, *, truth: dict | None = None) -> Path:
    """Summed singular values with the FDD picks, and the input-output FRFs with the fitted
    modes; dotted lines mark ``truth`` frequencies when given (synthetic campaigns)."""
    panels = [n for n in result.fdd.results if n not in ("input_output", SHAPE_ANALYSIS)]  # no peaks picked there
    nrows = 2 if result.frfs else 1
    fig, axes = plt.subplots(nrows, 1, figsize=(10, 4.2 * nrows), squeeze=False)
    ax = axes[0, 0]
    for name in panels:
        r = result.fdd.results[name]
        y = r.singular_values[0] / np.median(r.singular_values[0])
        line, = ax.loglog(r.frequency, y, lw=1, label=f"{name} (N={r.n_used})")
        for fr, _ in result.fdd_peaks.get(name, []):
            k = int(np.argmin(np.abs(r.frequency - fr)))
            ax.plot(fr, y[k], "v", color=line.get_color(), ms=8)
    ax.set_title("Segmental FDD: summed first singular values (normalised), picks marked")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("first singular value / its median [-]")
    ax.set_xlim(result.fdd.settings.band)
    ax.legend(fontsize=7, ncol=2)
    ax.grid(True, which="both", alpha=0.3)
    if result.frfs:
        ax = axes[1, 0]
        for frf in result.frfs.values():
            ax.loglog(frf.frequency, np.abs(frf.H), lw=1, label=frf.description)
        for m in result.modes:
            ax.axvline(m.frequency_hz, color=_COLOURS.get(m.label, "k"), lw=1.5,
                       label=f"{m.label} {m.frequency_hz:.3f} Hz, zeta {m.damping_ratio or float('nan'):.3f}")
        ax.set_title("Segmental input-output: FRFs from the measured rail input, fitted modes")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("|H| [-]")
        ax.set_xlim(result.fdd.settings.band)
        ax.legend(fontsize=7)
        ax.grid(True, which="both", alpha=0.3)
    if truth:
        for a in axes[:, 0]:
            for lbl, f in truth.items():
                a.axvline(f, color=_COLOURS.get(lbl, "k"), ls=":", lw=1)
    fig.tight_layout()
    fig.set_dpi(110)
    return save_figure(fig, path)


def plot_spectra(result: InServiceIdentification, path) -> Path | None:
    """PSD of every channel for slow, middle and fast steady-speed windows (seed Figure 7),
    with the classified spectral lines: tones fixed, speed-dependent lines at each class's
    mean speed."""
    psd = result.psd
    if psd is None:
        return None
    names = list(psd.psd)
    fig, axes = plt.subplots(len(names), 1, figsize=(10, 2.2 * len(names)), sharex=True, squeeze=False)
    colours = ("tab:blue", "tab:orange", "tab:red")
    for ax, name in zip(axes[:, 0], names):
        # the marked lines as one collection per style: hundreds of single axvlines made
        # drawing and the layout take seconds
        across = ax.get_xaxis_transform()  # x in data, y from the bottom (0) to the top (1) of the axes
        for k, (lo, hi) in enumerate(psd.speed_classes):
            ax.semilogy(psd.frequency, psd.psd[name][k], lw=0.8, color=colours[k % 3],
                        label=f"{lo:.0f}-{hi:.0f} m/s")
            v = 0.5 * (lo + hi)
            xs = [v / ln.wavelength_m for ln in result.spectral_lines
                  if ln.kind == "speed_dependent" and ln.wavelength_m and name in ln.channels and ln.wavelength_m < 5]
            if xs:
                ax.vlines(xs, 0, 1, transform=across, colors=colours[k % 3], linestyles=":", lw=0.8)
        tones = [ln.frequency_hz for ln in result.spectral_lines
                 if ln.kind == "speed_independent" and name in ln.channels]
        if tones:
            ax.vlines(tones, 0, 1, transform=across, colors="k", linestyles="--", lw=0.8)
        unit = psd.units.get(name)
        ax.set_ylabel(f"{name}\n[({unit})^2/Hz]" if unit else f"{name}\n[SI^2/Hz]", fontsize=7)
        # a few decades' labels and no minor ticks on y: a tick is several artists, and a
        # PSD spans many decades in nine panels
        ax.yaxis.set_major_locator(LogLocator(numticks=5))
        ax.yaxis.set_minor_locator(NullLocator())
        ax.grid(True, which="major", alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=3, loc="upper right")
    axes[0, 0].set_title("PSD per channel by speed class; dotted: speed-dependent lines, dashed: fixed tones")
    axes[-1, 0].set_xlabel("frequency [Hz]")
    fig.tight_layout()
    fig.set_dpi(100)
    return save_figure(fig, path)


def plot_stabilisation(stab: Stabilisation, frequency: np.ndarray, H: np.ndarray, path, *,
                       modes: Sequence[Mode] | None = None):
    """Stabilisation diagram over sum_o |H_o|^2 (dB, right axis): every kept pole by order,
    marked not stable (o), stable in frequency (.), frequency and damping (x), or all
    including shape (filled circle); vertical lines at ``modes``. Written atomically to
    ``path`` (temporary file in the same folder, then ``os.replace``)."""
    f, Hb, _ = band_lines(frequency, H, stab.band, min_lines=2)
    fig, ax = plt.subplots(figsize=(10, 5.5))
    styles = [("not stable", {"marker": "o", "mfc": "none", "color": "0.6", "ms": 4}),
              ("frequency", {"marker": ".", "color": "tab:blue", "ms": 5}),
              ("frequency + damping", {"marker": "x", "color": "tab:orange", "ms": 5}),
              ("frequency + damping + shape", {"marker": "o", "color": "tab:green", "ms": 4})]
    for level, (label, st) in enumerate(styles):
        xs, ys = [], []
        for op in stab.orders:
            sf_sd = op.stable_frequency & op.stable_damping
            sel = op.stable_frequency.astype(int) + sf_sd + op.stable == level
            xs.extend(op.frequency_hz[sel])
            ys.extend([op.order] * int(sel.sum()))
        ax.plot(xs, ys, ls="none", label=label, **st)
    for m in modes or ():
        ax.axvline(m.frequency_hz, color="k", lw=0.8, ls="--")
    ax.set_xlim(stab.band)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("model order [-]")
    ax.legend(fontsize=8, loc="upper left")
    ax2 = ax.twinx()
    ax2.plot(f, 10 * np.log10(np.maximum(np.sum(np.abs(Hb) ** 2, axis=1), np.finfo(float).tiny)), color="k", lw=1)
    ax2.set_ylabel("sum of |H|^2 [dB]")
    ax.set_title(f"p-LSCF stabilisation (df {100 * stab.freq_tol:g} %, dzeta {100 * stab.damping_tol:g} %, "
                 f"MAC >= {stab.mac_min:g})")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_mac(matrix: np.ndarray, labels_a: Sequence[str], labels_b: Sequence[str], path, *,
             y_name: str = "identified mode", x_name: str = "identified mode"):
    """MAC matrix as a grey-scale image with the values written in; rows ``labels_a``
    (the modes ``y_name`` says), columns ``labels_b`` (``x_name``). Written atomically to
    ``path``."""
    matrix = np.asarray(matrix, float)
    if matrix.shape != (len(labels_a), len(labels_b)):
        raise ValueError(f"MAC matrix {matrix.shape} does not match {len(labels_a)} x {len(labels_b)} labels")
    fig, ax = plt.subplots(figsize=(1.2 + 0.6 * len(labels_b), 1.0 + 0.6 * len(labels_a)))
    ax.imshow(matrix, cmap="Greys", vmin=0, vmax=1)
    for (i, j), v in np.ndenumerate(matrix):
        ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7, color="w" if v > 0.5 else "k")
    ax.set_xticks(range(len(labels_b)), labels_b, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(len(labels_a)), labels_a, fontsize=8)
    ax.set_xlabel(x_name, fontsize=8)
    ax.set_ylabel(y_name, fontsize=8)
    ax.set_title("MAC")
    fig.tight_layout()
    return save_figure(fig, path)
