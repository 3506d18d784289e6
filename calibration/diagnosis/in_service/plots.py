"""Figures of an in-service diagnosis, read from its result: the residual PSD before and
after the extension, and the baseline residual's speed-frequency map (a line fixed in
frequency is vertical there, a line proportional to speed a ray through the origin)."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib.pyplot as plt
import numpy as np

from ...models.car2d import wheelset_dynamic_stiffness
from ...data.outputs import save_figure
from .response import response_nrp
from .track import transmissibility2

if TYPE_CHECKING:
    from .result import InServiceDiagnosis

#: a model output's PSD unit by its kind (:class:`~calibration.models.car2d.Output`), SI
PSD_UNITS = {"displacement": "m^2/Hz", "velocity": "(m/s)^2/Hz", "acceleration": "(m/s^2)^2/Hz",
             "pitch_angle": "rad^2/Hz", "pitch_rate": "(rad/s)^2/Hz"}


def plot_diagnosis(diagnosis: InServiceDiagnosis, stem) -> list[Path]:
    """``<stem>_residual_psd.png`` and ``<stem>_speed_map.png``; returns their paths."""
    stem = Path(stem)
    return [_residual_psd(diagnosis, stem.with_name(stem.name + "_residual_psd.png")),
            _speed_map(diagnosis, stem.with_name(stem.name + "_speed_map.png"))]


def _wheel_line(d: InServiceDiagnosis, path: Path) -> Path:
    """The held-out runs' consistency spectrum over wavenumber, with the fitted wheel line."""
    spec = d.best.heldout_line_spectrum
    fig, ax = plt.subplots(figsize=(9, 4.5))
    ax.semilogy(spec.wavenumber, spec.power, lw=0.8, label="axle-box consistency (held-out runs)")
    ax.semilogy(spec.wavenumber, spec.floor, lw=0.8, ls="--", label="floor (running median)")
    lam = d.best.parameters["wavelength_m"]
    ax.axvline(1 / lam, color="tab:red", lw=0.8, label=f"fitted wheel line, {lam:.3f} m")
    ax.set_xlim(0, 1 / d.settings.wheels.wavelengths_m[0])
    ax.set_xlabel("wavenumber [1/m]")
    ax.set_ylabel("power [(1/m)^2 per bin]")
    ax.set_title(f"cause: {d.cause}")
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def _track_collapse(d: InServiceDiagnosis, path: Path) -> Path:
    """Axle box 1's held-out level spectra per speed: as measured on a rigid rail, and
    through the fitted track."""
    stats, fit = d.statistics, d.best.fit
    f, bw = stats.centres, np.diff(stats.edges)
    keys = {k for k in stats.S if k[0] in d.heldout_runs}
    fig, ax = plt.subplots(figsize=(9, 4.5))
    i = stats.channels.index("axle1_mean")
    t2 = transmissibility2(f, wheelset_dynamic_stiffness(fit.vehicle, f, 1), fit.f_t, fit.zeta, fit.mass)
    for vb in stats.speed_bins:
        kk = stats.ordered({k for k in keys if k[1] == vb})
        if not kk:
            continue
        v = vb + d.settings.records.speed_bin / 2
        P = sum(stats.S[k][:, i, i].real for k in kk) / stats.seconds_of(kk) / bw
        kap = f / v
        line, = ax.loglog(kap, P * v / (2 * np.pi * f) ** 4, lw=0.6, label=f"{v:.0f} m/s, as measured")
        ax.loglog(kap, P * v / (2 * np.pi * f) ** 4 / t2, lw=1.2,
                  color=line.get_color(), ls="--")
    ax.set_xlabel("wavenumber [1/m]")
    ax.set_ylabel("level PSD [m^2 / (1/m)]")
    ax.set_title(f"axle box 1: rigid-rail collapse (solid) and with the fitted track "
                 f"({fit.f_t:.1f} Hz, zeta {fit.zeta:.2f}, {fit.mass:.0f} kg, dashed)", fontsize=9)
    ax.legend(fontsize=7)
    return save_figure(fig, path)


