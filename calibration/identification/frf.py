"""Frequency response functions from cross-spectra, and modal parameters from FRFs.

* :func:`h1` is the multi-input H1 estimator, H = G_yu G_uu^-1 per frequency, with the
  multiple coherence of each output. Summing CSD matrices over segments before the
  solve is the usual averaging; with inputs that are delayed copies of each other (the
  trailing bogie runs over the leading bogie's rail) segments at different speeds make
  G_uu invertible where one speed alone would not.
* :func:`fit_poles` fits a rational fraction N(s)/D(s) to an FRF over a band by linear
  least squares, re-weighted by 1/|D| (Sanathanan & Koerner, IEEE TAC 8, 1963) until the
  poles settle, and returns the poles as natural frequency [Hz] and damping ratio.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def h1(G: np.ndarray, outputs: list[int], inputs: list[int], *, rcond: float = 1e-10):
    """H (n_f, n_out, n_in) and multiple coherence (n_f, n_out) from CSD matrices G (n_f, n, n).

    G[f, i, j] = E[X_i X_j^*], so G_yu = G[:, outputs][:, :, inputs].
    """
    Guu = G[:, inputs][:, :, inputs]
    Gyu = G[:, outputs][:, :, inputs]
    Gyy = np.real(np.einsum("fii->fi", G[:, outputs][:, :, outputs]))
    H = np.empty(Gyu.shape, complex)
    for k in range(G.shape[0]):
        H[k] = Gyu[k] @ np.linalg.pinv(Guu[k], rcond=rcond)
    explained = np.real(np.einsum("foi,foi->fo", H, np.conj(Gyu)))
    coherence = np.clip(explained / np.maximum(Gyy, 1e-300), 0.0, 1.0)
    return H, coherence


@dataclass(frozen=True)
class Pole:
    frequency_hz: float  # natural frequency |lambda| / 2 pi
    damping_ratio: float
    damped_frequency_hz: float  # Im(lambda) / 2 pi
    residue_magnitude: float  # |residue| / (zeta omega): the pole's peak contribution

    @property
    def eigenvalue(self) -> complex:
        w = 2 * np.pi * self.frequency_hz
        return complex(-self.damping_ratio * w, 2 * np.pi * self.damped_frequency_hz)


def fit_poles(f: np.ndarray, H: np.ndarray, band: tuple[float, float], n_modes: int, *,
              weights: np.ndarray | None = None, iterations: int = 20) -> list[Pole]:
    """Poles of a rational fit of order 2 n_modes to the FRF H(f) over ``band`` [Hz].

    Returns the stable, oscillatory poles (one per conjugate pair) found inside the band,
    sorted by frequency.
    """
    sel = (f >= band[0]) & (f <= band[1]) & np.isfinite(H)
    fk, Hk = f[sel], H[sel]
    wk = np.ones(fk.size) if weights is None else np.asarray(weights)[sel]
    w0 = 2 * np.pi * np.sqrt(band[0] * band[1])
    s = 1j * 2 * np.pi * fk / w0
    order = 2 * n_modes
    V = s[:, None] ** np.arange(order + 1)  # powers 0..order
    D_prev = np.ones(fk.size, complex)
    poles = np.array([])
    for _ in range(iterations):
        # unknowns: numerator n_0..n_order, denominator d_1..d_order (d_0 = 1)
        A = np.hstack([V, -Hk[:, None] * V[:, 1:]]) * (wk / np.abs(D_prev))[:, None]
        b = Hk * wk / np.abs(D_prev)
        Ar = np.vstack([A.real, A.imag])
        br = np.concatenate([b.real, b.imag])
        scale = np.linalg.norm(Ar, axis=0)
        scale[scale == 0] = 1
        x, *_ = np.linalg.lstsq(Ar / scale, br, rcond=None)
        x = x / scale
        d = np.concatenate([[1.0], x[order + 1:]])
        D_new = V @ d
        new_poles = np.roots(d[::-1]) * w0
        if poles.size == new_poles.size and np.allclose(np.sort_complex(poles), np.sort_complex(new_poles),
                                                        rtol=1e-9):
            break
        poles, D_prev = new_poles, D_new
    num = x[: order + 1]
    out = []
    for lam in poles:
        if lam.imag <= 0 or lam.real >= 0:
            continue
        wn = abs(lam)
        fn = wn / (2 * np.pi)
        if not band[0] <= fn <= band[1]:
            continue
        zeta = -lam.real / wn
        # residue of N/D at lam (scaled variable)
        ls = lam / w0
        dprime = np.polyval(np.polyder(d[::-1]), ls)
        res = np.polyval(num[::-1], ls) / dprime
        out.append(Pole(float(fn), float(zeta), float(lam.imag / (2 * np.pi)),
                        float(abs(res) / max(zeta * wn / w0, 1e-12))))
    return sorted(out, key=lambda p: p.frequency_hz)
