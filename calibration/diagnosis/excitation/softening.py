"""The extension ``local_panel_softening``: one panel's rigidities divided by its own factor,
fitted to the training FRFs. The panels are those the effects catalogue softens, the roof
and the three floor panels (:data:`SOFTENING_GROUPS`): the ones the detectability speaks
for. The side and end walls are where the box model is crudest (smeared windows, one end
rigidity); softened, they patched its form on a clean independent shell car (bench seed
6503: the rear end wall over 3.5, confidence high).

A softened panel can leave the baseline in a basin far from the truth, so the fit is started
from three factor sets (the baseline's, the nominal ones, and those of a particle swarm per
panel on the identified modes with that panel's rigidities searched on their own), scanned
over panel x divisor, then refined; docs/methods/diagnosis-excitation.md tells which bench
cases each start was added for."""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np

from ...calibrate_box import RefineSettings, SwarmSettings, calibrate_box, targets_from_identification
from ...models.box import BoxModel
from ...models.box.shinkansen import DEFINITE_MARGIN, across_partner
from ...optimisers.base import SearchParameter
from .basis import Operators, ReducedFRFModel, Stiffness
from .context import Context
from .family import Family, Layout
from .fitting import Fitted, at_bounds, basis_at, extension_start, factor_bounds, fit_best
from .least_squares import least_squares, total_error

#: the panel groups the effects catalogue softens (the roof, or one of the three floor
#: panels: docs/methods/truth-simulator.md), and so the panels this extension searches
SOFTENING_GROUPS = ("roof", "floor")


def softening_panels(model: BoxModel) -> tuple[str, ...]:
    """The panels of ``model`` a softening is searched on (:data:`SOFTENING_GROUPS`)."""
    return tuple(pn.name for pn in model.vehicle.panels if pn.group in SOFTENING_GROUPS)


#: rigidity divisors searched: from barely softer (1.2, the null end: a fit that ends there
#: only re-adjusts the baseline) to 30, three times the top of the effects catalogue's range
#: (3-10, docs/methods/truth-simulator.md), so that the catalogue's range is inside
DIVISOR_RANGE = (1.2, 30.0)
#: the scan's divisors: geometric steps of about 1.5 over 1.5-17, so that every divisor in that
#: span is within a factor 1.25 of one scanned
DIVISOR_SCAN = (1.5, 2.2, 3.3, 5.0, 7.5, 11.0, 17.0)


def panel_split_model(ops: Operators, panel: str) -> tuple[BoxModel, tuple[str, ...]]:
    """The box model with ``panel``'s share of each of its group's factors made a factor of
    its own, named ``factor@panel`` (K stays linear in the factors, as the swarm needs);
    returns it and the factors so copied. A factor whose whole energy is the panel's (the
    roof's) is not copied: it is already the panel's own. (A rigidity no factor scales
    stays unscaled: the copies then soften the panel's factored part only.)"""
    model = ops.model
    _, Kp = ops.panel_stiffness(panel)
    own = set(ops.own_group_factors(panel))
    copies = tuple(n for n in model.names if n in Kp and n not in own)
    units = dict(model.K_units)
    for n in copies:
        units[n] = (model.K_units[n] - Kp[n]).tocsr()
        units[f"{n}@{panel}"] = Kp[n]
    return replace(model, names=model.names + tuple(f"{n}@{panel}" for n in copies), K_units=units), copies


@dataclass(frozen=True)
class PanelSwarm:
    """The swarm's answer for one panel softened: the group factors (within the priors)
    and the panel's own values of the factors that touch it, their ratio a divisor each.

    modal_fit_pct : seed eq. 3 on the full model, the largest frequency error of the
        identified modes [%]
    p : (n_p,) factors, the panel's own ones (roof) included
    divisors : factor -> group value / the panel's own value (copied factors only)
    own : factors whose whole energy is the panel's
    """

    panel: str
    modal_fit_pct: float
    p: np.ndarray
    divisors: dict
    own: tuple[str, ...]

    def factors_at(self, ctx: Context, divisor: float) -> np.ndarray:
        """Factors that, with the panel divided by ``divisor``, give the panel its own values
        found by the swarm where the priors allow (the roof's factors times the divisor,
        clipped to their range)."""
        p = self.p.copy()
        for n in self.own:
            i = ctx.names.index(n)
            p[i] = np.clip(p[i] * divisor, ctx.low[i], ctx.high[i])
        return p


