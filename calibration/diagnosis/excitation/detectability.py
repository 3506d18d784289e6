"""Detectability for the excitation test: for each extension, the weakest effect this
campaign could have named, so that ``none`` says what it rules out.

Nothing here knows a truth. At the end of a diagnosis each extension's model, at the
baseline's factors and dampings, is evaluated with the effect at magnitude theta and with
the effect absent (an equipment mass of nothing, a divisor of 1, a force gain of 1).
The difference of the two, in the residual's units (:func:`.least_squares.residual`), is
what data with that effect would add to the baseline's misfit:

* the baseline's refit absorbs what its own factors and dampings can mimic: the training
  part's difference is projected on the baseline's Jacobian there, and the same
  combination of its parameters is taken off the held-out part's difference (a
  linearised refit);
* what is left adds its mean square to each held-out channel's error E (per line, the
  sum of the log-magnitude and the phase terms);
* a perfect extension removes it again, so the gain it would bring is the addition over
  the baseline's measured held-out error plus it, summed over the channels as the
  decision sums them;
* the gain's scatter comes from the cross term of the addition with the baseline's
  residual and from the residual's own power, both taken as random with the per-line error
  as the residual's variance (a noise residual's per-line error is a scaled chi-square of
  two degrees of freedom).

An effect is *detectable* at theta when the gain less ``Z`` of its scatter reaches the
decision's bar (:mod:`calibration.diagnosis.limits`). The effect's other parameters are
varied over what the catalogue may hide, and the weakest counts: the equipment tuned to
each carbody mode in 8-20 Hz where that mode moves the floor most, the softening on each
panel the catalogue softens (the roof and the floor panels). A force gain within 1 % of 1
is the load cell's tolerance and never named, so its limit is at least that, and at least
the gain that stands :data:`.force.UNIFORM` times above the baseline's channel level
scatter (:func:`.frf.level_scatter`), as the decision requires.
"""
from __future__ import annotations

import numpy as np

from ..limits import Z, Detectability, Limit, Magnitude, search, weakest
from .context import Context
from .equipment import MASS_RANGE, SCAN_DAMPING, mount_grid
from .extensions import EXTENSIONS
from .fitting import Fitted, factor_bounds
from .force import UNIFORM
from ...models.box.mount import equipment_accelerance
from .frf import level_scatter, modal_accelerance, normalised_error_lines
from .least_squares import jacobian
from .softening import DIVISOR_RANGE, panel_family, softening_panels

#: [Hz] the carbody modes the effects catalogue tunes underfloor equipment to
EQUIPMENT_BAND = (8.0, 20.0)
#: each extension's magnitude: the range its fit searches
MAGNITUDES = {
    "underfloor_equipment": Magnitude("mass_ratio", "-", MASS_RANGE[0], MASS_RANGE[1]),
    "local_panel_softening": Magnitude("rigidity_divisor", "-", DIVISOR_RANGE[0], DIVISOR_RANGE[1]),
    "force_calibration": Magnitude("force_error", "-", 0.0, 0.5, signed=True, log=False),
}
_missing = set(EXTENSIONS) - set(MAGNITUDES)
if _missing:
    raise ImportError(f"excitation detectability.MAGNITUDES lacks {', '.join(sorted(_missing))}")


class Refit:
    """The baseline's held-out misfit and its linearised refit, formed once.

    J_train, J_test : the baseline's residual Jacobians on the two parts (its factors and
        dampings); e_lines : (n_f, n_s) its held-out error per line and channel; n_f : lines
    """

    def __init__(self, J_train: np.ndarray, J_test: np.ndarray, e_lines: np.ndarray):
        self.J_train, self.J_test, self.e_lines = J_train, J_test, e_lines
        self.n_f, self.n_s = e_lines.shape

    @classmethod
    def of(cls, ctx: Context, base: Fitted, H_test: np.ndarray | None = None) -> "Refit":
        """The refit of ``base``; ``H_test``: its accelerance at the held-out lines, if at hand."""
        s = ctx.settings
        _, hi = factor_bounds(ctx, base.layout.n_slots)
        free = np.ones(base.x.size, bool)
        J_tr = jacobian(base.family, base.x, ctx.meas, s.floor, free, hi)
        J_te = jacobian(base.family, base.x, ctx.meas_test, s.floor, free, hi)
        H = base.accelerance(ctx.meas_test.frequency) if H_test is None else H_test
        e = normalised_error_lines(ctx.meas_test, H, s.floor)
        return cls(J_tr, J_te, e)

    def predict(self, d_train: np.ndarray, d_test: np.ndarray) -> tuple[float, float]:
        """(gain, its standard deviation) a perfect extension would bring if the data carried
        an effect that changes the residual by ``d_train`` and ``d_test``."""
        beta, *_ = np.linalg.lstsq(self.J_train, d_train, rcond=1e-10)
        left = (d_test - self.J_test @ beta).reshape(2, self.n_f, self.n_s)
        sq = (left ** 2).sum(axis=0)  # (n_f, n_s)
        added = float(sq.sum()) / self.n_f
        before = max(float(self.e_lines.sum()) / self.n_f + added, 1e-300)
        gain = added / before
        # the gain A / (E + A) moves with the cross term C of the addition with the residual
        # (by (1 - gain) / before) and with the residual's own power E (by -gain / before)
        var_cross = 2.0 * float(np.sum(sq * self.e_lines)) / self.n_f ** 2
        var_power = float(np.sum(self.e_lines ** 2)) / self.n_f ** 2
        return gain, float(np.sqrt((1 - gain) ** 2 * var_cross + gain ** 2 * var_power)) / before

    def judge(self, d_train: np.ndarray, d_test: np.ndarray) -> tuple[float, float]:
        """(gain less Z of its scatter, the gain over Z of its scatter)."""
        gain, sigma = self.predict(d_train, d_test)
        return gain - Z * sigma, gain / max(Z * sigma, 1e-300)


