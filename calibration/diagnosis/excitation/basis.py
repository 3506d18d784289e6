"""The reduced-basis engine of the excitation-test diagnosis: the box model (and a softened
panel) projected on Rayleigh-Ritz bases rebuilt around the current point, with what an FRF
and the classification of its modes need.

A basis holds the full model's modes (all those below ``basis_hz``, kept exactly), the
static responses to the exciter (and to an equipment's mount), and parameter-derivative
directions compressed by proper orthogonal decomposition in the M inner product.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg

from ...data.campaign import Sensor
from ...models.box import BoxModel
from ...models.box.assembly import panel_parts
from ...models.box.factor import factorise
from ...models.box.fit import sensor_operator
from ...models.box.modal import rigid_probe
from ...models.box.parametric_basis import CLUSTER_EXTRA, NEGLIGIBLE, canonical_vectors
from ...signals.modal import count_modes_below


def points_operator(model: BoxModel, points) -> np.ndarray:
    """Vertical displacement rows (n, n_dof) at floor points (x, y) [m] (at the middle
    floor's height)."""
    z = model.panel("floor_middle").centre[2]
    sensors = tuple(Sensor(f"p{i}", "displacement", "m", "floor", "z", (float(x), float(y), z))
                    for i, (x, y) in enumerate(points))
    return sensor_operator(model, sensors)


@dataclass(frozen=True, eq=False)
class Operators:
    """What every reduced model of one campaign reads, built once on the full model.

    S : (n_s, n_dof) the sensors' vertical displacement
    e : (n_dof,) the exciter's
    bogie : indices of the bogies' DOFs
    rigid_D : (3 n_points, n_dof) displacements at the rigid-body test points
        (:func:`calibration.models.box.modal.rigid_probe`)
    rigid_Q : (3 n_points, 6) orthonormal rigid-body fields there
    panel_units : cache, panel name -> (K0 part, {factor name: part}) of its rigidity energy
    """

    model: BoxModel
    S: np.ndarray
    e: np.ndarray
    bogie: np.ndarray
    rigid_D: np.ndarray
    rigid_Q: np.ndarray
    panel_units: dict

    @classmethod
    def build(cls, model: BoxModel, sensors, exciter) -> "Operators":
        S = sensor_operator(model, sensors)
        e = sensor_operator(model, (exciter,))[0]
        bogie = np.concatenate([np.arange(model.n_dof)[model.dof_slices[b.name]] for b in model.vehicle.bodies]) \
            if model.vehicle.bodies else np.zeros(0, int)
        D, R = rigid_probe(model)
        Q, _ = np.linalg.qr(R)
        return cls(model, S, e, bogie, D, Q, {})

    def panel_stiffness(self, panel: str) -> tuple[sp.csr_matrix, dict]:
        """The panel's rigidity energy split as the assembly does: the part no factor
        scales and one part per factor (sparse, full size); softening the panel by a
        divisor s is K(p) - (1 - 1/s) (K0_P + sum_i p_i K_P,i)."""
        if panel in self.panel_units:
            return self.panel_units[panel]
        model = self.model
        pn = model.panel(panel)
        s = model.dof_slices[panel]
        idx = np.arange(s.start, s.stop)
        parts = panel_parts(model.vehicle.parameters, pn)
        n = model.n_dof

        def full(block):
            r, c = np.meshgrid(idx, idx, indexing="ij")
            return sp.csr_matrix((np.asarray(block).ravel(), (r.ravel(), c.ravel())), shape=(n, n))

        out = (full(parts.pop(None, np.zeros((idx.size, idx.size)))),
               {k: full(v) for k, v in parts.items()})
        self.panel_units[panel] = out
        return out

    def own_group_factors(self, panel: str) -> tuple[str, ...]:
        """The factors whose whole energy is this panel's (the roof's factors for the roof,
        alone in its group)."""
        model = self.model
        _, Kp = self.panel_stiffness(panel)
        out = []
        for n, A in Kp.items():
            if abs(model.K_units[n] - A).sum() <= 1e-9 * abs(model.K_units[n]).sum():
                out.append(n)
        return tuple(out)


@dataclass(frozen=True, eq=False)
class Stiffness:
    """A point of the model family: the box model's factors ``p`` and an optional softened
    ``panel`` with rigidities divided by ``divisor``."""

    p: np.ndarray
    panel: str | None = None
    divisor: float = 1.0

    def matrix(self, ops: Operators) -> sp.csr_matrix:
        """K [N/m] of the full model at this point."""
        K = ops.model.stiffness(self.p)
        if self.panel is None or self.divisor == 1.0:
            return K
        K0p, Kp = ops.panel_stiffness(self.panel)
        g = 1.0 - 1.0 / self.divisor
        part = K0p + sum(self.p[ops.model.names.index(n)] * A for n, A in Kp.items())
        return (K - g * part).tocsr()


def modes_below(model: BoxModel, p, hz: float, start: int = 60) -> int:
    """How many modes of the box model at factors ``p`` lie below ``hz`` [Hz]: counted by
    Sylvester's law of inertia (:func:`calibration.signals.modal.count_modes_below`) or,
    where that factorisation is not usable, by solving the lowest modes in growing batches
    (from ``start``) until one passes ``hz``."""
    K = model.stiffness(np.asarray(p, float))
    n = count_modes_below(K, model.M, hz)
    if n is not None:
        return n
    lu = factorise(K)
    k = min(start, model.n_dof - 2)
    while True:
        w2, _ = lowest_modes(K, model.M, k, lu)
        n = int(np.sum(np.sqrt(np.clip(w2, 0, None)) < 2 * np.pi * hz))
        if n < k or k >= model.n_dof - 2:
            return n
        k = min(2 * k, model.n_dof - 2)


def lowest_modes(K, M, n_modes: int, lu=None) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``n_modes`` eigenpairs (omega^2 [rad^2/s^2], M-normalised shapes) of
    K x = lambda M x (K positive definite: the vehicle stands on its suspension),
    shift-invert about 0 with the factorisation ``lu`` of K (made here when not given),
    from a fixed start vector; shapes of equal eigenvalues canonical.

    Not :func:`calibration.models.box.parametric_basis.full_modes` (shifted below 0 and factorising
    K - sigma M): a basis needs the factorisation of K itself for its static responses, and
    this reuses it."""
    lu = factorise(K) if lu is None else lu
    op = scipy.sparse.linalg.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
    v0 = np.random.default_rng(0).standard_normal(K.shape[0])
    k = min(n_modes + CLUSTER_EXTRA, K.shape[0] - 2)
    w2, X = scipy.sparse.linalg.eigsh(K.tocsc(), k=k, M=M.tocsc(), sigma=0.0, OPinv=op, which="LM", v0=v0)
    order = np.argsort(w2)
    w2, X = w2[order], canonical_vectors(w2[order], X[:, order], M)  # equal pairs: shapes round-off does not turn
    return w2[:n_modes], X[:, :n_modes]


def m_orthonormal(V: np.ndarray, M) -> np.ndarray:
    """An M-orthonormal basis of the span of ``V``'s columns (directions with a Gram
    eigenvalue below 1e-12 of the largest dropped)."""
    V = V / np.sqrt(np.einsum("ij,ij->j", V, M @ V))[None, :]  # unit columns first: statics are tiny
    G = V.T @ (M @ V)
    lam, U = scipy.linalg.eigh((G + G.T) / 2)
    keep = lam > 1e-12 * lam.max()
    return V @ (U[:, keep] / np.sqrt(lam[keep]))


@dataclass(frozen=True, eq=False)
class Modes:
    """Modes of a reduced model at one point.

    omega : (r,) [rad/s]
    Y : (r, r) reduced shapes (full shapes V @ Y, M-normalised)
    sensor_shapes : (n_s, r) and exciter_shape : (r,) their vertical values [1/sqrt(kg)]
    elastic : (r,) bool, carbody elastic (neither a bogie nor a carbody rigid-body mode)
    suspension_zeta : (r,) the suspension's proportional damping estimate [-]
    """

    omega: np.ndarray
    Y: np.ndarray
    sensor_shapes: np.ndarray
    exciter_shape: np.ndarray
    elastic: np.ndarray
    suspension_zeta: np.ndarray

    @property
    def frequency_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)


@dataclass(frozen=True, eq=False)
class ReducedFRFModel:
    """The model family projected on a basis V (n_dof, r), V^T M V = I, for FRFs:
    K_r(theta) = K0 + sum_j c_j(theta) K_j with the terms [factors..., panel parts...], and
    the damping, sensor, exciter and mode-classification rows on the same basis.

    Not :class:`calibration.models.box.parametric_basis.ReducedFamily` (the swarm's batched
    eigen-solver over the factors alone) nor :class:`calibration.models.box.vehicle_reduction.ReducedVehicle`
    (a time-domain reduction with rigid bogies): this one carries a softened panel's terms,
    static responses in its basis and what an accelerance and the truth's mode classes need.

    C : (r, r) suspension damping; S : (n_s, r) sensors; e : (r,) exciter; B : (r, r) bogie
    mass; RD : (3 n_points, r) rigid-body test points; RQD : its part off the rigid fields.
    """

    V: np.ndarray
    K0: np.ndarray
    K_terms: np.ndarray  # (d, r, r): the factors' unit matrices, then (softening) the panel's parts
    panel: str | None
    C: np.ndarray
    S: np.ndarray
    e: np.ndarray
    B: np.ndarray
    RD: np.ndarray
    RQD: np.ndarray
    ops: Operators

    @classmethod
    def build(cls, ops: Operators, at: Stiffness, *, n_modes: int, n_deriv: int, extra: int,
              below_hz: float | None = None, static_rows=(), extra_points: tuple[Stiffness, ...] = ()
              ) -> "ReducedFRFModel":
        """Basis: the full model's lowest ``n_modes`` modes at ``at`` (more if needed to
        hold every mode below ``below_hz`` [Hz]; kept exactly), the static responses K^-1 b
        of the exciter and of ``static_rows`` (kept exactly), and, compressed to ``extra``
        vectors by POD, the derivative directions K^-1 K_i phi_k of the lowest ``n_deriv``
        modes for every factor (and the softened panel) and the modes at ``extra_points``."""
        model = ops.model
        K = at.matrix(ops)
        M = model.M
        lu = factorise(K)
        w2, X = lowest_modes(K, M, n_modes, lu)
        while below_hz is not None and w2[-1] < (2 * np.pi * below_hz) ** 2 and X.shape[1] < model.n_dof - 22:
            w2, X = lowest_modes(K, M, X.shape[1] + 20, lu)  # a softened panel brings its modes down
        n_modes = X.shape[1]
        statics = lu.solve(np.column_stack([ops.e, *static_rows]))
        dirs = [model.K_units[n] for n in model.names]
        if at.panel is not None:
            K0p, Kp = ops.panel_stiffness(at.panel)
            dirs.append(K0p + sum(at.p[model.names.index(n)] * A for n, A in Kp.items()))
        blocks = [lu.solve(D @ X[:, :n_deriv]) for D in dirs]
        for q in extra_points:
            blocks.append(lowest_modes(q.matrix(ops), M, n_modes)[1])
        V = m_orthonormal(np.hstack([X, statics]), M)
        size = V.shape[1] + extra
        if extra > 0 and blocks:
            Sb = np.hstack(blocks)
            before = np.sqrt(np.einsum("ij,ij->j", Sb, M @ Sb))
            Sb = Sb - V @ (V.T @ (M @ Sb))
            after = np.sqrt(np.einsum("ij,ij->j", Sb, M @ Sb))
            # directions that are round-off only (a factor a mode does not strain) are left out,
            # not normalised into noise that differs with the BLAS thread count
            real = (before > NEGLIGIBLE * before.max()) & (after > NEGLIGIBLE * before)
            Sb = Sb[:, real] / after[real][None, :]
            G = Sb.T @ (M @ Sb)
            lam, U = scipy.linalg.eigh((G + G.T) / 2)
            lam, U = lam[::-1], canonical_vectors(lam[::-1], U[:, ::-1])
            keep = np.arange(min(size - V.shape[1], lam.size))
            keep = keep[lam[keep] > 1e-10 * lam.max()]
            V = m_orthonormal(np.hstack([V, Sb @ (U[:, keep] / np.sqrt(lam[keep]))]), M)

        def project(A):
            P = V.T @ (A @ V)
            return (P + P.T) / 2

        terms = [project(model.K_units[n]) for n in model.names]
        K0 = project(model.K0)
        if at.panel is not None:
            K0p, Kp = ops.panel_stiffness(at.panel)
            terms += [project(Kp[n]) if n in Kp else np.zeros((V.shape[1],) * 2) for n in model.names]
            terms.append(project(K0p))
        Vb = V[ops.bogie]
        B = Vb.T @ (M[ops.bogie][:, ops.bogie] @ Vb) if ops.bogie.size else np.zeros((V.shape[1],) * 2)
        RD = ops.rigid_D @ V
        return cls(V, K0, np.stack(terms), at.panel, project(model.C), ops.S @ V, V.T @ ops.e, B, RD,
                   RD - ops.rigid_Q @ (ops.rigid_Q.T @ RD), ops)

    @property
    def size(self) -> int:
        return self.V.shape[1]

    def coefficients(self, p, divisor: float = 1.0) -> np.ndarray:
        """c(theta) of the terms at factors ``p`` and the softened panel's ``divisor``."""
        p = np.asarray(p, float)
        if self.panel is None:
            return p
        g = 1.0 - 1.0 / divisor
        return np.concatenate([p, -g * p, [-g]])

    def modes(self, p, divisor: float = 1.0, classify_below_hz: float = np.inf) -> Modes:
        """Modes at factors ``p`` (and the softened panel's ``divisor``), each classified as
        the truth does (bogie: most kinetic energy in the bogies; carbody rigid: > 95 %
        rigid motion; else elastic) with the suspension's damping estimate; modes above
        ``classify_below_hz`` [Hz] are taken as elastic."""
        K = self.K0 + np.tensordot(self.coefficients(p, divisor), self.K_terms, axes=1)
        w2, Y = np.linalg.eigh(K)
        w = np.sqrt(np.clip(w2, 1e-6, None))
        n = int(np.searchsorted(w, 2 * np.pi * classify_below_hz))
        Yc = Y[:, :n]
        bogie = np.einsum("ij,ij->j", Yc, self.B @ Yc)
        d = self.RD @ Yc
        rigid = 1.0 - np.sum((self.RQD @ Yc) ** 2, axis=0) / np.maximum(np.sum(d**2, axis=0), 1e-300)
        elastic = np.ones(w.size, bool)
        elastic[:n] = (bogie <= 0.5) & (rigid <= 0.95)
        zeta_s = np.zeros(w.size)
        zeta_s[:n] = np.einsum("ij,ij->j", Yc, self.C @ Yc) / (2 * w[:n])
        return Modes(w, Y, self.S @ Y, Y.T @ self.e, elastic, zeta_s)

    def mount_rows(self, points) -> np.ndarray:
        """(n, r): the basis's vertical displacements at floor points (x, y) [m]."""
        return points_operator(self.ops.model, points) @ self.V
