"""What targeted frequencies can and cannot determine about the parameters.

At a parameter set p the relative sensitivity matrix is

    S_ij = (p_j / f_i) df_i/dp_j,

exact from the eigenvectors: for mass-normalised phi, d(w^2)/dp = phi^T (dK/dp - w^2 dM/dp) phi
(the model is linear in the parameters, so dK/dp and dM/dp are its unit matrices). With
S = U diag(s) V^T:

* singular values above ``rtol`` times the largest count as determined (the rank); the
  remaining right singular vectors, together with the d - m directions four frequencies
  cannot reach in six parameters, are the undetermined directions: moving the parameters
  along one of them by a relative step changes no targeted frequency to first order;
* relative uncertainties ``sigma_f`` of the measured frequencies (one for all, or one per
  mode) weight the rows of S; with the weighted S = U diag(s) V^T, a 95 % interval of
  +-1.96 / s_k follows on the coordinate v_k^T log(p / p*) of each determined direction k
  (the Gauss-Newton linearisation at the optimum);
* parameters within ``bound_tol`` of a range end are flagged (the seed's m_v).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..models.batch import LinearFamily


def frequency_sensitivities(family: LinearFamily, p: np.ndarray, labels: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Frequencies f (m,) [Hz] and df/dp (m, d) [Hz per unit] at one parameter row, for ``labels``
    (the lowest mode of each label, as :func:`frequencies_by_label` reports)."""
    rows, f_out = [], []
    for lbl in labels:
        w2, phi = family.labelled_mode(p, lbl)
        w = np.sqrt(w2)
        dw2 = np.array([phi @ (family.K_unit[n] - w2 * family.M_unit[n]) @ phi for n in family.names])
        rows.append(dw2 / (2 * w) / (2 * np.pi))
        f_out.append(w / (2 * np.pi))
    return np.array(f_out), np.array(rows)


@dataclass(frozen=True)
class Direction:
    singular_value: float
    vector: np.ndarray  # unit vector over relative parameter changes
    names: tuple[str, ...]

    def describe(self, threshold: float = 0.2) -> str:
        """In parameter terms, e.g. '+0.62 k_s +0.55 J_v -0.41 m_v' (relative changes)."""
        order = np.argsort(-np.abs(self.vector))
        parts = [f"{self.vector[i]:+.2f} {self.names[i]}" for i in order if abs(self.vector[i]) >= threshold]
        return " ".join(parts)


@dataclass(frozen=True)
class Identifiability:
    names: tuple[str, ...]
    labels: tuple[str, ...]
    sensitivity: np.ndarray  # relative, (m, d)
    singular_values: np.ndarray
    rank: int
    determined: tuple[Direction, ...]
    undetermined: tuple[Direction, ...]
    intervals: tuple[tuple[float, float], ...]  # 95 % on each determined coordinate v^T log(p/p*)
    at_bound: tuple[str, ...]
    sigma_f: tuple[float, ...]  # relative, per mode

    def to_json(self) -> dict:
        return {
            "parameters": list(self.names), "modes": list(self.labels),
            "relative_sensitivity": self.sensitivity.round(6).tolist(),
            "singular_values": self.singular_values.round(6).tolist(), "rank": self.rank,
            "determined_directions": [{"singular_value": d.singular_value, "vector": d.vector.round(4).tolist(),
                                       "in_words": d.describe(),
                                       "interval_95_log": list(iv)} for d, iv in zip(self.determined, self.intervals)],
            "undetermined_directions": [{"singular_value": d.singular_value, "vector": d.vector.round(4).tolist(),
                                         "in_words": d.describe()} for d in self.undetermined],
            "at_bound": list(self.at_bound),
            "frequency_uncertainty_relative": dict(zip(self.labels, self.sigma_f)),
            "summary": self.summary(),
        }

    def summary(self) -> str:
        n = len(self.labels)
        verb = "frequency determines" if n == 1 else "frequencies determine"
        text = (f"{n} {verb} {self.rank} of {len(self.names)} parameter combinations; "
                f"{len(self.undetermined)} cannot be determined")
        if self.undetermined:
            text += ": " + "; ".join(f"({d.describe()})" for d in self.undetermined)
        if self.at_bound:
            text += f". At a range limit: {', '.join(self.at_bound)}"
        return text

    def contains(self, p_true: np.ndarray, p_opt: np.ndarray) -> list[bool]:
        """Whether ``p_true`` lies inside each determined direction's 95 % interval."""
        x = np.log(np.asarray(p_true) / np.asarray(p_opt))
        return [lo <= d.vector @ x <= hi for d, (lo, hi) in zip(self.determined, self.intervals)]


def identifiability(family: LinearFamily, p: np.ndarray, labels: tuple[str, ...], *, sigma_f=0.005,
                    low=None, high=None, rtol: float = 1e-3, bound_tol: float = 0.005) -> Identifiability:
    """``sigma_f``: relative frequency uncertainty, a number for every mode or one per label."""
    p = np.asarray(p, float)
    f, J = frequency_sensitivities(family, p, labels)
    S = J * p[None, :] / f[:, None]
    sigma = np.broadcast_to(np.asarray(sigma_f, float), (len(labels),)).copy()
    if not np.all(sigma > 0):
        raise ValueError(f"frequency uncertainties must be > 0, got {sigma}")
    U, s, Vt = np.linalg.svd(S / sigma[:, None], full_matrices=True)
    rank = int(np.sum(s > rtol * s[0]))
    names = family.names
    determined = tuple(Direction(float(s[k]), Vt[k], names) for k in range(rank))
    undetermined = tuple(Direction(float(s[k]) if k < s.size else 0.0, Vt[k], names) for k in range(rank, len(names)))
    intervals = tuple((-1.96 / d.singular_value, 1.96 / d.singular_value) for d in determined)
    at_bound = []
    if low is not None and high is not None:
        for n, v, lo, hi in zip(names, p, low, high):
            if np.isfinite(lo) and np.isfinite(hi):
                span = hi - lo
                if v - lo <= bound_tol * span:
                    at_bound.append(f"{n} (lower)")
                elif hi - v <= bound_tol * span:
                    at_bound.append(f"{n} (upper)")
    return Identifiability(names, tuple(labels), S, s, rank, determined, undetermined, intervals, tuple(at_bound),
                           tuple(float(x) for x in sigma))