def _residual_psd(d: InServiceDiagnosis, path: Path) -> Path:
    best = d.best
    if best is not None and best.kind == "wheel":
        return _wheel_line(d, path)
    if best is not None and best.kind == "track":
        return _track_collapse(d, path)
    stats, lay, base = d.statistics, d.layout, d.baseline
    keys = {k for k in stats.S if k[0] in d.heldout_runs}
    f, bw = stats.centres, np.diff(stats.edges)
    secs = stats.seconds_of(keys)
    R0, P = response_nrp(stats, lay, keys, base, by_band=True)
    R1 = R2 = None
    if best is not None:
        R1, _ = response_nrp(stats, lay, keys, best.fit, by_band=True)
    # with no cause named, the model the diagnosis ends with (its properties): what it still
    # gets wrong; a vehicle cause's fit is that model already
    if best is None and d.extended is not None:
        R2, _ = response_nrp(stats, lay, keys, d.extended, by_band=True)
    n = len(lay.responses)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.2 * n), sharex=True, squeeze=False)
    for c, ax in enumerate(axes[:, 0]):
        ax.loglog(f, P[:, c] / bw / secs, color="0.6", lw=0.8, label="measured")
        ax.loglog(f, R0[:, c] / bw / secs, color="tab:red", lw=0.9, label="residual, baseline")
        if R1 is not None:
            ax.loglog(f, R1[:, c] / bw / secs, color="tab:blue", lw=0.9, label=f"residual, with {best.name}")
        if R2 is not None:
            ax.loglog(f, R2[:, c] / bw / secs, color="tab:green", lw=0.9, label="residual, with every finding")
        ax.set_ylabel(f"{lay.response_names[c]}\n[{PSD_UNITS[lay.responses[c].kind]}]", fontsize=7)
    axes[0, 0].legend(fontsize=7)
    axes[0, 0].set_title(f"held-out runs, residual PSD; cause: {d.cause}", fontsize=9)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    return save_figure(fig, path)


def _speed_map(d: InServiceDiagnosis, path: Path) -> Path:
    stats, base, best = d.statistics, d.baseline, d.best
    f, bw = stats.centres, np.diff(stats.edges)
    bins = stats.speed_bins
    if best is not None and best.kind in ("wheel", "track"):
        name = "consistency" if best.kind == "wheel" else "axle1_mean"
        i = stats.channels.index(name)
        rows = [sum(stats.S[k][:, i, i].real for k in stats.S if k[1] == vb)
                / stats.seconds_of({k for k in stats.S if k[1] == vb}) / bw for vb in bins]
        label, unit = f"{name} PSD", PSD_UNITS["acceleration"]
    else:
        ch = d.evidence.channels
        name = max(ch, key=lambda n: max([p["over_floor"] for p in ch[n]["peaks"]] + [ch[n]["input_coherence"]]))
        c = d.layout.response_names.index(name)
        rows = []
        for vb in bins:
            keys = {k for k in stats.S if k[1] == vb}
            R, _ = response_nrp(stats, d.layout, keys, base, by_band=True)
            rows.append(R[:, c] / bw / stats.seconds_of(keys))
        label, unit = f"{name}: baseline residual PSD", PSD_UNITS[d.layout.responses[c].kind]
    fig, ax = plt.subplots(figsize=(9, 4.5))
    v = np.array(bins) + d.settings.records.speed_bin / 2
    img = np.log10(np.maximum(np.array(rows), 1e-300))
    mesh = ax.pcolormesh(f, v, img, shading="nearest", cmap="viridis",
                         vmin=np.percentile(img, 5), vmax=img.max())
    ax.set_xscale("log")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("speed bin [m/s]")
    ax.set_title(f"speed-frequency map, {label} (log10)", fontsize=9)
    fig.colorbar(mesh, ax=ax, label=f"log10 PSD [{unit}]")
    return save_figure(fig, path)