def _residual_change(ctx: Context, H_of) -> tuple[np.ndarray, np.ndarray]:
    """The residual's change on both parts from ``H_of(f) -> (H with the effect, H without)``:
    the weighted log of their ratio (the difference of two residuals would wrap where the
    baseline's phase misfit is near pi)."""
    out = []
    for meas in (ctx.meas, ctx.meas_test):
        on, off = H_of(meas.frequency)
        q = np.log(on / off) / np.sqrt(2 * (meas.sigma2 + ctx.settings.floor ** 2))
        out.append(np.concatenate([q.real.ravel(), q.imag.ravel()]))
    return out[0], out[1]


def _force(ctx: Context, base: Fitted):
    """The baseline read through a load cell of gain 1 + theta: every FRF over it."""
    def change(theta: float):
        return _residual_change(ctx, lambda f: (base.accelerance(f) / (1 + theta), base.accelerance(f)))
    return [("either sign", change)]


def _equipment(ctx: Context, base: Fitted):
    """Underfloor equipment on the baseline, one variant per carbody mode in the catalogue's
    8-20 Hz (the truth's equipment is tuned to one): mounted where the mode moves the floor
    most (:func:`.equipment.mount_grid`), tuned to it, damping ratio 5 %."""
    modes, zeta, _, _ = base.family.parts(base.x)
    points = mount_grid(ctx.model)
    A = base.family.red.mount_rows(points) @ modes.Y  # (n_points, r)
    lo, hi = max(EQUIPMENT_BAND[0], ctx.settings.band[0]), min(EQUIPMENT_BAND[1], ctx.settings.band[1])
    out = []
    for k in np.flatnonzero(modes.elastic & (modes.frequency_hz >= lo) & (modes.frequency_hz <= hi)):
        j = int(np.argmax(np.abs(A[:, k])))
        f_k, a = float(modes.frequency_hz[k]), A[j]

        def change(theta: float, a=a, f_k=f_k):
            def H_of(f):
                return (equipment_accelerance(f, modes.omega, zeta, modes.sensor_shapes, modes.exciter_shape, a,
                                              theta * ctx.carbody_mass, f_k, SCAN_DAMPING),
                        modal_accelerance(f, modes.omega, zeta, modes.sensor_shapes, modes.exciter_shape))
            return _residual_change(ctx, H_of)
        out.append((f"{f_k:.2f} Hz at ({points[j][0]:.1f}, {points[j][1]:.1f}) m", change))
    return out


