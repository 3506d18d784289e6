"""Fitting a hypothesis's model to the training FRFs in rounds: least squares on a reduced
basis, then the basis rebuilt and the damping slots re-taken at the answer, until it stops
moving."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .basis import Modes, ReducedFRFModel, Stiffness, points_operator
from .context import Context
from .family import Family, Layout, Slots
from .least_squares import least_squares, total_error


#: the extension's unknowns in the order of :class:`.family.Layout` (masses, frequencies,
#: dampings and divisors as logs, positions as metres)
RAW_NAMES = {"equipment": ("equipment_mass_kg", "mounting_frequency_hz", "mounting_damping_ratio", "mount_x_m",
                           "mount_y_m"),
             "softening": ("rigidity_divisor",), "force": ("force_gain",)}
#: unknowns whose search limits are places, not sizes (see :meth:`Fitted.extension_at_limits`)
NOT_LIMITS = ("mount_x_m", "mount_y_m")


@dataclass(frozen=True, eq=False)
class Fitted:
    """A model fitted to the training FRFs: its family on a basis rebuilt at ``x``.

    train_error : sum over channels of E on the training part [-]
    panel : the softened panel (softening only)
    """

    name: str
    family: Family
    x: np.ndarray
    train_error: float
    panel: str | None = None
    ext_bounds: tuple[np.ndarray, np.ndarray] | None = None  # the extension's unknowns' (lo, hi)

    @property
    def layout(self) -> Layout:
        return self.family.layout

    def accelerance(self, f) -> np.ndarray:
        """H (n_f, n_s) [(m/s^2)/N] at ``f`` [Hz]."""
        return self.family.accelerance(self.x, f)

    def factors(self, names) -> dict[str, float]:
        p, _, _ = self.layout.split(self.x)
        return {n: float(v) for n, v in zip(names, p)}

    def extension_parameters(self, carbody_mass: float) -> dict:
        """The extension's parameters by name, SI units (``carbody_mass`` [kg] gives the
        equipment's mass ratio)."""
        _, _, ext = self.layout.split(self.x)
        if self.layout.extension == "softening":
            return {"panel": self.panel, "rigidity_divisor": float(np.exp(ext[0]))}
        if self.layout.extension == "equipment":
            m, fe, ze = np.exp(ext[:3])
            return {"equipment_mass_kg": float(m), "mass_ratio": float(m / carbody_mass),
                    "mounting_frequency_hz": float(fe), "mounting_damping_ratio": float(ze),
                    "mount_x_m": float(ext[3]), "mount_y_m": float(ext[4])}
        if self.layout.extension == "force":
            return {"force_gain": float(np.exp(ext[0]))}
        return {}

    def extension_at_limits(self, tol: float = 0.01) -> list[str]:
        """The extension's sizes within ``tol`` of their range of a search limit, as
        ``"name (lower)"`` / ``"name (upper)"``. Not judged: a mount's place (the floor's edge
        is where real equipment hangs, not a size the data push past) and the softening's
        lowest divisor, its null end (:attr:`.extensions.ExcitationExtension.null_end`)."""
        if self.ext_bounds is None:
            return []
        _, _, ext = self.layout.split(self.x)
        out = []
        for name, v, lo, hi in zip(RAW_NAMES[self.layout.extension], ext, *self.ext_bounds, strict=True):
            if name in NOT_LIMITS:
                continue
            if v - lo <= tol * (hi - lo) and self.layout.extension != "softening":
                out.append(f"{name} (lower)")
            elif hi - v <= tol * (hi - lo):
                out.append(f"{name} (upper)")
        return out

    def modes(self) -> tuple[Modes, np.ndarray]:
        """The model's modes and the damping ratio of each."""
        modes, zeta, _, _ = self.family.parts(self.x)
        return modes, zeta


def stiffness_at(layout: Layout, x, panel) -> Stiffness:
    p, _, ext = layout.split(x)
    if layout.extension == "softening":
        return Stiffness(p, panel, float(np.exp(ext[0])))
    return Stiffness(p)


def basis_at(ctx: Context, layout: Layout, x, panel) -> ReducedFRFModel:
    """The reduced model at unknowns ``x`` (with the static response to a load at the
    equipment's mount, for that hypothesis)."""
    s = ctx.settings
    rows = ()
    if layout.extension == "equipment":
        rows = (points_operator(ctx.model, [layout.split(x)[2][3:5]])[0],)
    return ReducedFRFModel.build(ctx.ops, stiffness_at(layout, x, panel), n_modes=ctx.n_modes,
                                 n_deriv=min(s.derivative_modes, ctx.n_modes), extra=s.basis_extra,
                                 below_hz=s.basis_hz, static_rows=rows)


