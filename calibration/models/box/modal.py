"""Modal model of the box vehicle: the modes of the full model up to a cut-off, plus the
residual pseudo-mode(s) that make its static and low-frequency response exact.

A residual pseudo-mode is the static response of the omitted modes to a load,
psi = K^-1 e - sum_kept phi phi^T e / omega^2; it is M- and K-orthogonal to the kept modes,
so it is one more decoupled mode (modal truncation augmentation). Damping is modal: the
suspension's proportional estimate phi^T C phi / (2 omega) for a rigid-body-on-suspension
mode, one ratio for the carbody's elastic modes. :meth:`ModalModel.frf` gives the
accelerance of this model exactly.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg
import scipy.optimize

from ..car2d import StateSpace
from .assembly import BoxModel
from .factor import factorise
from .fit import sensor_operator
from .parametric_basis import full_modes


@dataclass(frozen=True, kw_only=True)
class ModalSettings:
    """Which modes a modal model keeps and the damping it gives them.

    max_mode_hz : modes kept [Hz]
    elastic_damping : ratio of the carbody's elastic modes [-]
    suspension_damping : clip (low, high) of the suspension's proportional estimate [-]
    residual_damping : ratio of the residual pseudo-modes [-]
    """

    max_mode_hz: float = 100.0
    elastic_damping: float = 0.02
    suspension_damping: tuple[float, float] = (0.02, 0.3)
    residual_damping: float = 0.05

    def __post_init__(self):
        if not self.max_mode_hz > 0:
            raise ValueError(f"max_mode_hz must be positive, got {self.max_mode_hz}")
        if not 0 <= self.elastic_damping < 1 or not 0 <= self.residual_damping < 1:
            raise ValueError("elastic_damping and residual_damping must be in [0, 1)")
        lo, hi = self.suspension_damping
        if not 0 <= lo < hi:
            raise ValueError(f"suspension_damping = {self.suspension_damping} must satisfy 0 <= low < high")


@dataclass(frozen=True, eq=False)
class ModalModel:
    """Modal model of the vehicle: kept modes and, last, the residual pseudo-mode.

    ``sensor_shapes[o, k]`` and ``exciter_shape[k]`` are the vertical displacements of
    M-normalised mode k at sensor o (named ``outputs[o]``) and at the exciter ``input``
    [1/sqrt(kg)];
    ``kind[k]`` is ``"elastic"``, ``"carbody_rigid"``, ``"bogie"`` or ``"residual"``
    (residual pseudo-modes come last); ``suspension_damping`` the proportional estimate
    phi^T C phi / (2 omega) [-].

    ``damping_matrix`` (n, n) [1/s], when given, replaces diag(2 zeta omega): the modal
    equations are q'' + D q' + diag(omega^2) q = phi_e f, and ``damping_ratio`` is then
    only its diagonal's estimate D_kk / (2 omega_k) (:meth:`poles` gives the exact ones).
    """

    parameters: Mapping[str, float]
    frequency_hz: np.ndarray  # (n,)
    damping_ratio: np.ndarray  # (n,)
    kind: tuple[str, ...]
    sensor_shapes: np.ndarray  # (n_sensors, n)
    exciter_shape: np.ndarray  # (n,)
    suspension_damping: np.ndarray  # (n,)
    damping_matrix: np.ndarray | None = None  # (n, n) [1/s]; None: modal damping
    outputs: tuple[str, ...] = ()  # sensor names, one per row of sensor_shapes
    input: str = "exciter_force"

    def with_damping(self, damping) -> "ModalModel":
        """The same modes with these modal damping ratios (one per mode, pseudo-modes
        last): damping does not change the undamped modes, so they are not solved again."""
        damping = np.asarray(damping, float)
        if damping.shape != self.damping_ratio.shape:
            raise ValueError(f"damping has {damping.size} ratios; the model has {self.damping_ratio.size} modes "
                             "(residual pseudo-modes included)")
        return replace(self, damping_ratio=damping, damping_matrix=None)

    def _damping(self) -> np.ndarray:
        if self.damping_matrix is not None:
            return self.damping_matrix
        return np.diag(2 * self.damping_ratio * 2 * np.pi * self.frequency_hz)

    def frf(self, frequency) -> np.ndarray:
        """Accelerance H[i, o] = a_o / F [(m/s^2)/N] at ``frequency[i]`` [Hz], time
        dependence exp(+i omega t) (the convention of ``scipy.signal.csd``)."""
        w = 2 * np.pi * np.asarray(frequency, float)[:, None]
        wn = 2 * np.pi * self.frequency_hz[None, :]
        if self.damping_matrix is None:
            g = -w**2 * self.exciter_shape / (wn**2 - w**2 + 2j * self.damping_ratio * wn * w)
            return g @ self.sensor_shapes.T
        # C (i omega - A)^-1 B + D through the state matrix's eigenvectors (complex modes)
        ss = self.state_space()
        lam, V = np.linalg.eig(ss.A)
        left, right = ss.C @ V, np.linalg.solve(V, ss.B[:, 0])
        return (right / (1j * w - lam)) @ left.T + ss.D[:, 0]

    def poles(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequency |s| / 2 pi [Hz] and damping ratio -Re(s) / |s| [-] of each
        mode's pole s, in mode order. Modal damping: ``frequency_hz`` and ``damping_ratio``
        themselves; a damping matrix: the state matrix's eigenvalues, each assigned to the
        undamped mode that dominates its eigenvector."""
        if self.damping_matrix is None:
            return self.frequency_hz, self.damping_ratio
        n = self.frequency_hz.size
        s, V = np.linalg.eig(self.state_space().A)
        upper = s.imag > 0
        if upper.sum() != n:
            raise ValueError(f"{n - upper.sum()} of {n} modes are overdamped; no pole pairs to list")
        s, V = s[upper], V[:n, upper]
        content = np.abs(V) ** 2 / np.sum(np.abs(V) ** 2, axis=0)  # (mode, pole)
        mode, pole = scipy.optimize.linear_sum_assignment(-content)
        s = s[pole[np.argsort(mode)]]
        return np.abs(s) / (2 * np.pi), -s.real / np.abs(s)

    def state_space(self) -> StateSpace:
        """x = [q; q'] (modal), input the exciter force [N], outputs the sensors'
        accelerations [m/s^2] (with the feed-through of the force)."""
        n = self.frequency_hz.size
        wn = 2 * np.pi * self.frequency_hz
        if self.damping_matrix is None:
            dyn = np.hstack([-np.diag(wn**2), -np.diag(2 * self.damping_ratio * wn)])  # q'' = dyn x + phi_e f
        else:
            dyn = np.hstack([-np.diag(wn**2), -self.damping_matrix])
        A = np.vstack([np.hstack([np.zeros((n, n)), np.eye(n)]), dyn])
        B = np.concatenate([np.zeros(n), self.exciter_shape])[:, None]
        C = self.sensor_shapes @ dyn
        D = (self.sensor_shapes @ self.exciter_shape)[:, None]
        outputs = self.outputs or tuple(f"y{o + 1}" for o in range(self.sensor_shapes.shape[0]))
        return StateSpace(A, B, C, D, outputs, (self.input,))

    def listed(self, band: tuple[float, float]) -> np.ndarray:
        """Indices of the physical modes with frequency in ``band`` [Hz]."""
        f = self.frequency_hz
        return np.flatnonzero((f >= band[0]) & (f <= band[1]) & (np.asarray(self.kind) != "residual"))