def definite(search: tuple[SearchParameter, ...]) -> tuple[SearchParameter, ...]:
    """``search`` with each cross-direction factor's low raised where its lengthwise partner's
    high would make the plate indefinite (:func:`.shinkansen.across_limits`): the panel
    swarm's lows, divided for softening, would reach it in the orthotropic set. A softening
    divides all of a panel's rigidities alike, so their ratio needs no such room."""
    high = {q.name: q.high for q in search}

    def floor(q: SearchParameter) -> float:
        partner = across_partner(q.name)
        if partner is None:
            return q.low
        along, ratio = partner  # 1 % above the margin's line, which is itself refused
        return max(q.low, DEFINITE_MARGIN * 1.01 * ratio * high[along])
    return tuple(replace(q, low=floor(q), mean=max(q.mean, floor(q))) for q in search)


def panel_swarm(ctx: Context, panel: str) -> PanelSwarm:
    """The seed's particle swarm on the identified modes (as the baseline's,
    :func:`calibrate_box`) with ``panel``'s rigidities searched on their own
    (:func:`panel_split_model`, down to the group's range divided by the largest divisor): a
    start for the softening that does not depend on the basin the baseline found."""
    s = ctx.settings
    model, copies = panel_split_model(ctx.ops, panel)
    own = ctx.ops.own_group_factors(panel)
    prior = ctx.search
    soft = DIVISOR_RANGE[1]
    search = definite(tuple(replace(q, low=q.low / soft) if q.name in own else q for q in prior) + tuple(
        replace(q, name=f"{q.name}@{panel}", low=q.low / soft) for q in prior if q.name in copies))
    sensors = tuple(ctx.campaign.meta.sensor(n) for n in ctx.sensors)
    cal = calibrate_box(targets_from_identification(ctx.ident), sensors, search,
                        swarm=SwarmSettings(pso=s.pso, seed=s.seed, log_factors=ctx.log_factors),
                        refinement=RefineSettings(enabled=False), model=model)
    found = cal.parameters
    p = np.array([found[n] for n in ctx.names])
    group = np.array([n not in own for n in ctx.names])  # back in the priors (the own ones: by the divisor, later)
    p[group] = np.clip(p[group], ctx.low[group], ctx.high[group])
    divisors = {n: float(found[n] / found[f"{n}@{panel}"]) for n in copies}
    return PanelSwarm(panel, cal.pso["best_full_pct"], p, divisors, own)


def panel_family(ctx: Context, base: Fitted, panel: str, extra_points: tuple[Stiffness, ...] = ()) -> Family:
    """The softening of ``panel`` on the baseline ``base``'s factors and damping slots: one
    basis at the panel divided by 4 that also holds the modes at 1.5 and 12 and at
    ``extra_points``. Kept in ``ctx.memo`` per panel and baseline, so that the
    detectability evaluates the model the scan did (where the baseline was not re-fitted
    since, it gets the scan's basis, extra points included)."""
    s = ctx.settings
    p_b = base.layout.split(base.x)[0]
    key = ("softening", panel, p_b.tobytes(), base.family.slots.hz0.tobytes())
    if key not in ctx.memo:
        red = ReducedFRFModel.build(ctx.ops, Stiffness(p_b, panel, 4.0), n_modes=ctx.n_modes, n_deriv=0,
                                    extra=s.basis_extra + 60, below_hz=s.basis_hz,
                                    extra_points=(Stiffness(p_b, panel, 1.5), Stiffness(p_b, panel, 12.0),
                                                  *extra_points))
        ctx.memo[key] = Family.make(red, base.family.slots, Layout(len(p_b), base.family.slots.n, "softening"),
                                    ctx.default_zeta)
    return ctx.memo[key]


def _scan(ctx: Context, base: Fitted) -> tuple[list[tuple], list[PanelSwarm]]:
    """(training error, panel, divisor, factors, factor set) of every panel x divisor of
    :data:`DIVISOR_SCAN` at three factor sets (``"baseline"``, ``"nominal"``, ``"swarm"``:
    :func:`panel_swarm`'s, also at the divisors it found), on one basis per panel spanning
    them, best first; and the swarms."""
    s = ctx.settings
    p_b, z_b, _ = base.layout.split(base.x)
    p_nom = ctx.nominal
    scan, swarms = [], []
    for panel in softening_panels(ctx.model):
        sw = panel_swarm(ctx, panel)
        swarms.append(sw)
        found = sorted({float(np.clip(d, *DIVISOR_RANGE)) for d in sw.divisors.values()})
        d_sw = float(np.exp(np.mean(np.log(found)))) if found else 4.0
        # the scan's basis spans every factor set it is evaluated at (the baseline's may be
        # far from nominal, e.g. a softened roof pushes the roof factors to their bound)
        fam = panel_family(ctx, base, panel, (Stiffness(p_nom, panel, 4.0),
                                              Stiffness(sw.factors_at(ctx, d_sw), panel, d_sw)))
        for which, factors, divisors in (("baseline", lambda d: p_b, DIVISOR_SCAN),
                                         ("nominal", lambda d: p_nom, DIVISOR_SCAN),
                                         ("swarm", functools.partial(sw.factors_at, ctx),
                                          sorted(set(DIVISOR_SCAN) | set(found)))):
            for d in divisors:
                p0 = factors(d)
                x = np.concatenate([np.log(p0), np.log(z_b), [np.log(d)]])
                scan.append((total_error(fam, x, ctx.meas, s.floor), panel, d, p0, which))
    scan.sort(key=lambda r: r[0])
    return scan, swarms


