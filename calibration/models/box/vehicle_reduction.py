"""The box-type vehicle reduced for time simulation (the box FMU and its reference).

The carbody (panels, joints, iron blocks) is represented by its free-free modes below a
cut-off and by residual-flexibility pseudo-modes (static correction): for every load the
carbody takes (the exciter, and each suspension element's seat along each axis it acts
in) the static shape of the modes left out, found by a shifted solve and M-orthogonalised
against the kept modes, then diagonalised among themselves (Craig & Kurdila, *Fundamentals
of structural dynamics*, 2006, section 17.5; the "modal truncation augmentation" of
Dickens, Nakagawa & Wittbrodt, Comput. Struct. 62 (1997) 985-998). The bogies (and an
extended model's equipment) stay rigid bodies with their free DOF (six for a bogie) and the
suspension elements stay elements, assembled on these
coordinates the way :mod:`.assembly` assembles them on the full model; the wheelsets are
held by the axle boxes to the rail, whose vertical level under wheelset j is an input.

q = (eta, bogie1 (x, y, z, roll, pitch, yaw), bogie2 (...), ...), with eta the carbody's
generalised coordinates (M-orthonormal, K-diagonal: stiffness omega^2), so

    M q'' + (C_s + C_c) q' + K q = B_k z + B_c dz + b_f F

with C_s from the suspension dampers and C_c = diag(2 zeta omega) on the carbody's elastic
coordinates (zeta a parameter). Floor accelerations are S q''.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse.linalg

from ...signals.modal import count_modes_below
from .assembly import RIGID_DOFS, BoxModel, local_operator, assemble
from .shinkansen import free_carbody

RIGID_HZ = 0.05  # carbody modes below this are its six rigid-body motions


@dataclass(frozen=True)
class ReducedVehicle:
    names: tuple[str, ...]  # generalised coordinates
    M: np.ndarray  # (nq, nq) diagonal
    K: np.ndarray  # (nq, nq)
    C_suspension: np.ndarray  # (nq, nq)
    omega: np.ndarray  # (nq,) [rad/s] of the carbody coordinates (0 for rigid ones and bogie DOFs)
    elastic: np.ndarray  # (nq,) bool: carbody coordinates that take the structural damping
    B_k: np.ndarray  # (nq, 4) rail level under wheelsets 1-4 [m] -> force
    B_c: np.ndarray  # (nq, 4) its rate [m/s] -> force
    b_force: np.ndarray  # (nq,) exciter force [N] -> generalised force
    S: np.ndarray  # (n_sensors, nq) floor vertical displacement per coordinate
    sensors: tuple[str, ...]
    n_modes: int  # true carbody modes kept (the rest of the carbody coordinates are pseudo-modes)
    cutoff_hz: float
    wheelset_x: np.ndarray  # (4,) [m] wheelsets 1 (leading) .. 4

    @property
    def n_carbody(self) -> int:
        """The carbody's coordinates: its modes and pseudo-modes."""
        return sum(n.startswith("carbody_") for n in self.names)

    def damping(self, zeta: float) -> np.ndarray:
        return self.C_suspension + np.diag(np.where(self.elastic, 2.0 * zeta * self.omega, 0.0))

    def state_space(self, zeta: float):
        """x' = A x + B w, y = C x + D w with x = (q, q'), w = (z_1..4, dz_1..4, F), y = floor
        accelerations."""
        from ..car2d import StateSpace

        nq = self.M.shape[0]
        Minv = np.diag(1.0 / np.diag(self.M))
        C = self.damping(zeta)
        acc_x = np.hstack([-Minv @ self.K, -Minv @ C])
        acc_w = Minv @ np.hstack([self.B_k, self.B_c, self.b_force[:, None]])
        A = np.block([[np.zeros((nq, nq)), np.eye(nq)], [acc_x]])
        B = np.vstack([np.zeros((nq, acc_w.shape[1])), acc_w])
        inputs = tuple(f"z_rail_{j}" for j in range(1, 5)) + tuple(f"dz_rail_{j}" for j in range(1, 5)) + (
            "exciter_force",)
        return StateSpace(A, B, self.S @ acc_x, self.S @ acc_w, self.sensors, inputs)


