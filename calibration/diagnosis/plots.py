"""Figures of a diagnosis: residual PSD before and after the extension, and the baseline
residual's speed-frequency map (a line fixed in frequency is vertical there, a line
proportional to speed a ray through the origin)."""
from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ..data.outputs import save_figure
from .response import response_nrp
from .track import fit_track, transmissibility2
from .wheels import line_spectrum


def plot_diagnosis(result: dict, stem) -> list[Path]:
    stem = Path(stem)
    ctx, base_fit, best = result["_plot"]["ctx"], result["_plot"]["base_fit"], result["_plot"]["best"]
    return [_residual_psd(result, ctx, base_fit, best, stem.with_name(stem.name + "_residual_psd.png")),
            _speed_map(result, ctx, base_fit, best, stem.with_name(stem.name + "_speed_map.png"))]


def _response_after(ctx, best):
    from .extensions import EXTENSIONS
    from .response import fit_response

    ext = EXTENSIONS[best["name"]]
    return fit_response(ctx.stats, ctx.lay, {k for k in ctx.stats.S if k[0] in ctx.train}, ctx.base, ctx.bounds,
                        ext.params, ext.make, starts=ctx.settings.starts)


def _residual_psd(result, ctx, base_fit, best, path) -> Path:
    keys = {k for k in ctx.stats.S if k[0] in ctx.test}
    f = ctx.stats.centres
    bw = np.diff(ctx.stats.edges)
    secs = sum(ctx.stats.seconds[k] for k in keys)
    if best is not None and best["kind"] == "wheel":
        spec_b = line_spectrum(ctx.records, ctx.rows, ctx.test, ctx.settings.wheels)
        fig, ax = plt.subplots(figsize=(9, 4.5))
        ax.semilogy(spec_b.wavenumber, spec_b.power, lw=0.8, label="axle-box consistency (held-out runs)")
        ax.semilogy(spec_b.wavenumber, spec_b.floor, lw=0.8, ls="--", label="floor (running median)")
        lam = best["parameters"]["wavelength_m"]
        ax.axvline(1 / lam, color="tab:red", lw=0.8, label=f"fitted wheel line, {lam:.3f} m")
        ax.set_xlim(0, 1 / ctx.settings.wheels.wavelengths[0])
        ax.set_xlabel("wavenumber [1/m]")
        ax.set_ylabel("power [(1/m)^2 per bin]")
        ax.set_title(f"cause: {result['cause']}")
        ax.legend(fontsize=8)
        return save_figure(fig, path)
    if best is not None and best["kind"] == "track":
        fig, ax = plt.subplots(figsize=(9, 4.5))
        fit = fit_track(ctx.stats, {k for k in ctx.stats.S if k[0] in ctx.train}, True, ctx.settings.track)
        i = ctx.stats.channels.index("axle1_mean")
        for vb in ctx.stats.speed_bins:
            kk = [k for k in keys if k[1] == vb]
            if not kk:
                continue
            v = vb + ctx.settings.records.speed_bin / 2
            P = sum(ctx.stats.S[k][:, i, i].real for k in kk) / sum(ctx.stats.seconds[k] for k in kk) / bw
            kap = f / v
            line, = ax.loglog(kap, P * v / (2 * np.pi * f) ** 4, lw=0.6, label=f"{v:.0f} m/s, as measured")
            ax.loglog(kap, P * v / (2 * np.pi * f) ** 4 / transmissibility2(f, fit.f_t, fit.zeta), lw=1.2,
                      color=line.get_color(), ls="--")
        ax.set_xlabel("wavenumber [1/m]")
        ax.set_ylabel("level PSD [m^2 / (1/m)]")
        ax.set_title(f"axle box 1: rigid-rail collapse (solid) and with the fitted track "
                     f"({fit.f_t:.1f} Hz, zeta {fit.zeta:.2f}, dashed)", fontsize=9)
        ax.legend(fontsize=7)
        return save_figure(fig, path)
    R0, P = response_nrp(ctx.stats, ctx.lay, keys, base_fit.parameters, base_fit.extras, base_fit.sensors, by_band=True)
    after = _response_after(ctx, best) if best is not None else None
    n = len(ctx.lay.responses)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.2 * n), sharex=True, squeeze=False)
    for c, ax in enumerate(axes[:, 0]):
        ax.loglog(f, P[:, c] / bw / secs, color="0.6", lw=0.8, label="measured")
        ax.loglog(f, R0[:, c] / bw / secs, color="tab:red", lw=0.9, label="residual, baseline")
        if after is not None:
            R1, _ = response_nrp(ctx.stats, ctx.lay, keys, after.parameters, after.extras, after.sensors, by_band=True)
            ax.loglog(f, R1[:, c] / bw / secs, color="tab:blue", lw=0.9, label=f"residual, with {best['name']}")
        ax.set_ylabel(ctx.lay.response_names[c], fontsize=7)
    axes[0, 0].legend(fontsize=7)
    axes[0, 0].set_title(f"held-out runs, residual PSD; cause: {result['cause']}", fontsize=9)
    axes[-1, 0].set_xlabel("frequency [Hz]")
    return save_figure(fig, path)


def _speed_map(result, ctx, base_fit, best, path) -> Path:
    f = ctx.stats.centres
    bw = np.diff(ctx.stats.edges)
    bins = ctx.stats.speed_bins
    if best is not None and best["kind"] in ("wheel", "track"):
        name = "consistency" if best["kind"] == "wheel" else "axle1_mean"
        i = ctx.stats.channels.index(name)
        rows = [sum(ctx.stats.S[k][:, i, i].real for k in ctx.stats.S if k[1] == vb)
                / sum(ctx.stats.seconds[k] for k in ctx.stats.S if k[1] == vb) / bw for vb in bins]
        label = f"{name} PSD"
    else:
        ch = result["evidence"]["channels"]
        name = max(ch, key=lambda n: max([p["over_floor"] for p in ch[n]["peaks"]] + [ch[n]["input_coherence"]]))
        c = ctx.lay.response_names.index(name)
        rows = []
        for vb in bins:
            keys = {k for k in ctx.stats.S if k[1] == vb}
            R, _ = response_nrp(ctx.stats, ctx.lay, keys, base_fit.parameters, base_fit.extras, base_fit.sensors,
                                by_band=True)
            rows.append(R[:, c] / bw / sum(ctx.stats.seconds[k] for k in keys))
        label = f"{name}: baseline residual PSD"
    fig, ax = plt.subplots(figsize=(9, 4.5))
    v = np.array(bins) + ctx.settings.records.speed_bin / 2
    img = np.log10(np.maximum(np.array(rows), 1e-300))
    mesh = ax.pcolormesh(f, v, img, shading="nearest", cmap="viridis",
                         vmin=np.percentile(img, 5), vmax=img.max())
    ax.set_xscale("log")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("speed bin [m/s]")
    ax.set_title(f"speed-frequency map, {label} (log10)", fontsize=9)
    fig.colorbar(mesh, ax=ax)
    return save_figure(fig, path)
