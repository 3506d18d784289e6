"""Fast batched eigen-analysis of the box model on a parameter-robust reduced basis.

The full model (about 2700 DOF) takes seconds per eigen-solve; a swarm of 1000 particles
over 1000 iterations needs a million. Because K(p) = K0 + sum_i p_i K_i and the mass is
fixed, one basis V (n x r, M-orthonormal) serves a neighbourhood of parameter space: the
full model's lowest modes at a point, kept exactly, and the directions their parameter
derivatives point to, compressed by proper orthogonal decomposition (M-weighted). Each
particle then solves the r x r problem (V^T K(p) V) y = lambda y, all particles in one
batched call, the projected matrices V^T K_i V being formed once.

The reduced frequencies are upper bounds of the full ones (Rayleigh-Ritz); the error is
not assumed: :func:`full_modes` re-solves a point on the full model and
:meth:`ReducedFamily.residuals` gives the eigen-residual of each mode in the energy norm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from .assembly import BoxModel
from .factor import factorise


#: eigenvalues closer than this (relative) are one cluster, whose vectors are made canonical: the
#: symmetric bogies' pairs are equal to 4e-16, and mixing a cluster's vectors moves their Rayleigh
#: quotients by up to this much, which a modal truth must keep under 1e-9 (1e-6 broke that bound)
CLUSTER_RTOL = 1e-10
#: modes solved beyond those asked for, so that a cluster at the cut is seen whole
CLUSTER_EXTRA = 4
#: a basis direction smaller than this, relative, is round-off, not a direction
NEGLIGIBLE = 1e-8


def canonical_vectors(values, vectors, inner=None, *, rtol: float = CLUSTER_RTOL, seed: int = 0) -> np.ndarray:
    """``vectors`` (n, m), sorted by ``values`` (m,), with every cluster of (nearly) equal
    values replaced by a basis that depends on the cluster's span only.

    Of equal eigenvalues only the span of the eigenvectors is defined; which basis of it a
    solver returns is decided by round-off (the box model's two bogies give exactly equal
    pairs: on two BLAS threads instead of one, shapes of a pair rotated by up to 80 degrees,
    and a reduced basis built from them gave frequencies 8e-6 apart at a point 3 % away,
    enough to send a swarm elsewhere). Each cluster's vectors become the projection of fixed
    (seeded) vectors on the span, orthonormalised in order in the ``inner`` product (a
    matrix; None: Euclidean), so any leading part of a cluster is canonical too. A vector
    of a near-equal pair mixes its partner by at most ``rtol`` in eigenvalue."""
    w = np.asarray(values, float)
    X = np.array(vectors, float, copy=True)
    n, m = X.shape
    R = None
    i = 0
    while i < m:
        j = i + 1
        while j < m and abs(w[j] - w[j - 1]) <= rtol * max(abs(w[j]), abs(w[j - 1])):
            j += 1
        if j - i > 1:
            if R is None:
                R = np.random.default_rng(seed).standard_normal((n, m))
            Xc = X[:, i:j]
            MR = R[:, i:j] if inner is None else inner @ R[:, i:j]
            P = Xc @ (Xc.T @ MR)  # the projection of R on the span: the same for any basis of it
            G = P.T @ P if inner is None else P.T @ (inner @ P)
            L = np.linalg.cholesky((G + G.T) / 2)
            X[:, i:j] = scipy.linalg.solve_triangular(L, P.T, lower=True).T
        i = j
    return X


def full_modes(model: BoxModel, p, n_modes: int, shift_hz: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Lowest ``n_modes`` of the full model at parameters p: frequencies [Hz] and
    M-normalised shapes (n_dof, n_modes), by shift-invert Lanczos from a fixed start
    vector (ARPACK's own is random, and the same call must give the same modes); the
    shapes of equal frequencies canonical (:func:`canonical_vectors`)."""
    K, M = model.stiffness(p).tocsc(), model.M.tocsc()
    sigma = -(2 * np.pi * shift_hz) ** 2
    v0 = np.random.default_rng(0).standard_normal(model.n_dof)
    OPinv = factorise(K - sigma * M).operator()
    k = min(n_modes + CLUSTER_EXTRA, model.n_dof - 2)
    w2, X = scipy.sparse.linalg.eigsh(K, k=k, M=M, sigma=sigma, which="LM", v0=v0, OPinv=OPinv)
    order = np.argsort(w2)
    w2, X = w2[order], canonical_vectors(w2[order], X[:, order], M)
    return np.sqrt(np.clip(w2[:n_modes], 0, None)) / (2 * np.pi), X[:, :n_modes]