def vertical_operators(model: BoxModel, sensors, exciter) -> tuple[np.ndarray, np.ndarray]:
    """Rows giving what the sensors read (n_sensors, n_dof) and the exciter's displacement
    along its direction (n_dof,); the exciter's row is also the generalised force of a
    unit force there."""
    return sensor_operator(model, sensors), sensor_operator(model, (exciter,))[0]


def rigid_probe(model: BoxModel) -> tuple[np.ndarray, np.ndarray]:
    """Where a mode's rigid-body share is measured: the displacement rows D (3 n, n_dof) at
    n = 9 points of every panel (its centre and +-80 % of its half sides) and the rigid-body
    motion fields R (3 n, 6) at those points (translation a and rotation theta: a + theta x r)."""
    D, R = [], []
    for pn in model.vehicle.panels:
        for s in (-0.8, 0.0, 0.8):
            for t in (-0.8, 0.0, 0.8):
                r = np.asarray(pn.centre, float) + pn.axes[:, 0] * pn.a / 2 * s + pn.axes[:, 1] * pn.b / 2 * t
                D.append(model.displacement(pn.name, r))
                R.append(np.hstack([np.eye(3), [[0, r[2], -r[1]], [-r[2], 0, r[0]], [r[1], -r[0], 0]]]))
    return np.vstack(D), np.vstack(R)