def fit(ctx: Context, name: str, layout: Layout, slots: Slots, x0, lo, hi, *, panel=None, red=None,
        rounds: int = 4, tol: float = 2e-3, quick: bool = False) -> Fitted:
    """Least squares on the training FRFs in rounds, the basis rebuilt and the damping
    slots re-taken at each round's answer (every elastic mode in the band gets a slot,
    keeping the damping it had), until the unknowns move less than ``tol`` (log units) or
    ``rounds`` are done. The answer is the lowest training error of the start (if within
    the bounds) and the rounds, each on its own basis: a rebuilt basis can make a round end
    above the last (a fit nested on the baseline once ended above it). ``quick``: one short
    round with the dampings held (to rank candidate starts)."""
    s = ctx.settings
    x = np.asarray(x0, float)
    red = basis_at(ctx, layout, x, panel) if red is None else red
    fam = Family.make(red, slots, layout, ctx.default_zeta)
    inside = bool(np.all((x >= lo) & (x <= hi)))  # a start outside the bounds is no answer
    head = layout.n_p + layout.n_slots  # the extension's unknowns follow; re-taking the slots leaves them
    ext_bounds = (np.asarray(lo)[head:], np.asarray(hi)[head:]) if layout.extension else None
    best = Fitted(name, fam, x, total_error(fam, x, ctx.meas, s.floor) if inside else np.inf, panel, ext_bounds)
    for _ in range(1 if quick else rounds):
        free = np.ones(x.size, bool)
        if quick:
            free[layout.n_p:layout.n_p + layout.n_slots] = False
        x_new = least_squares(fam, x, lo, hi, ctx.meas, s.refine_iterations // 3 if quick else s.refine_iterations,
                              s.floor, free)
        moved = float(np.max(np.abs(x_new - x)))
        x = x_new
        if not quick:
            modes, zeta, _, _ = fam.parts(x)
            red = basis_at(ctx, layout, x, panel)
            slots, layout, x, lo, hi = retake_slots(ctx, fam, modes, zeta, layout, x, lo, hi)
        fam = Family.make(red, slots, layout, ctx.default_zeta)
        now = Fitted(name, fam, x, total_error(fam, x, ctx.meas, s.floor), panel, ext_bounds)
        best = now if now.train_error < best.train_error else best
        if quick or moved < tol:
            break
    return best


def retake_slots(ctx: Context, fam: Family, modes: Modes, zeta: np.ndarray, layout: Layout, x, lo, hi):
    """Slots at the elastic modes in the band of ``modes`` (on ``fam``'s basis), each with
    the damping its mode has now; the unknowns' layout, vector and bounds to match."""
    band = ctx.settings.band
    sel = modes.elastic & (modes.frequency_hz >= band[0] * 0.9) & (modes.frequency_hz <= band[1] * 1.05)
    slots = Slots(fam.red.V @ modes.Y[:, sel], modes.frequency_hz[sel])
    z = np.clip(zeta[sel], *ctx.settings.damping_range)
    n_p, n_s = layout.n_p, layout.n_slots
    new = Layout(n_p, slots.n, layout.extension)
    z0, z1 = np.log(ctx.settings.damping_range)
    x = np.concatenate([x[:n_p], np.log(z), x[n_p + n_s:]])
    lo = np.concatenate([lo[:n_p], np.full(slots.n, z0), lo[n_p + n_s:]])
    hi = np.concatenate([hi[:n_p], np.full(slots.n, z1), hi[n_p + n_s:]])
    return slots, new, x, lo, hi


def fit_best(ctx: Context, starts: list[tuple], **kw) -> list[Fitted]:
    """Quick fits from every start (name, layout, slots, x0, lo, hi, panel, red), then the
    full fit from the best one; returns the full fit and the quick ones, best first."""
    quick = [fit(ctx, nm, lay, sl, x0, lo, hi, panel=pn, red=rd, quick=True, **kw)
             for nm, lay, sl, x0, lo, hi, pn, rd in starts]
    i = int(np.argmin([q.train_error for q in quick]))
    nm, lay, sl, _, lo, hi, pn, _ = starts[i]
    full = fit(ctx, nm, lay, sl, quick[i].x, lo, hi, panel=pn, **kw)
    return [full] + sorted((q for j, q in enumerate(quick) if j != i), key=lambda q: q.train_error)


def factor_bounds(ctx: Context, n_slots: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of the log factors (the priors) and of ``n_slots`` log damping ratios."""
    z0, z1 = np.log(ctx.settings.damping_range)
    return (np.concatenate([np.log(ctx.low), np.full(n_slots, z0)]),
            np.concatenate([np.log(ctx.high), np.full(n_slots, z1)]))


def at_bounds(ctx: Context, fitted: Fitted, tol: float = 0.01) -> list[str]:
    """The factors of ``fitted`` within ``tol`` of their log range of a bound, as
    ``"name (lower)"`` or ``"name (upper)"``."""
    p = np.array(list(fitted.factors(ctx.names).values()))
    span = np.log(ctx.high / ctx.low)
    out = []
    for n, v, lo, hi, sp_ in zip(ctx.names, p, ctx.low, ctx.high, span):
        if np.log(v / lo) <= tol * sp_:
            out.append(f"{n} (lower)")
        elif np.log(hi / v) <= tol * sp_:
            out.append(f"{n} (upper)")
    return out


def extension_start(ctx: Context, base: Fitted, layout: Layout, red: ReducedFRFModel, x_head):
    """Slots at an extension's starting point (its structure modes in the band) with the
    baseline's dampings carried over by shape; returns them and their damping ratios."""
    p, _, ext = layout.split(np.concatenate([x_head, np.zeros(layout.size - len(x_head))]))
    divisor = float(np.exp(ext[0])) if layout.extension == "softening" else 1.0
    modes = red.modes(p, divisor)
    slots = Slots.at(red, modes, ctx.settings.band)
    _, zb, _ = base.layout.split(base.x)
    z = slots.map_zeta(base.family.slots, zb, ctx.model.M, ctx.default_zeta)
    return slots, z