def _softening(ctx: Context, base: Fitted):
    """Each panel the catalogue may soften, softened on the baseline: the softening's model of
    that panel (:func:`.softening.panel_family`, the scan's where the baseline was not
    re-fitted since) at the baseline's factors and dampings, its divisor theta against 1. A
    panel whose every rigidity is scaled by factors of its own (the roof) softened by theta
    is those factors over theta: the refit absorbs it until the first of them reaches its
    lower bound (theta_0 = min p / low), so what is left is taken as the softening by theta /
    theta_0 (the linearised refit cannot follow a shift that large)."""
    p_b, z_b, _ = base.layout.split(base.x)
    head = np.r_[np.log(p_b), np.log(z_b)]
    out = []
    for name in softening_panels(ctx.model):
        fam = panel_family(ctx, base, name)
        own = ctx.ops.own_group_factors(name)
        _, Kp = ctx.ops.panel_stiffness(name)
        absorbed = 1.0
        if own and set(Kp) == set(own):
            i = [ctx.names.index(n) for n in own]
            absorbed = max(1.0, float(np.min(p_b[i] / ctx.low[i])))

        def change(theta: float, fam=fam, absorbed=absorbed):
            left = max(theta / absorbed, 1.0)
            return _residual_change(ctx, lambda f: (fam.accelerance(np.r_[head, np.log(left)], f),
                                                    fam.accelerance(np.r_[head, 0.0], f)))
        words = f"panel {name}" + ("" if absorbed == 1.0 else
                                   f" (its own factors absorb a divisor up to {absorbed:.3g})")
        out.append((words, change))
    return out


def _limit(ctx: Context, name: str, variants: list, refit: Refit, level_floor: float | None = None) -> Limit:
    """The weakest over ``variants`` ((held values in words, theta -> residual changes)) of
    the smallest size that clears the bar; for a factor on every channel, at least what
    stands :data:`.force.UNIFORM` times above the baseline's channel level scatter
    ``level_floor``."""
    mag, ext = MAGNITUDES[name], EXTENSIONS[name]
    bar = ctx.settings.bar(ext.n_params)
    stronger = "above" if mag.strong > mag.weak else "below"
    if not variants:
        return Limit(name, mag.parameter, mag.unit, None, False,
                     f"no carbody mode in {EQUIPMENT_BAND[0]:g}-{EQUIPMENT_BAND[1]:g} Hz inside the FRF band to tune "
                     "it to", stronger)

    def judge_of(change):
        def judge(theta: float) -> tuple[float, float]:
            out = [refit.judge(*change(s * theta)) for s in ((1.0, -1.0) if mag.signed else (1.0,))]
            return min(o[0] for o in out), min(o[1] for o in out)
        return judge

    found = [search(mag, judge_of(change), bar) for _, change in variants]
    k = weakest(mag, found)
    limit, strong, observable = found[k]
    held = variants[k][0]
    if len(variants) > 1:
        each = "; ".join(f"{w}: {'not detectable' if x[0] is None else f'{x[0]:.3g}'}"
                         for (w, _), x in zip(variants, found))
        held = f"the weakest of {each}"
    span = f"{min(mag.weak, mag.strong):g}-{max(mag.weak, mag.strong):g}"
    if not observable:
        return Limit(name, mag.parameter, mag.unit, None, False,
                     f"not observable: even at {mag.strong:g} ({held}) it changes no channel beyond the scatter",
                     stronger)
    if limit is None:
        return Limit(name, mag.parameter, mag.unit, None, True,
                     f"not detectable within its range {span} ({held}): at {mag.strong:g} the predicted held-out "
                     f"gain less its scatter is {strong:.0%}, under the bar of {bar:.0%}", stronger)
    tolerance = ""
    never = float(np.expm1(ext.null_tol))  # a gain within its tolerance (in log, either side) is never named
    if ext.null_end is not None and ext.null_end[1] == 1.0 and limit < never:
        limit, tolerance = never, "; smaller errors are within a load cell's tolerance and not named"
    if ext.uniform_level and level_floor is not None:  # a gain must stand above the channels' level scatter
        uniform = float(np.expm1(UNIFORM * level_floor))
        if limit < uniform:
            limit, tolerance = uniform, (f"; smaller errors are within the channels' own level scatter "
                                         f"({level_floor:.1%} rms) and not named")
    what = f"|{mag.parameter}|" if mag.signed else mag.parameter
    side = "and above" if stronger == "above" else "and below"
    return Limit(name, mag.parameter, mag.unit, limit, True,
                 f"{what} {limit:.3g} {side} ({held}) would gain {bar:.0%} on the held-out FRFs after the "
                 f"baseline's refit absorbs what it can{tolerance}", stronger, signed=mag.signed)


def detectability(ctx: Context, base: Fitted) -> Detectability:
    """Each extension's detectable limit on this campaign, from the baseline ``base`` (see
    the module's description)."""
    H_test = base.accelerance(ctx.meas_test.frequency)
    refit = Refit.of(ctx, base, H_test)
    variants = {"underfloor_equipment": _equipment(ctx, base),
                "local_panel_softening": _softening(ctx, base),
                "force_calibration": _force(ctx, base)}
    scatter = level_scatter(ctx.meas_test, H_test, ctx.settings.floor)
    return Detectability(tuple(_limit(ctx, name, variants[name], refit, scatter) for name in EXTENSIONS))