def carbody_basis(cb: BoxModel, p, cutoff_hz: float, loads: np.ndarray, shift_hz: float = 0.5):
    """(V, omega, n_modes): free carbody modes below ``cutoff_hz`` and the pseudo-modes of
    the residual flexibility for ``loads`` (n_dof, n_loads), M-orthonormal, K-diagonal.

    K - sigma M (sigma = -(2 pi ``shift_hz``)^2) is factorised once and serves both the
    shift-invert Lanczos solve for the modes and the loads' static shapes; the number of
    modes to ask for is counted beforehand
    (:func:`calibration.signals.modal.count_modes_below`), so one eigen-solve
    suffices."""
    K, M = cb.stiffness(p).tocsc(), cb.M.tocsc()
    sigma = -(2 * np.pi * shift_hz) ** 2
    lu = scipy.sparse.linalg.splu((K - sigma * M).tocsc())
    OPinv = scipy.sparse.linalg.LinearOperator(K.shape, matvec=lu.solve, dtype=float)
    v0 = np.random.default_rng(0).standard_normal(cb.n_dof)
    below = count_modes_below(K, M, cutoff_hz)
    # a few more than counted: the highest wanted mode is not the last one asked for, and the
    # first unwanted one shows the cut-off passed. Without a count (the symmetric factorisation
    # pivoted or broke down), grow the request until the cut-off is passed, as before.
    n = min(below + 4, cb.n_dof - 2) if below is not None else 40
    while True:
        _, X = scipy.sparse.linalg.eigsh(K, k=n, M=M, sigma=sigma, which="LM", v0=v0, OPinv=OPinv)
        # the eigenvalues as the vectors' Rayleigh quotients: Lanczos' own, sigma + 1/theta,
        # carry the shifted solve's round-off (K's joint springs make K - sigma M ill-conditioned:
        # 1e-8 relative on some modes, depending on the factorisation's ordering), the quotients
        # only its square (1e-11 against a dense solve)
        w2 = np.einsum("ij,ij->j", X, K @ X) / np.einsum("ij,ij->j", X, M @ X)
        order = np.argsort(w2)
        w2, X = w2[order], X[:, order]
        if np.sqrt(max(w2[-1], 0.0)) / (2 * np.pi) > cutoff_hz or n >= cb.n_dof - 2:
            break
        n = min(n + 40, cb.n_dof - 2)
    keep = np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi) <= cutoff_hz
    X, w2 = X[:, keep], np.clip(w2[keep], 0, None)
    # static shapes of the loads, shifted (the free carbody's K is singular), less the kept modes
    Psi = lu.solve(np.asarray(loads, float))
    for _ in range(2):  # M-orthogonal to the kept modes, twice for round-off
        Psi = Psi - X @ (X.T @ (M @ Psi))
    G = Psi.T @ (M @ Psi)
    lam, U = np.linalg.eigh(G)
    ok = lam > lam.max() * 1e-10  # independent directions only
    Psi = Psi @ U[:, ok] / np.sqrt(lam[ok])
    Kp = Psi.T @ (K @ Psi)
    wp, Up = scipy.linalg.eigh(0.5 * (Kp + Kp.T))
    Psi = Psi @ Up
    V = np.hstack([X, Psi])
    return V, np.sqrt(np.append(w2, np.clip(wp, 0, None))), int(X.shape[1])


