"""The modal comparisons every layer uses: MAC between mode shapes, FRAC and the
log-magnitude error between frequency responses, and the count of a structure's modes
below a frequency.

One place for each, so that the identification, the calibration, the diagnosis and the
references measure agreement the same way.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

_TINY = 1e-300  # keeps a shape of zeros at MAC 0 instead of 0 / 0


def mac_matrix(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Modal assurance criterion between the columns of ``a`` (n, p) and of ``b`` (n, q),
    or of each matrix of a batch ``b`` (N, n, q):

        MAC_ij = |a_i^H b_j|^2 / ((a_i^H a_i)(b_j^H b_j)),

    in [0, 1] and invariant to complex scaling of either shape (Allemang & Brown, Proc.
    1st IMAC, 1982). 1-D inputs are single shapes; a shape of zeros has MAC 0 with every
    shape. Returns (p, q), or (N, p, q) for a batch."""
    a, b = np.asarray(a), np.asarray(b)
    a = a[:, None] if a.ndim == 1 else a
    b = b[:, None] if b.ndim == 1 else b
    if a.shape[0] != b.shape[-2]:
        raise ValueError(f"shapes have {a.shape[0]} and {b.shape[-2]} entries; they must match")
    num = np.abs(np.einsum("ip,...iq->...pq", np.conj(a), b)) ** 2
    da = np.real(np.einsum("ip,ip->p", np.conj(a), a))
    db = np.real(np.einsum("...iq,...iq->...q", np.conj(b), b))
    return num / (da[:, None] * db[..., None, :] + _TINY)


def frac(H_meas: np.ndarray, H_model: np.ndarray) -> np.ndarray:
    """Frequency response assurance criterion per channel (columns of (n_f, n_channels)):

        FRAC = |sum_f conj(H_meas) H_model|^2 / (sum_f |H_meas|^2 sum_f |H_model|^2),

    1 when the two responses have the same shape over frequency (up to a complex scale)."""
    return np.abs(np.sum(np.conj(H_meas) * H_model, axis=0)) ** 2 / (
        np.sum(np.abs(H_meas) ** 2, axis=0) * np.sum(np.abs(H_model) ** 2, axis=0) + _TINY)


def log_error_db(H_meas: np.ndarray, H_model: np.ndarray) -> np.ndarray:
    """rms over frequency of 20 log10 |H_model / H_meas| per channel [dB]."""
    ratio = np.abs(H_model) / np.maximum(np.abs(H_meas), _TINY)
    return np.sqrt(np.mean((20 * np.log10(ratio)) ** 2, axis=0))


def count_modes_below(K, M, frequency_hz: float) -> int | None:
    """How many generalised eigenvalues of (K, M) (sparse, symmetric) lie below
    (2 pi ``frequency_hz``)^2, by Sylvester's law of inertia: the negative pivots of an
    LDL^T factorisation of K - (2 pi f)^2 M (SuperLU in symmetric mode: a symmetric
    ordering, no pivoting, so U = D L^T and diag(U) = D). None when the factorisation is
    not of that form (it pivoted, or broke down), so the caller must count another way."""
    A = scipy.sparse.csc_matrix(K - (2 * np.pi * frequency_hz) ** 2 * M)
    try:
        lu = scipy.sparse.linalg.splu(A, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                      options={"SymmetricMode": True})
    except RuntimeError:  # exactly singular: the frequency is an eigenvalue
        return None
    d = lu.U.diagonal()
    if not np.array_equal(lu.perm_r, lu.perm_c) or not np.all(np.isfinite(d)) or np.any(d == 0):
        return None
    return int(np.count_nonzero(d < 0))
