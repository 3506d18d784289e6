"""Standard errors of a shaker test's modes: a delete-one-group jackknife over its Welch segments.

The Welch segments of all records, in time order, are split into K contiguous groups, and
each group's auto- and cross-spectra are kept as sums (:func:`group_spectra`). Replicate g
is the H1 FRF of every segment but group g's, identified again by the same estimator as
the full data (p-LSCF over all orders, poles clustered into modes); each full-data mode is
paired with the replicate mode of like frequency and shape (:func:`pair_modes`). Over the
replicates that found a mode, the jackknife standard error of its frequency and damping ratio
is sqrt((G - 1) / G sum_i (x_i - mean x)^2) for G groups (Efron & Tibshirani, *An introduction to the
bootstrap*, 1993, ch. 11; with groups, Künsch, Ann. Stat. 17 (1989) 1217-1241, whose
blocks keep the correlation of overlapping segments inside a group). Groups of segments
rather than records: a test is often one or two records, too few for a jackknife.
"""
from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.signal

from ..signals.modal import mac_matrix
from .ema import Mode


@dataclass(frozen=True, eq=False)
class GroupSpectra:
    """Welch spectra summed per group of segments: ``Gff[g]`` (n_f,) [N^2/Hz], ``Gfy[g]`` and
    ``Gyy[g]`` (n_f, n_out) [N unit/Hz, unit^2/Hz], each the sum over the group's
    ``counts[g]`` segments of their one-sided spectra at ``frequency`` (n_f,) [Hz]."""

    frequency: np.ndarray
    Gff: np.ndarray  # (n_g, n_f)
    Gfy: np.ndarray  # (n_g, n_f, n_out) complex, E[conj(F) Y]
    Gyy: np.ndarray  # (n_g, n_f, n_out)
    counts: np.ndarray  # (n_g,) segments

    @property
    def segments(self) -> int:
        return int(self.counts.sum())

    def average(self, without: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """(Gff, Gfy, Gyy, segments): the average over every segment, or all but group ``without``'s."""
        keep = np.ones(self.counts.size, bool)
        if without is not None:
            keep[without] = False
        n = int(self.counts[keep].sum())
        return self.Gff[keep].sum(axis=0) / n, self.Gfy[keep].sum(axis=0) / n, self.Gyy[keep].sum(axis=0) / n, n

    def h1(self, without: int | None = None) -> np.ndarray:
        """H1 = G_fy / G_ff (n_f, n_out) of every segment, or all but group ``without``'s."""
        Gff, Gfy, _, _ = self.average(without)
        return Gfy / np.maximum(Gff, np.finfo(float).tiny)[:, None]


def group_spectra(records, fs: float, nperseg: int, groups: int, window="hann") -> GroupSpectra:
    """Spectra of ``records`` (pairs of force (n,) [N] and responses (n, n_out), no NaN) in
    Welch segments of ``nperseg`` overlapping by half, as :func:`.ema.frf_h1_records` takes
    them (records shorter than a segment are skipped), split in time order into ``groups``
    (>= 2) groups of contiguous segments as equal as can be (fewer when there are fewer
    segments)."""
    if groups < 2:
        raise ValueError(f"groups must be >= 2, got {groups}")
    step = nperseg - nperseg // 2
    records = [(np.asarray(x, float), np.asarray(y, float).reshape(len(x), -1)) for x, y in records]
    n_seg = [1 + (x.size - nperseg) // step if x.size >= nperseg else 0 for x, _ in records]
    total = sum(n_seg)
    if total < 2:
        raise ValueError(f"{total} Welch segment(s) of nperseg {nperseg}; at least 2 are needed")
    bounds = np.linspace(0, total, min(groups, total) + 1).round().astype(int)  # group g: [bounds[g], bounds[g+1])
    n_g, n_out = bounds.size - 1, records[0][1].shape[1]
    f = np.fft.rfftfreq(nperseg, 1.0 / fs)
    Gff, Gfy, Gyy = np.zeros((n_g, f.size)), np.zeros((n_g, f.size, n_out), complex), np.zeros((n_g, f.size, n_out))
    kw = {"fs": fs, "nperseg": nperseg, "noverlap": nperseg // 2, "window": window, "axis": 0}
    first = 0  # global index of the record's first segment
    for (x, y), n in zip(records, n_seg):
        for g in range(n_g):
            a, b = max(bounds[g], first) - first, min(bounds[g + 1], first + n) - first  # its segments [a, b)
            if b <= a:
                continue
            sl = slice(a * step, (b - 1) * step + nperseg)
            Gff[g] += (b - a) * scipy.signal.welch(x[sl], **kw)[1]
            Gfy[g] += (b - a) * scipy.signal.csd(x[sl, None], y[sl], **kw)[1]
            Gyy[g] += (b - a) * scipy.signal.welch(y[sl], **kw)[1]
        first += n
    return GroupSpectra(f, Gff, Gfy, Gyy, np.diff(bounds))


@dataclass(frozen=True)
class ModeSpread:
    """Jackknife standard errors of one mode: frequency [Hz] and damping ratio [-] (None
    from fewer than three replicates), and how many of the ``groups`` replicates found it."""

    frequency_std_hz: float | None
    damping_std: float | None
    replicates: int
    groups: int


def pair_modes(modes: Sequence[Mode], found: Sequence[Mode], *, cluster_tol: float, bandwidth_fraction: float,
               cluster_mac: float) -> list[Mode | None]:
    """For each of ``modes``, the mode of ``found`` that is the same mode, or None: one to one,
    each pair within the clustering's distance of :meth:`.ema.Stabilisation.select_modes`,
    max(|df| / (tol f), (1 - MAC) / (1 - cluster_mac)) <= 1 with tol = max(``cluster_tol``,
    ``bandwidth_fraction`` x the damping ratio), the nearest pairs first."""
    if not modes or not found:
        return [None] * len(modes)
    f = np.array([m.frequency_hz for m in modes])
    g = np.array([m.frequency_hz for m in found])
    zeta = np.array([m.damping_ratio or 0.0 for m in modes])
    tol = np.maximum(cluster_tol, bandwidth_fraction * zeta)
    d = np.abs(g[None, :] - f[:, None]) / (tol * f)[:, None]
    mac = mac_matrix(np.column_stack([m.shape for m in modes]), np.column_stack([m.shape for m in found]))
    d = np.maximum(d, (1.0 - mac) / (1.0 - cluster_mac))
    rows, cols = scipy.optimize.linear_sum_assignment(np.where(d <= 1.0, d, 1e6))
    out: list[Mode | None] = [None] * len(modes)
    for i, j in zip(rows, cols):
        if d[i, j] <= 1.0:
            out[i] = found[j]
    return out


def _std(x: list[float], groups: int) -> float | None:
    """The delete-a-group jackknife's standard error over the replicates that found the mode,
    scaled by (G - 1) / G for the G groups deleted: fewer replicates than groups do not make
    each one count for more of the data."""
    return float(np.sqrt((groups - 1) / groups * np.sum((np.asarray(x) - np.mean(x)) ** 2))) if len(x) >= 3 else None


def jackknife_modes(spectra: GroupSpectra, modes: Sequence[Mode], identify: Callable[[np.ndarray], list[Mode]], *,
                    cluster_tol: float, bandwidth_fraction: float, cluster_mac: float) -> list[ModeSpread]:
    """The standard errors of ``modes`` (identified from all of ``spectra``): ``identify``
    maps an FRF (n_f, n_out) on ``spectra.frequency`` to its modes, and is run once per
    group on the FRF without it; a mode a replicate loses is judged on those that found it."""
    freq: list[list[float]] = [[] for _ in modes]
    damp: list[list[float]] = [[] for _ in modes]
    n_g = spectra.counts.size
    for g in range(n_g):
        found = identify(spectra.h1(without=g))
        for k, m in enumerate(pair_modes(modes, found, cluster_tol=cluster_tol, bandwidth_fraction=bandwidth_fraction,
                                         cluster_mac=cluster_mac)):
            if m is not None:
                freq[k].append(m.frequency_hz)
                if m.damping_ratio is not None:
                    damp[k].append(m.damping_ratio)
    return [ModeSpread(_std(fk, n_g), _std(dk, n_g), len(fk), n_g) for fk, dk in zip(freq, damp)]