def reduce_vehicle(model: BoxModel, parameters, cutoff_hz: float, sensors, exciter) -> ReducedVehicle:
    """``model``: the assembled vehicle (carbody, bogies, suspension; shinkansen_vehicle);
    ``parameters``: its stiffness factors by name or in model.names order."""
    p = np.array([float(parameters[n]) for n in model.names]) if isinstance(parameters, dict) else \
        np.asarray(parameters, float)
    vehicle = model.vehicle
    panels = {pn.name for pn in vehicle.panels}
    cb = assemble(free_carbody(vehicle))
    n_cb = cb.n_dof
    bodies = [b for b in vehicle.bodies]
    free = {b.name: [i for i, d in enumerate(RIGID_DOFS) if d not in b.fixed] for b in bodies}
    # carbody loads: the exciter and every suspension seat along each axis the element acts in
    seats = []
    for ln in vehicle.links:
        if ln.body_a in panels:
            idx, G = local_operator(model, ln.body_a, ln.point_a, patch=ln.patch)
            for d in range(3):
                if ln.k[d] or ln.c[d]:
                    f = np.zeros(n_cb)
                    f[idx] = G[d]
                    seats.append(f)
    from ..box.fit import sensor_operator

    e_full = sensor_operator(model, (exciter,))[0]
    S_full = sensor_operator(model, sensors)
    loads = np.column_stack([e_full[:n_cb]] + seats)
    V, omega_c, n_modes = carbody_basis(cb, p, cutoff_hz, loads)
    n_eta = V.shape[1]
    nq = n_eta + sum(len(v) for v in free.values())
    body_col = dict(zip(free, n_eta + np.cumsum([0] + [len(v) for v in free.values()])[:-1]))

    def operator(body, point, patch=(0.0, 0.0)):
        """(3, nq) displacement of a material point in the reduced coordinates."""
        out = np.zeros((3, nq))
        if body == "ground":
            return out
        if body in panels:
            idx, G = local_operator(model, body, point, patch=patch)
            out[:, :n_eta] = G @ V[idx]
            return out
        rb = next(b for b in bodies if b.name == body)
        out[:, body_col[body]:body_col[body] + len(free[body])] = rb.operator(point)[:, free[body]]
        return out

    M = np.zeros((nq, nq))
    M[:n_eta, :n_eta] = np.eye(n_eta)
    for b in bodies:
        c, n = body_col[b.name], len(free[b.name])
        M[c:c + n, c:c + n] = np.diag(np.array([b.mass] * 3 + list(b.inertia))[free[b.name]])
    K = np.zeros((nq, nq))
    K[:n_eta, :n_eta] = np.diag(omega_c**2)
    C = np.zeros((nq, nq))
    xw = []
    for ln in vehicle.links:
        if ln.body_a == "ground" and ln.body_b != "ground":
            xw.append(ln.point_a[0])
    wheelset_x = np.array(sorted(set(np.round(xw, 9)), reverse=True))
    if wheelset_x.size != 4:
        raise ValueError(f"expected axle boxes at four wheelset positions, found {wheelset_x}")
    B_k, B_c = np.zeros((nq, 4)), np.zeros((nq, 4))
    for ln in vehicle.links:
        D = operator(ln.body_a, ln.point_a, ln.patch) - operator(ln.body_b, ln.point_b)
        K += D.T @ np.diag(ln.k) @ D
        C += D.T @ np.diag(ln.c) @ D
        if ln.body_a == "ground":  # the ground end rides on the rail: e = D q + e_z z_j
            j = int(np.argmin(np.abs(wheelset_x - ln.point_a[0])))
            B_k[:, j] -= D.T @ (np.asarray(ln.k) * np.array([0.0, 0.0, 1.0]))
            B_c[:, j] -= D.T @ (np.asarray(ln.c) * np.array([0.0, 0.0, 1.0]))
    b_force = np.zeros(nq)
    b_force[:n_eta] = V.T @ e_full[:n_cb]
    S = np.zeros((S_full.shape[0], nq))
    S[:, :n_eta] = S_full[:, :n_cb] @ V
    elastic = np.zeros(nq, bool)
    elastic[:n_eta] = omega_c > 2 * np.pi * RIGID_HZ
    omega = np.zeros(nq)
    omega[:n_eta] = omega_c
    names = tuple(f"carbody_mode_{k + 1}" for k in range(n_modes)) + tuple(
        f"carbody_pseudo_{k + 1}" for k in range(n_eta - n_modes)) + tuple(
        f"{b.name}_{RIGID_DOFS[i]}" for b in bodies for i in free[b.name])
    return ReducedVehicle(names, M, K, C, omega, elastic, B_k, B_c, b_force, S, tuple(s.name for s in sensors),
                          n_modes, float(cutoff_hz), wheelset_x)


def frf_full(model: BoxModel, parameters, frequencies_hz, sensors, exciter, zeta_modes=None) -> np.ndarray:
    """Accelerance (n_f, n_sensors) from the exciter force to the sensors by direct solves of
    the full vehicle (suspension damping only): the reduction's yardstick."""
    from ..box.fit import sensor_operator

    p = np.array([float(parameters[n]) for n in model.names]) if isinstance(parameters, dict) else \
        np.asarray(parameters, float)
    K, M, C = model.stiffness(p).tocsc(), model.M.tocsc(), model.C.tocsc()
    e = sensor_operator(model, (exciter,))[0]
    S = sensor_operator(model, sensors)
    out = []
    for f in np.atleast_1d(frequencies_hz):
        w = 2 * np.pi * f
        x = scipy.sparse.linalg.spsolve((K - w**2 * M + 1j * w * C).tocsc(), e)
        out.append(-w**2 * (S @ x))
    return np.array(out)


def frf_reduced(r: ReducedVehicle, frequencies_hz, zeta: float = 0.0) -> np.ndarray:
    C = r.damping(zeta)
    out = []
    for f in np.atleast_1d(frequencies_hz):
        w = 2 * np.pi * f
        x = np.linalg.solve(r.K - w**2 * r.M + 1j * w * C, r.b_force)
        out.append(-w**2 * (r.S @ x))
    return np.array(out)