def fit_softening(ctx: Context, base: Fitted) -> list[Fitted]:
    """Global start (:func:`_scan`); then the best start of each factor set of the
    best-scoring panel, of each panel whose own factors the baseline pressed to their lower
    bound, of the panel whose swarm fits the identified modes best (from the swarm's
    factors) and of the ``settings.starts`` best-scoring panels refined with factors and
    divisor free, first on smoothed spectra (continuation), then briefly on the exact
    residual; the best of them fitted fully (dampings free too). Returns the fits, best
    first."""
    s = ctx.settings
    p_b = base.layout.split(base.x)[0]
    scan, swarms = _scan(ctx, base)
    ctx.say("swarm per softened panel, modal fit: " + ", ".join(
        f"{sw.panel} {sw.modal_fit_pct:.1f} %" + (" (/" + "/".join(f"{d:.2g}" for d in sw.divisors.values()) + ")"
                                                 if sw.divisors else "") for sw in swarms))
    ctx.say("panel softening scan: " + ", ".join(f"{pn} /{d:.3g} ({w}): {e:.0f}" for e, pn, d, _, w in scan[:4]))
    # evidence first: a panel whose own factors the baseline drove to their lower bound is
    # refined whatever its scan score (the baseline's other factors bent around it, so
    # the scan, which holds them, underrates it); then the best-scoring panels
    lower = {n.split(" ")[0] for n in at_bounds(ctx, base) if n.endswith("(lower)")}
    pressed = {pn for pn in softening_panels(ctx.model) if lower & set(ctx.ops.own_group_factors(pn))}
    if pressed:
        ctx.say(f"panel(s) whose own factors sit at their lower bound, refined first: {', '.join(sorted(pressed))}")
    # the panel the swarm fits the identified modes best with is refined from its own
    # factors too: the scan's exact FRF error punishes the few-percent peak misalignment a
    # swarm on frequencies leaves more than it rewards the right panel
    best_swarm = min(swarms, key=lambda sw: sw.modal_fit_pct).panel
    # the best-scoring panel is refined from the best start of each of its three factor sets:
    # with a strong softening the scan's best set may lead the refinement to a local minimum
    # another set avoids
    top = scan[0][1]
    order = sorted(scan, key=lambda r: (r[1] not in pressed and r[1] != top,
                                        not (r[1] == best_swarm and r[4] == "swarm"), r[0]))
    # starts: the top panel's three sets, two sets of each other pressed panel, the best
    # swarm's start and the settings.starts - 1 best-scoring other panels
    budget = 3 + 2 * len(pressed - {top}) + 1 + (s.starts - 1)
    starts, seen = [], set()
    for err, panel, d, p0, which in order:  # the best divisor of each panel (of each factor set: top, pressed)
        key = (panel, which) if panel == top else (panel, which == "nominal") if panel in pressed else panel
        if key in seen:
            continue
        seen.add(key)
        lay0 = Layout(len(p_b), 0, "softening")
        head = np.concatenate([np.log(p0), [np.log(d)]])
        red = basis_at(ctx, lay0, head, panel)
        slots, z = extension_start(ctx, base, lay0, red, head)
        lay = Layout(len(p_b), slots.n, "softening")
        lo, hi = factor_bounds(ctx, slots.n)
        lo, hi = np.append(lo, np.log(DIVISOR_RANGE[0])), np.append(hi, np.log(DIVISOR_RANGE[1]))
        x = np.concatenate([np.log(p0), np.log(z), [np.log(d)]])
        free = np.ones(x.size, bool)
        free[lay.n_p:lay.n_p + lay.n_slots] = False
        for width in (0.06, 0.03):  # continuation on smoothed spectra (relative widths), the basis rebuilt after each
            fam = Family.make(red, slots, lay, ctx.default_zeta)
            x = least_squares(fam, x, lo, hi, ctx.meas, s.refine_iterations // 2, s.floor, free, smooth=width)
            red = basis_at(ctx, lay, x, panel)
        starts.append(("local_panel_softening", lay, slots, x, lo, hi, panel, red))
        if len(starts) == budget:
            break
    return fit_best(ctx, starts)