def rigid_share(model: BoxModel, X: np.ndarray) -> np.ndarray:
    """Fraction of each mode's carbody motion that is a rigid-body motion (least-squares
    fit of a + theta x r to the displacements at the points of :func:`rigid_probe`)."""
    D, R = rigid_probe(model)
    d = D @ X
    fit = R @ np.linalg.lstsq(R, d, rcond=None)[0]
    return np.sum(fit**2, axis=0) / np.sum(d**2, axis=0)


def modal_model(model: BoxModel, parameters: Mapping[str, float] | None = None, *, sensors, exciter,
                damping=None, settings: ModalSettings = ModalSettings(), residual_points=()) -> ModalModel:
    """Modal model of the full box model at ``parameters`` (factors by name; missing ones
    nominal 1): every mode up to ``settings.max_mode_hz`` and the residual pseudo-mode.

    ``damping``: ratios of all those modes, pseudo-mode last. By default the suspension
    estimate for rigid-body-on-suspension modes and ``settings.elastic_damping`` for
    elastic ones.
    ``sensors``, ``exciter``: campaign sensors the shapes are taken at.
    ``residual_points``: further points (sensors: position and direction) where a load
    acts; the static response of the omitted modes to the exciter force and to a unit load
    at each of these spans the residual pseudo-modes (one per load, M- and K-orthogonal to
    each other and to the kept modes, damping ``settings.residual_damping``), so a spring
    attached there sees the full model's static flexibility."""
    parameters = dict(parameters or {})
    unknown = sorted(set(parameters) - set(model.names))
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(model.names)}")
    p = np.array([float(parameters.get(n, 1.0)) for n in model.names])
    n = min(150, model.n_dof - 2)
    while True:
        f, X = full_modes(model, p, n)
        if f[-1] > settings.max_mode_hz or n == model.n_dof - 2:
            break
        n = min(n + 60, model.n_dof - 2)
    keep = f <= settings.max_mode_hz
    f, X = f[keep], X[:, keep]
    w = 2 * np.pi * f
    S, e = vertical_operators(model, sensors, exciter)
    if residual_points:
        loads = np.column_stack([e, *sensor_operator(model, residual_points)])
        Psi = factorise(model.stiffness(p)).solve(loads) - X @ (X.T @ loads / w[:, None] ** 2)
        k_psi = Psi.T @ loads  # = Psi^T K Psi, as X^T M Psi = 0
        lam, Z = scipy.linalg.eigh((k_psi + k_psi.T) / 2, Psi.T @ (model.M @ Psi))
        psi_hat, f_res = Psi @ Z, np.sqrt(lam) / (2 * np.pi)
    else:
        # residual pseudo-mode: static response of the omitted modes to the exciter force
        psi = factorise(model.stiffness(p)).solve(e) - X @ (X.T @ e / w**2)
        m_psi = psi @ (model.M @ psi)
        psi_hat = psi / np.sqrt(m_psi)
        f_res = np.sqrt((psi @ e) / m_psi) / (2 * np.pi)
    n_res = np.size(f_res)
    # kinds and the suspension's damping estimate
    bogies = np.concatenate([np.arange(model.n_dof)[model.dof_slices[b.name]] for b in model.vehicle.bodies])
    bogie_share = np.einsum("ij,ij->j", X[bogies], (model.M @ X)[bogies])
    rigid = rigid_share(model, X)
    kind = tuple("bogie" if b > 0.5 else "carbody_rigid" if r > 0.95 else "elastic" for b, r in zip(bogie_share, rigid))
    zeta_s = np.einsum("ij,ij->j", X, model.C @ X) / (2 * w)
    zeta = np.append(np.where(np.array(kind) == "elastic", settings.elastic_damping,
                              np.clip(zeta_s, *settings.suspension_damping)), [settings.residual_damping] * n_res)
    if damping is not None:
        if len(damping) != zeta.size:
            raise ValueError(f"damping has {len(damping)} ratios; the model keeps {zeta.size - n_res} modes and "
                             f"{n_res} residual pseudo-mode(s) ({zeta.size})")
        zeta = np.asarray(damping, float)
    return ModalModel(
        parameters={nm: float(v) for nm, v in zip(model.names, p)},
        frequency_hz=np.append(f, f_res), damping_ratio=zeta,
        kind=kind + ("residual",) * n_res, sensor_shapes=np.column_stack([S @ X, S @ psi_hat]),
        exciter_shape=np.append(X.T @ e, psi_hat.T @ e), suspension_damping=np.append(zeta_s, [0.0] * n_res),
        outputs=tuple(s.name for s in sensors), input=exciter.name)
