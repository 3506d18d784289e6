"""Experimental modal analysis of a stationary shaker test (one force input, many outputs).

Pipeline (pure functions of arrays; results are frozen objects made once):

1. :func:`frf_h1` estimates H = G_fy / G_ff (H1) and the ordinary coherence of every output
   from Welch spectra of the force [N] and the responses (e.g. accelerations [m/s^2]).
2. :func:`lscf` runs the least-squares complex-frequency-domain estimator (p-LSCF,
   "PolyMAX" with one reference) for a list of model orders and flags, order by order, the
   poles that are stable in frequency, damping and shape: a :class:`Stabilisation`.
   :meth:`Stabilisation.select_modes` turns clusters of poles consistent in
   frequency and shape across orders into physical modes.
3. :func:`mode_shapes` fits residues to all outputs at the selected poles by least-squares
   frequency-domain (LSFD) fitting with lower and upper residual terms.
4. :func:`peak_picking` is the baseline: peaks of sum_o |H_o|^2, half-power damping,
   shapes from the quadrature (imaginary) response.
5. :func:`mpc` measures a complex shape's phase collinearity; shapes are compared by
   :func:`calibration.signals.modal.mac_matrix`, and the two usual figures are drawn by
   :mod:`calibration.identification.plots`.

Sign convention: time dependence exp(+i omega t), poles lambda = -zeta omega_n + i omega_d
with omega_d > 0; one pole of every complex-conjugate pair is reported. Frequencies in Hz,
eigenvalues in rad/s. Mode shapes are complex columns scaled so that their
largest-magnitude entry is 1 (real, positive).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.cluster.hierarchy
import scipy.signal
import scipy.spatial.distance

from ..signals.modal import mac_matrix
from ..signals.peaks import parabolic_shift

Quantity = Literal["displacement", "velocity", "acceleration"]
_DERIVATIVE = {"displacement": 0, "velocity": 1, "acceleration": 2}


# --------------------------------------------------------------------------- results


@dataclass(frozen=True, eq=False)
class FRFEstimate:
    """H1 estimate: ``H[k, o]`` is output o per unit force at ``frequency[k]`` [Hz]
    (e.g. (m/s^2)/N for accelerance), ``coherence`` its ordinary coherence [-], from
    ``n_averages`` Welch segments."""

    frequency: np.ndarray  # (n_f,) [Hz]
    H: np.ndarray  # (n_f, n_out) complex
    coherence: np.ndarray  # (n_f, n_out) in [0, 1]
    n_averages: int


@dataclass(frozen=True, eq=False)
class Mode:
    """One identified mode: natural frequency [Hz], damping ratio [-] (None when not
    resolvable), shape (n_out,) with largest-magnitude entry 1 (None when not estimated),
    and the number of model orders whose diagram holds it (0 for peak picking)."""

    frequency_hz: float
    damping_ratio: float | None
    shape: np.ndarray | None = None
    n_stable: int = 0

    @property
    def eigenvalue(self) -> complex:
        """lambda = -zeta omega_n + i omega_n sqrt(1 - zeta^2) [rad/s]."""
        w, z = 2 * np.pi * self.frequency_hz, self.damping_ratio or 0.0
        return complex(-z * w, w * np.sqrt(1 - z * z))


@dataclass(frozen=True, eq=False)
class OrderPoles:
    """Poles of one model order kept in the band (one per conjugate pair), sorted by
    frequency, with their stability against the previous order of the diagram."""

    order: int
    frequency_hz: np.ndarray  # (n_p,)
    damping_ratio: np.ndarray  # (n_p,)
    shapes: np.ndarray  # (n_out, n_p) complex, numerators at the poles, normalised
    stable_frequency: np.ndarray  # (n_p,) bool
    stable_damping: np.ndarray  # (n_p,) bool
    stable_shape: np.ndarray  # (n_p,) bool

    @property
    def stable(self) -> np.ndarray:
        """Stable in frequency, damping and shape."""
        return self.stable_frequency & self.stable_damping & self.stable_shape


@dataclass(frozen=True, eq=False)
class Stabilisation:
    """Stabilisation diagram of :func:`lscf`: one :class:`OrderPoles` per model order, and
    the criteria used (relative frequency and damping change, MAC with the nearest pole of
    the previous order)."""

    band: tuple[float, float]  # [Hz]
    orders: tuple[OrderPoles, ...]
    freq_tol: float
    damping_tol: float
    mac_min: float
    max_damping: float

    def select_modes(self, *, min_fraction: float = 0.4, cluster_tol: float = 0.005,
                     cluster_mac: float = 0.9, bandwidth_fraction: float = 0.0,
                     min_mpc: float = 0.7) -> list[Mode]:
        """Physical modes: clusters of consistent poles across orders, one mode each.

        Candidates are the poles stable in frequency against the previous order (damping
        and shape are left to the clustering: near a close pair they wander between
        orders while the frequency holds). Two poles belong to one mode when they differ
        in frequency by at most tol = max(``cluster_tol``, ``bandwidth_fraction`` x their
        mean damping ratio) (relative: a pole's frequency scatters in proportion to its
        half-power bandwidth, 2 zeta f) *and* their shapes have MAC >= ``cluster_mac``;
        poles of one order never do. Average-linkage clustering on
        d = max(|df| / (tol f), (1 - MAC) / (1 - cluster_mac)) cut at 1 (the
        frequency-and-shape distance of automated modal analysis, Reynders, Houbrechts &
        De Roeck, Mech. Syst. Signal Process. 29 (2012) 228-250) keeps a close pair apart
        where a cut on frequency alone would merge it. Within a cluster each order keeps
        its pole nearest the cluster median. A cluster is a mode when it holds poles from
        at least ``min_fraction`` of the orders and its shape is that of a lightly damped
        structure, its phase collinearity (:func:`mpc`) at least ``min_mpc``: the
        computational poles a least-squares fraction holds near the band's edges or between
        modes can be stable over as many orders as a mode, but their numerators are no mode
        shape (MPC 0.005-0.5 on the synthetic tests, where the modes' are 0.82-1, a pair
        0.08 % apart the lowest). Its frequency and damping are the medians, its shape that
        of the member most like the others (largest summed MAC).
        """
        if not 0 < min_fraction <= 1:
            raise ValueError(f"min_fraction must be in (0, 1], got {min_fraction}")
        if not 0 < cluster_tol or not 0 <= cluster_mac < 1:
            raise ValueError(f"cluster_tol must be > 0 and cluster_mac in [0, 1), got {cluster_tol}, {cluster_mac}")
        rows = [(op.frequency_hz[i], op.damping_ratio[i], k, op.shapes[:, i])
                for k, op in enumerate(self.orders) for i in np.flatnonzero(op.stable_frequency)]
        if not rows:
            return []
        f = np.array([r[0] for r in rows])
        zeta = np.array([r[1] for r in rows])
        order = np.array([r[2] for r in rows])
        shapes = np.column_stack([r[3] for r in rows])
        if f.size == 1:
            labels = np.zeros(1, int)
        else:
            tol = np.maximum(cluster_tol, bandwidth_fraction * 0.5 * (zeta[:, None] + zeta[None, :]))
            d_f = np.abs(f[:, None] - f[None, :]) / (tol * 0.5 * (f[:, None] + f[None, :]))
            d = np.maximum(d_f, (1.0 - mac_matrix(shapes, shapes)) / (1.0 - cluster_mac))
            d[order[:, None] == order[None, :]] = 1e6  # one pole per order and mode
            np.fill_diagonal(d, 0.0)
            tree = scipy.cluster.hierarchy.linkage(scipy.spatial.distance.squareform(d, checks=False), "average")
            labels = scipy.cluster.hierarchy.fcluster(tree, t=1.0, criterion="distance")
        modes = []
        for c in np.unique(labels):
            idx = np.flatnonzero(labels == c)
            f_med = np.median(f[idx])
            best = {}
            for i in idx:  # one pole per order
                if order[i] not in best or abs(f[i] - f_med) < abs(f[best[order[i]]] - f_med):
                    best[order[i]] = i
            if len(best) < min_fraction * len(self.orders):
                continue
            sel = np.array(sorted(best.values()))
            rep = sel[int(np.argmax(mac_matrix(shapes[:, sel], shapes[:, sel]).sum(axis=1)))]
            if mpc(shapes[:, rep]) < min_mpc:
                continue
            modes.append(Mode(float(np.median(f[sel])), float(np.median(zeta[sel])), shapes[:, rep], int(sel.size)))
        return sorted(modes, key=lambda m: m.frequency_hz)


@dataclass(frozen=True, eq=False)
class ModalFit:
    """LSFD fit over the band: complex ``shapes`` (n_out, n_modes) normalised to a largest
    entry of 1, the ``residues`` they come from (units of H times rad/s), the real lower
    and upper residual coefficients, the synthesised FRF ``H_fit`` on ``frequency`` and the
    relative fit error ||H - H_fit|| / ||H|| of each output over the band."""

    frequency: np.ndarray  # (n_fb,) [Hz]
    shapes: np.ndarray  # (n_out, n_modes) complex
    residues: np.ndarray  # (n_out, n_modes) complex
    lower: np.ndarray  # (n_out,) coefficient of s^(d-2) [H (rad/s)^(2-d)]
    upper: np.ndarray  # (n_out,) coefficient of s^d [H (rad/s)^-d]
    H_fit: np.ndarray  # (n_fb, n_out) complex
    relative_error: np.ndarray  # (n_out,)


# --------------------------------------------------------------------------- H1


def frf_h1(force: np.ndarray, responses: np.ndarray, fs: float, nperseg: int, noverlap: int | None = None,
           window="hann") -> FRFEstimate:
    """H1 estimator H_o = G_fy_o / G_ff with ordinary coherence |G_fy_o|^2 / (G_ff G_yy_o).

    Welch averaging (``scipy.signal.csd`` / ``welch``, same ``fs``, ``nperseg``,
    ``noverlap`` (default nperseg // 2), ``window``, mean removed per segment). H1 is unbiased by noise on the
    responses; noise on the force biases |H| low (Bendat & Piersol, *Engineering
    applications of correlation and spectral analysis*, 2nd ed. 1993, ch. 3).

    ``force`` (n,) [N], ``responses`` (n, n_out) (or (n,)), ``fs`` [Hz]. At least two
    segments are required (the coherence of one segment is 1 whatever the data).
    """
    force = np.asarray(force, float)
    responses = np.asarray(responses, float)
    if responses.ndim == 1:
        responses = responses[:, None]
    if force.ndim != 1 or responses.ndim != 2:
        raise ValueError(f"force must be 1-D (n,) and responses (n, n_out); got {force.shape} and {responses.shape}")
    if force.size != responses.shape[0]:
        raise ValueError(f"length mismatch: force has {force.size} samples, responses {responses.shape[0]}")
    for name, x in (("force", force), ("responses", responses)):
        bad = np.flatnonzero(~np.isfinite(x.reshape(x.shape[0], -1)).all(axis=1))
        if bad.size:
            raise ValueError(f"{name} contains NaN or inf ({bad.size} samples, first at sample {bad[0]})")
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    step = nperseg - (nperseg // 2 if noverlap is None else int(noverlap))
    n_avg = 1 + (force.size - nperseg) // step if force.size >= nperseg and step > 0 else 0
    if n_avg < 2:
        raise ValueError(f"record too short: {force.size} samples give {n_avg} Welch segment(s) of nperseg "
                         f"{nperseg}; at least 2 are needed")
    return frf_h1_records([(force, responses)], fs, nperseg, noverlap, window, min_averages=2)


def frf_h1_records(records, fs: float, nperseg: int, noverlap: int | None = None, window="hann", *,
                   min_averages: int = 2) -> FRFEstimate:
    """H1 and coherence from several records (runs, or the blocks of a run between gaps):
    their Welch auto- and cross-spectra are averaged with weights equal to their segment
    counts, so every segment counts once. Records shorter than ``nperseg`` are skipped.
    ``records``: iterable of (force (n,), responses (n, n_out)) pairs without NaN."""
    noverlap = nperseg // 2 if noverlap is None else int(noverlap)
    if not 0 <= noverlap < nperseg:
        raise ValueError(f"noverlap must be in [0, nperseg), got {noverlap} for nperseg {nperseg}")
    if not fs > 0:
        raise ValueError(f"fs must be > 0 Hz, got {fs}")
    kw = {"fs": fs, "nperseg": nperseg, "noverlap": noverlap, "window": window, "axis": 0}
    total, sums, f = 0, None, None
    for force, responses in records:
        force, responses = np.asarray(force, float), np.asarray(responses, float)
        if responses.ndim == 1:
            responses = responses[:, None]
        n_avg = 1 + (force.size - nperseg) // (nperseg - noverlap) if force.size >= nperseg else 0
        if n_avg < 1:
            continue
        f, Gff = scipy.signal.welch(force, **kw)
        _, Gfy = scipy.signal.csd(force[:, None], responses, **kw)  # E[conj(F) Y]
        _, Gyy = scipy.signal.welch(responses, **kw)
        parts = (n_avg * Gff[:, None], n_avg * Gfy, n_avg * Gyy)
        sums = parts if sums is None else tuple(a + b for a, b in zip(sums, parts))
        total += n_avg
    if total < min_averages:
        raise ValueError(f"records too short: {total} Welch segment(s) of nperseg {nperseg} with noverlap "
                         f"{noverlap}; at least {min_averages} are needed")
    Gff, Gfy, Gyy = (x / total for x in sums)
    tiny = np.finfo(float).tiny
    H = Gfy / np.maximum(Gff, tiny)
    coherence = np.clip(np.abs(Gfy) ** 2 / np.maximum(Gff * Gyy, tiny), 0.0, 1.0)
    return FRFEstimate(f, H, coherence, int(total))


# --------------------------------------------------------------------------- helpers


def band_lines(frequency, H, band, weights=None, min_lines: int = 8):
    """Validated band selection: f (n_b,), H (n_b, n_out), weights (n_b, n_out)."""
    f = np.asarray(frequency, float)
    H = np.asarray(H)
    if H.ndim == 1:
        H = H[:, None]
    if f.ndim != 1 or H.shape[0] != f.size:
        raise ValueError(f"H must have shape (n_f, n_out) with n_f = len(frequency) = {f.size}; got {H.shape}")
    lo, hi = band
    if not 0 <= lo < hi:
        raise ValueError(f"band {band} Hz must satisfy 0 <= f_lo < f_hi")
    sel = (f >= lo) & (f <= hi)
    if np.count_nonzero(sel) < min_lines:
        raise ValueError(f"band {band} Hz holds {np.count_nonzero(sel)} spectral lines; at least {min_lines} needed")
    if not np.all(np.isfinite(H[sel])):
        raise ValueError(f"H contains NaN or inf inside the band {band} Hz")
    W = None
    if weights is not None:
        W = np.asarray(weights, float)
        W = np.broadcast_to(W[:, None] if W.ndim == 1 else W, H.shape)[sel]
        if np.any(W < 0) or not np.all(np.isfinite(W)):
            raise ValueError("weights must be finite and >= 0")
    return f[sel], H[sel], W


def _normalise(phi: np.ndarray) -> np.ndarray:
    """Scale each column so that its largest-magnitude entry is 1 (real, positive)."""
    phi = np.array(phi, complex, ndmin=2)
    k = np.argmax(np.abs(phi), axis=0)
    ref = phi[k, np.arange(phi.shape[1])]
    return phi / np.where(ref == 0, 1, ref)


def _eigenvalues(poles) -> np.ndarray:
    """Eigenvalues [rad/s] from complex values or objects with frequency_hz/damping_ratio."""
    if isinstance(poles, np.ndarray) and np.iscomplexobj(poles):
        lam = poles.ravel()
    else:
        lam = np.array([p.eigenvalue if hasattr(p, "eigenvalue") else complex(p) for p in poles], complex)
    if lam.size == 0:
        raise ValueError("no poles given")
    if np.any(lam.real >= 0) or np.any(lam.imag <= 0):
        raise ValueError("poles must be stable and oscillatory (Re lambda < 0 < Im lambda); "
                         f"got {lam[(lam.real >= 0) | (lam.imag <= 0)]}")
    return lam


# --------------------------------------------------------------------------- MPC


def mpc(phi: np.ndarray) -> float:
    """Modal phase collinearity of one complex shape (n,): 1 when its entries lie on one line
    through the origin of the complex plane (a real mode times any complex scale, as lightly
    and proportionally damped structures have), 0 for phases spread evenly. With S the 2 x 2
    matrix of the real and imaginary parts' sums of products, MPC = ((l1 - l2) / (l1 + l2))^2
    of its eigenvalues (Pappa, Elliott & Schenk, J. Guid. Control Dyn. 16 (1993) 852-858)."""
    phi = np.asarray(phi)
    sxx, syy, sxy = np.sum(phi.real ** 2), np.sum(phi.imag ** 2), np.sum(phi.real * phi.imag)
    total = sxx + syy
    if total == 0:
        raise ValueError("a mode shape is all zeros")
    return float(((sxx - syy) ** 2 + 4 * sxy ** 2) / total ** 2)


# --------------------------------------------------------------------------- p-LSCF


def _arnoldi(z: np.ndarray, w2: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """Polynomials with real coefficients orthonormal on the lines ``z`` (upper unit
    half-circle) under <a, b> = 2 Re sum_k w2_k conj(a(z_k)) b(z_k), the inner product of
    the conjugate-symmetric set {z, conj z}: values Q (n_b, degree + 1) and the Hessenberg
    recurrence z q_k = sum_{j <= k + 1} Hs[j, k] q_j (degree + 1, degree). "Vandermonde with
    Arnoldi" (Brubeck, Nakatsukasa & Trefethen, SIAM Review 63 (2021) 405-415): the
    monomials z^r on the arc of a band are numerically dependent (condition numbers 1e15-1e17
    at order 30-100), the orthonormal basis is not."""
    Q = np.zeros((z.size, degree + 1), complex)
    Hs = np.zeros((degree + 1, degree))
    Q[:, 0] = 1.0 / np.sqrt(2.0 * np.sum(w2))
    for k in range(degree):
        v = z * Q[:, k]
        for _ in range(2):  # classical Gram-Schmidt twice is orthogonal to working precision
            h = 2.0 * np.real(Q[:, :k + 1].conj().T @ (w2 * v))
            v = v - Q[:, :k + 1] @ h
            Hs[:k + 1, k] += h
        Hs[k + 1, k] = np.sqrt(2.0 * np.sum(w2 * np.abs(v) ** 2))
        if not Hs[k + 1, k] > 0:
            raise ValueError(f"order {degree} needs more than {z.size} spectral lines in the band")
        Q[:, k + 1] = v / Hs[k + 1, k]
    return Q, Hs


def _arnoldi_values(Hs: np.ndarray, z: np.ndarray, q0: float, degree: int) -> np.ndarray:
    """The basis of :func:`_arnoldi` at any points ``z`` (n,), by its recurrence: (n, degree + 1)."""
    V = np.zeros((z.size, degree + 1), complex)
    V[:, 0] = q0
    for k in range(degree):
        V[:, k + 1] = (z * V[:, k] - V[:, :k + 1] @ Hs[:k + 1, k]) / Hs[k + 1, k]
    return V


def lscf(frequency: np.ndarray, H: np.ndarray, band: tuple[float, float], orders: Sequence[int],
         weights: np.ndarray | None = None, *, freq_tol: float = 0.01, damping_tol: float = 0.05,
         mac_min: float = 0.98, max_damping: float = 0.2) -> Stabilisation:
    """Poles of a common-denominator fraction H_o(z) = N_o(z) / d(z) for every model order.

    Least-squares complex-frequency-domain (LSCF) estimator with one reference, the
    single-input case of poly-reference LSCF ("PolyMAX"): Guillaume, Verboven, Vanlanduit,
    Van der Auweraer & Peeters, Proc. IMAC XXI (2003); Peeters, Van der Auweraer, Guillaume
    & Leuridan, Shock and Vibration 11 (2004) 395-409.

    * z_k = exp(i omega_k dt), dt = 1 / (2 f_hi): the band lies on the upper unit
      half-circle. Numerators and denominator are polynomials in z with real coefficients
      (conjugate symmetry of physical FRFs), written in a basis orthonormal on the band's
      lines (:func:`_arnoldi`) rather than in monomials: the estimator is the same, but its
      normal equations keep their digits, so the poles do not move with round-off (BLAS
      threads, CPU kernels) and the stabilisation diagram is the data's, not the
      arithmetic's.
    * Linearised error per output and line: w_ko (N_o(z_k) - H_ko d(z_k)). The numerators
      are eliminated output by output: M = sum_o (T_o - S_o^T R_o^-1 S_o) with
      R_o = Re X^H W_o^2 X, S_o = Re X^H W_o^2 H_o X, T_o = Re X^H W_o^2 |H_o|^2 X (reduced
      normal equations; R_o = I when the weights are common to all outputs), solved with
      the highest-degree coefficient of the denominator fixed to 1 (PolyMAX's monic
      denominator: only the highest basis polynomial holds z^p). The basis is nested, so
      the blocks are formed once at the highest order and lower orders are leading
      sub-blocks.
    * Roots of d: eigenvalues of the recurrence's Hessenberg matrix with its last column
      corrected by d's coefficients (a "confederate" matrix, the companion matrix of an
      orthogonal basis). Poles lambda = ln(z_root) / dt; kept: Im lambda > 0,
      0 < zeta < ``max_damping``, natural frequency in ``band``. A pole's shape is the
      numerators at it, N_o(z_root) (proportional to the residues over outputs).

    ``frequency`` (n_f,) [Hz], ``H`` (n_f, n_out), ``weights`` (n_f,) or (n_f, n_out) on
    the equation error (e.g. coherence, or 1 / standard deviation of H). ``orders`` are
    denominator orders (order p gives at most p/2 modes), analysed in increasing order.
    Stability against the nearest pole of the next lower order in ``orders``: relative
    frequency change <= ``freq_tol``, relative damping change <= ``damping_tol``, MAC >=
    ``mac_min``; the lowest order has nothing to compare with and is never stable.
    """
    orders = [int(p) for p in orders]
    if not orders or min(orders) < 2:
        raise ValueError(f"orders must be a non-empty list of integers >= 2, got {orders}")
    f, Hb, W = band_lines(frequency, H, band, weights)
    n_out = Hb.shape[1]
    common = W is None or np.allclose(W, W[:, :1])  # one numerator Gram matrix for all outputs
    W2 = np.ones((f.size, 1)) if W is None else (W[:, :1] ** 2 if common else W ** 2)
    dt = 1.0 / (2.0 * band[1])
    p_max = max(orders)
    if 2 * f.size * n_out < 2 * p_max + 2:
        raise ValueError(f"order {p_max} needs more data than {f.size} lines x {n_out} outputs")
    Q, Hs = _arnoldi(np.exp(2j * np.pi * f * dt), W2.mean(axis=1), p_max)
    QH = Q.conj().T  # (p_max + 1, n_b)
    S = 2.0 * np.real((QH[None] * (W2 * Hb).T[:, None, :]) @ Q)  # (n_out, ., .)
    T = 2.0 * np.real((QH * np.sum(W2 * np.abs(Hb) ** 2, axis=1)) @ Q)  # summed over outputs
    R = None if common else 2.0 * np.real((QH[None] * W2.T[:, None, :]) @ Q)  # (n_out, ., .)

    result, prev = [], None
    for p in sorted(set(orders)):
        n = p + 1
        Sp = S[:, :n, :n]
        RinvS = Sp if common else np.linalg.solve(R[:, :n, :n], Sp)
        M = T[:n, :n] - Sp.reshape(-1, n).T @ RinvS.reshape(-1, n)  # sum_o T_o - S_o^T R_o^-1 S_o
        c = np.append(np.linalg.solve(M[:p, :p], -M[:p, p]), 1.0)
        beta = RinvS @ c  # (n_out, n): numerator coefficients in the basis
        C = Hs[:p, :p].copy()
        C[:, p - 1] -= Hs[p, p - 1] * c[:p] / c[p]
        zr = np.linalg.eigvals(C).astype(complex)
        zr = zr[zr != 0]
        lam = np.log(zr) / dt
        wn = np.abs(lam)
        zeta = -lam.real / wn
        fn = wn / (2 * np.pi)
        keep = (lam.imag > 0) & (zeta > 0) & (zeta < max_damping) & (fn >= band[0]) & (fn <= band[1])
        idx = np.flatnonzero(keep)[np.argsort(fn[keep])]
        fn, zeta, zr = fn[idx], zeta[idx], zr[idx]
        shapes = (_normalise(beta @ _arnoldi_values(Hs, zr, Q[0, 0].real, p).T) if idx.size
                  else np.empty((n_out, 0)))
        sf = np.zeros(idx.size, bool)
        sd, sv = sf.copy(), sf.copy()
        if prev is not None and prev.frequency_hz.size and idx.size:
            j = np.argmin(np.abs(fn[:, None] - prev.frequency_hz[None, :]), axis=1)
            sf = np.abs(fn - prev.frequency_hz[j]) <= freq_tol * fn
            sd = np.abs(zeta - prev.damping_ratio[j]) <= damping_tol * zeta
            sv = np.einsum("ii->i", mac_matrix(shapes, prev.shapes[:, j])) >= mac_min
        prev = OrderPoles(p, fn, zeta, shapes, sf, sd, sv)
        result.append(prev)
    return Stabilisation((float(band[0]), float(band[1])), tuple(result), freq_tol, damping_tol, mac_min,
                         max_damping)


# --------------------------------------------------------------------------- LSFD


def mode_shapes(frequency: np.ndarray, H: np.ndarray, poles, band: tuple[float, float], *,
                quantity: Quantity = "acceleration", weights: np.ndarray | None = None) -> ModalFit:
    """Residues of all outputs at given poles by least-squares frequency-domain (LSFD) fit.

    H_o(s) = sum_r [R_or / (s - lambda_r) + conj(R_or) / (s - conj(lambda_r))]
             + L_o s^(d-2) + U_o s^d,   s = i omega,

    with d = 0, 1, 2 for displacement, velocity, acceleration per force: the lower residual
    stands for the modes below the band (mass line of a receptance), the upper for those
    above (the constant of a receptance); for an accelerance they are a constant and an
    s^2 term, and the accelerance's own constant (sum of phi phi^T / m) is part of L_o. The
    problem is linear in real unknowns (Re R, Im R, L, U), shared by all outputs, and solved
    in one column-scaled least-squares problem with s scaled by the band's centre
    (Peeters et al., Shock and Vibration 11 (2004); Heylen, Lammens & Sas, *Modal analysis
    theory and testing*, KU Leuven 1997).

    For one input the residue column R_:r is proportional to the mode shape; the returned
    shapes are those columns scaled to a largest-magnitude entry of 1.
    ``poles``: :class:`Mode` objects (or anything with ``frequency_hz``/``damping_ratio``)
    or complex eigenvalues [rad/s], one per conjugate pair.
    """
    if quantity not in _DERIVATIVE:
        raise ValueError(f"quantity must be one of {sorted(_DERIVATIVE)}, got {quantity!r}")
    lam = _eigenvalues(poles)
    f, Hb, W = band_lines(frequency, H, band, weights)
    n_out, m = Hb.shape[1], lam.size
    w0 = np.pi * (f[0] + f[-1])  # centre of the band [rad/s]
    s = 1j * 2 * np.pi * f / w0
    if np.any(s == 0) and _DERIVATIVE[quantity] < 2:
        raise ValueError("the band includes 0 Hz, where the lower residual is singular; start it above 0")
    ls = lam / w0
    d = _DERIVATIVE[quantity]
    P = 1 / (s[:, None] - ls) + 1 / (s[:, None] - ls.conj())  # multiplies Re R
    Q = 1j / (s[:, None] - ls) - 1j / (s[:, None] - ls.conj())  # multiplies Im R
    A = np.hstack([P, Q, (s ** (d - 2.0))[:, None], (s ** float(d))[:, None]])
    if W is None or np.allclose(W, W[:, :1]):
        w = np.ones(f.size) if W is None else W[:, 0]
        Ar = np.vstack([(A * w[:, None]).real, (A * w[:, None]).imag])
        br = np.vstack([(Hb * w[:, None]).real, (Hb * w[:, None]).imag])
        scale = np.linalg.norm(Ar, axis=0)
        x = np.linalg.lstsq(Ar / scale, br, rcond=None)[0] / scale[:, None]
    else:  # different weights per output: one problem each
        x = np.empty((2 * m + 2, n_out))
        for o in range(n_out):
            Aw = A * W[:, o:o + 1]
            Ar = np.vstack([Aw.real, Aw.imag])
            scale = np.linalg.norm(Ar, axis=0)
            bo = np.concatenate([(Hb[:, o] * W[:, o]).real, (Hb[:, o] * W[:, o]).imag])
            x[:, o] = np.linalg.lstsq(Ar / scale, bo, rcond=None)[0] / scale
    H_fit = A @ x
    residues = (x[:m] + 1j * x[m:2 * m]).T * w0  # back to H * rad/s
    err = np.linalg.norm(Hb - H_fit, axis=0) / np.maximum(np.linalg.norm(Hb, axis=0), np.finfo(float).tiny)
    return ModalFit(f, _normalise(residues), residues, x[2 * m] * w0 ** (2.0 - d), x[2 * m + 1] * w0 ** (-float(d)),
                    H_fit, err)


# --------------------------------------------------------------------------- peak picking


def peak_picking(frequency: np.ndarray, H: np.ndarray, band: tuple[float, float], min_separation_hz: float, *,
                 prominence_db: float = 3.0, n_modes: int | None = None, min_lines: int = 3,
                 quantity: Quantity = "acceleration") -> list[Mode]:
    """Modes from the peaks of the indicator sum_o |H_o|^2 (for one input, the square of the
    first singular value of H) in ``band`` [Hz].

    * Peaks at least ``min_separation_hz`` apart and ``prominence_db`` above their
      surroundings (on 10 log10 of the indicator); with ``n_modes`` the most prominent ones.
    * Sub-bin frequency: vertex of the parabola through the three dB values around the peak
      line (:func:`calibration.signals.peaks.parabolic_shift`).
    * Damping by the half-power bandwidth, zeta = (f_2 - f_1) / (2 f_peak), with f_1, f_2
      where the indicator falls to half its peak value (linear interpolation). None when a
      side does not fall to half power before the next valley or the band edge (overlapping
      modes), or when fewer than ``min_lines`` lines lie between f_1 and f_2.
    * Shape: the quadrature response at the peak line. At resonance a lightly damped real
      mode makes the receptance purely imaginary, H_o ~ -i phi_o phi_f / (2 m zeta w^2), and
      the accelerance (-w^2 times the receptance) likewise, so shape = Im H[peak]; for a
      mobility (``quantity="velocity"``) it is Re H. The column is real and scaled so that
      its largest-magnitude entry is +1, so the sign relative to the driving point is not
      kept. Valid for well-separated, lightly damped modes (Ewins, *Modal testing*, 2nd ed.
      2000, sec. 4.3).
    """
    if not min_separation_hz > 0:
        raise ValueError(f"min_separation_hz must be > 0, got {min_separation_hz}")
    if quantity not in _DERIVATIVE:
        raise ValueError(f"quantity must be one of {sorted(_DERIVATIVE)}, got {quantity!r}")
    f, Hb, _ = band_lines(frequency, H, band)
    df = float(np.median(np.diff(f)))
    ind = np.sum(np.abs(Hb) ** 2, axis=1)
    db = 10 * np.log10(np.maximum(ind, np.finfo(float).tiny))
    peaks, props = scipy.signal.find_peaks(db, distance=max(1, round(min_separation_hz / df)),
                                           prominence=prominence_db)
    if n_modes is not None:
        peaks = np.sort(peaks[np.argsort(props["prominences"])[::-1][:n_modes]])
    modes = []
    for k in peaks:
        fk = float(f[k] + parabolic_shift(db, int(k)) * df)
        f1, f2 = _half_power(f, ind, int(k))
        zeta = None
        if f1 is not None and f2 is not None and np.count_nonzero((f > f1) & (f < f2)) >= min_lines:
            zeta = float((f2 - f1) / (2 * fk))
        part = Hb[k].real if quantity == "velocity" else Hb[k].imag
        modes.append(Mode(fk, zeta, _normalise(part[:, None])[:, 0].real))
    return modes


def _half_power(f, ind, k):
    """Frequencies left and right of peak line k where ``ind`` first falls to half of
    ind[k], searching only down to the adjacent valley; None where it does not."""
    half = ind[k] / 2
    out = []
    for step in (-1, 1):
        j, found = k, None
        while 0 <= j + step < ind.size:
            a, b = ind[j], ind[j + step]
            if b > a:  # rising again: next mode before half power
                break
            if b <= half:
                found = f[j] + (f[j + step] - f[j]) * (a - half) / (a - b)
                break
            j += step
        out.append(found)
    return out[0], out[1]