@dataclass
class ReducedFamily:
    names: tuple[str, ...]
    V: np.ndarray  # (n_dof, r), V^T M V = I
    K0: np.ndarray  # (r, r)
    K_units: np.ndarray  # (d, r, r)
    model: BoxModel

    @classmethod
    def build(cls, model: BoxModel, points, *, modes_per_sample: int = 30, size: int = 60,
              derivatives: int = 0, modes=full_modes) -> "ReducedFamily":
        """Basis from the lowest ``modes_per_sample`` modes at each parameter row of
        ``points``, each with the static responses K(p)^-1 K_i phi_k of its lowest
        ``derivatives`` modes (the directions a first-order change of parameter i moves
        mode k in), compressed to ``size`` vectors. The first point's modes are kept
        exactly. (One basis for a whole 0.5-2 box, from modes at Latin-hypercube points,
        was 0.8-4 % off with 60-120 vectors; a basis around the point of interest, rebuilt
        as that point moves, is 0.03 % off over +-5 % of it.) ``modes``: :func:`full_modes`,
        or a caller's function giving the same (one that keeps the modes it solved for)."""
        points = np.atleast_2d(np.asarray(points, float))
        M = model.M
        primary = None  # the modes at the first point stay in the basis exactly
        blocks = []
        for p in points:
            _, X = modes(model, p, modes_per_sample)
            if primary is None:
                primary = X
            else:
                blocks.append(X)
            if derivatives:
                lu = factorise(model.stiffness(p))
                for name in model.names:
                    blocks.append(lu.solve(model.K_units[name] @ X[:, :derivatives]))
        V = primary
        if blocks and size > V.shape[1]:
            S = np.hstack(blocks)
            before = np.sqrt(np.einsum("ij,ij->j", S, M @ S))
            S = S - V @ (V.T @ (M @ S))  # M-orthogonal to the primary modes
            after = np.sqrt(np.einsum("ij,ij->j", S, M @ S))
            # a direction that is zero but for round-off (a factor a mode does not strain, or a
            # response inside the modes' span) would be blown up to a unit vector of noise by
            # the normalisation below: on one BLAS thread or two, another basis
            real = (before > NEGLIGIBLE * before.max()) & (after > NEGLIGIBLE * before)
            S = S[:, real] / after[real][None, :]  # every direction counts alike
            G = S.T @ (M @ S)  # POD in the M inner product
            lam, U = scipy.linalg.eigh((G + G.T) / 2)
            lam, U = lam[::-1], canonical_vectors(lam[::-1], U[:, ::-1])  # the model's symmetry: equal pairs
            keep = np.arange(min(size - V.shape[1], lam.size))
            V = np.hstack([V, S @ (U[:, keep] / np.sqrt(lam[keep]))])
        L = np.linalg.cholesky(V.T @ (M @ V))  # re-orthonormalise against round-off
        V = scipy.linalg.solve_triangular(L, V.T, lower=True).T
        return cls.from_basis(model, V)

    @classmethod
    def from_basis(cls, model: BoxModel, V: np.ndarray) -> "ReducedFamily":
        def project(A):
            P = V.T @ (A @ V)
            return (P + P.T) / 2
        return cls(model.names, V, project(model.K0), np.stack([project(model.K_units[n]) for n in model.names]),
                   model)

    @property
    def size(self) -> int:
        return self.V.shape[1]

    def stiffness(self, P: np.ndarray) -> np.ndarray:
        P = np.atleast_2d(P)
        return self.K0[None] + np.einsum("ni,ijk->njk", P, self.K_units)

    def modes(self, P: np.ndarray, n_modes: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Batched: frequencies (N, m) [Hz] and reduced shapes (N, r, m) of the lowest
        ``n_modes`` modes (all r when None); full shapes are V @ y."""
        w2, Y = np.linalg.eigh(self.stiffness(P))
        if n_modes is not None:
            w2, Y = w2[:, :n_modes], Y[:, :, :n_modes]
        return np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi), Y

    def residuals(self, p, n_modes: int) -> np.ndarray:
        """Relative eigen-residual of each reduced mode in the full model, in the energy
        (K^-1) norm: ||K x - lambda M x||_K^-1 / ||lambda M x||_K^-1. (The plain Euclidean
        norm is dominated by the stiff joint penalties and says little about frequencies.)"""
        f, Y = self.modes(np.asarray(p, float)[None, :], n_modes)
        X = self.V @ Y[0]
        lam = (2 * np.pi * f[0]) ** 2
        K = self.model.stiffness(p).tocsc()
        lu = factorise(K)
        R = K @ X - (self.model.M @ X) * lam
        B = (self.model.M @ X) * lam
        return np.sqrt(np.einsum("ij,ij->j", R, lu.solve(R)) / np.einsum("ij,ij->j", B, lu.solve(B)))
