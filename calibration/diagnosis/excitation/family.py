"""A hypothesis's model on one reduced basis: the unknowns' layout (factors, modal damping
ratios, the extension's own parameters), the damping slots that follow the elastic modes,
and the accelerance with its exact derivatives with respect to the slots' dampings."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from ...models.box.modal import ModalSettings
from .basis import Modes, ReducedFRFModel
from ...models.box.mount import equipment_accelerance
from .frf import modal_accelerance

#: clip (low, high) of the suspension's proportional damping estimate phi^T C phi / (2 omega)
#: of a bogie or carbody rigid-body mode: the box model's modal model's (and so the truth
#: simulator's) default
SUSPENSION_ZETA = ModalSettings().suspension_damping


@dataclass(frozen=True, eq=False)
class Slots:
    """Elastic modes whose damping ratio is a fitted parameter, held as their full-model
    shapes at a reference point; on any basis each slot is given the mode it resembles most
    (mass-weighted overlap, one mode per slot), so the ratios follow the modes as the
    stiffness moves and the basis is rebuilt.

    X0 : (n_dof, n_slots) M-normalised shapes; hz0 : (n_slots,) their frequencies [Hz]
    """

    X0: np.ndarray
    hz0: np.ndarray

    @classmethod
    def at(cls, red: ReducedFRFModel, modes: Modes, band) -> "Slots":
        """One slot per elastic mode in ``band`` [Hz] (widened to 0.9 x its low and 1.05 x
        its high end)."""
        lo, hi = band
        sel = modes.elastic & (modes.frequency_hz >= lo * 0.9) & (modes.frequency_hz <= hi * 1.05)
        return cls(red.V @ modes.Y[:, sel], modes.frequency_hz[sel])

    @property
    def n(self) -> int:
        return self.hz0.size

    def on(self, red: ReducedFRFModel) -> np.ndarray:
        """The slots' shapes in ``red``'s coordinates (r, n_slots)."""
        return red.V.T @ (red.ops.model.M @ self.X0)

    def zeta(self, modes: Modes, Y0: np.ndarray, slot_zeta: np.ndarray, default: float,
             clip) -> tuple[np.ndarray, np.ndarray]:
        """Damping ratio of every mode, and the mode each slot sits on (-1: none). A slot
        takes the elastic mode below 1.3 x the highest slot frequency it overlaps most (an
        assignment; an overlap of 0.3 or less is no match); other elastic modes get
        ``default``, the rest the suspension's estimate clipped to ``clip``."""
        z = np.where(modes.elastic, default, np.clip(modes.suspension_zeta, *clip))
        where = np.full(self.n, -1)
        if self.n:
            cand = np.flatnonzero(modes.elastic & (modes.frequency_hz <= 1.3 * self.hz0.max()))
            if cand.size:
                O = (modes.Y[:, cand].T @ Y0) ** 2
                rows, cols = scipy.optimize.linear_sum_assignment(-O)
                good = O[rows, cols] > 0.3
                z[cand[rows[good]]] = slot_zeta[cols[good]]
                where[cols[good]] = cand[rows[good]]
        return z, where

    def map_zeta(self, old: "Slots", old_zeta: np.ndarray, M, default: float) -> np.ndarray:
        """Damping of these slots from ``old`` ones of the same shape (mass-weighted overlap
        >= 0.5; else ``default``)."""
        z = np.full(self.n, default)
        if self.n and old.n:
            O = (self.X0.T @ (M @ old.X0)) ** 2
            r, c = scipy.optimize.linear_sum_assignment(-O)
            ok = O[r, c] >= 0.5
            z[r[ok]] = old_zeta[c[ok]]
        return z


@dataclass(frozen=True)
class Layout:
    """Where each unknown sits in a least-squares vector x: log factors, log slot dampings,
    then the extension's own (log divisor; or log mass, log mounting frequency, log damping
    ratio, mount x, mount y; or the log gain of the force sensor)."""

    n_p: int
    n_slots: int
    extension: str | None = None  # None, "softening", "equipment" or "force"

    @property
    def n_ext(self) -> int:
        return {None: 0, "softening": 1, "equipment": 5, "force": 1}[self.extension]

    @property
    def size(self) -> int:
        return self.n_p + self.n_slots + self.n_ext

    def split(self, x) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(factors, slot damping ratios, the extension's raw unknowns) of ``x``."""
        x = np.asarray(x, float)
        return (np.exp(x[:self.n_p]), np.exp(x[self.n_p:self.n_p + self.n_slots]), x[self.n_p + self.n_slots:])


@dataclass(frozen=True, eq=False)
class Family:
    """A hypothesis's model on one reduced basis: x (:class:`Layout`) -> accelerance."""

    red: ReducedFRFModel
    slots: Slots
    layout: Layout
    default_zeta: float
    Y0: np.ndarray = None  # slots on red's coordinates

    @classmethod
    def make(cls, red, slots, layout, default_zeta) -> "Family":
        return cls(red, slots, layout, default_zeta, slots.on(red))

    def parts(self, x):
        """(modes, damping ratio of every mode, the extension's raw unknowns, the mode each
        slot sits on) at ``x``."""
        p, zs, ext = self.layout.split(x)
        divisor = float(np.exp(ext[0])) if self.layout.extension == "softening" else 1.0
        modes = self.red.modes(p, divisor, classify_below_hz=1.5 * self.slots.hz0.max(initial=20.0))
        zeta, where = self.slots.zeta(modes, self.Y0, zs, self.default_zeta, SUSPENSION_ZETA)
        return modes, zeta, ext, where

    def accelerance(self, x, f, zeta_derivatives: bool = False):
        """H (n_f, n_s) [(m/s^2)/N] at ``f`` [Hz]; with ``zeta_derivatives`` also
        dH / d log zeta of every slot (n_slots, n_f, n_s), exact (zero for a slot on no mode)."""
        modes, zeta, ext, where = self.parts(x)
        w = 2 * np.pi * np.asarray(f, float)[:, None]
        om, Ss, e = modes.omega, modes.sensor_shapes, modes.exciter_shape
        if self.layout.extension == "equipment":
            m, fe, ze = np.exp(ext[:3])
            a = self.red.mount_rows([ext[3:5]])[0] @ modes.Y
            H = equipment_accelerance(f, om, zeta, Ss, e, a, m, fe, ze)
        else:
            H = modal_accelerance(f, om, zeta, Ss, e)
        # the force sensor reads g x the force applied, so what is measured is H / g
        gain = float(np.exp(-ext[0])) if self.layout.extension == "force" else 1.0
        H = H * gain
        if not zeta_derivatives:
            return H
        dH = np.zeros((self.slots.n,) + H.shape, complex)
        on = np.flatnonzero(where >= 0)
        if not on.size:
            return H, dH
        k = where[on]
        Z = om[k] ** 2 - w**2 + 2j * zeta[k] * om[k] * w  # (n_f, n_on)
        dy = -(2j * om[k] * w * zeta[k]) / Z**2  # d(1/Z_k) / d log zeta_k
        if self.layout.extension == "equipment":
            Zall = om**2 - w**2 + 2j * zeta * om * w
            # kappa of calibration.diagnosis.excitation.frf.mount_impedance, with c_e written as
            # 2 zeta_e m omega_e (the form the refinements were measured with)
            kstar = m * (2 * np.pi * fe) ** 2 + 1j * w[:, 0] * 2 * ze * m * 2 * np.pi * fe
            kappa = -w[:, 0] ** 2 * m * kstar / (kstar - w[:, 0] ** 2 * m)
            G_sm = (a / Zall) @ Ss.T
            G_me = (a * e / Zall).sum(axis=1)
            D = 1 + kappa * (a * a / Zall).sum(axis=1)
            alpha = e[k] - (kappa * G_me / D)[:, None] * a[k]  # (n_f, n_on)
            # dU/dy_k = alpha_k (Phi_s,k - kappa a_k G_sm / D)
            part = Ss[:, k].T[None, :, :] - (kappa / D)[:, None, None] * a[k][None, :, None] * G_sm[:, None, :]
            dU = (alpha * dy)[:, :, None] * part  # (n_f, n_on, n_s)
        else:
            dU = (e[k] * dy)[:, :, None] * Ss[:, k].T[None, :, :]
        dH[on] = np.moveaxis(-w[:, :, None] ** 2 * dU, 1, 0) * gain
        return H, dH
