"""The diagnosis of an excitation test, stage by stage: context, baseline, every extension
of the registry, the baseline re-fitted where a hypothesis found it a better basin, the
evidence, the decision, the result."""
from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np

from ...data.campaign import Campaign
from ...data.errors import CampaignError, InputError
from ...models.box import BoxModel, FactorSet
from ...models.box.rig import point_record
from ...models.box.shinkansen import order_change_of
from ...progress import counter
from ..threads import one_blas_thread
from .baseline import baseline_start, fit_baseline, modal_damping
from .context import Context, build_context
from .decision import confidences, judge, misfit_alarms, name_cause, summary_lines
from .detectability import detectability
from .evidence import HeldOut, compare_modes, confined_channel, gather_evidence, heldout, without_channel
from .extensions import EXTENSIONS
from .fitting import Fitted, factor_bounds, fit
from .least_squares import total_error
from .result import BaselineRecord, ExcitationDiagnosis, Restart
from .settings import ExcitationDiagnosisSettings


def _refit_baseline(ctx: Context, base: Fitted, held: HeldOut,
                    fits: dict[str, Fitted]) -> tuple[Fitted, HeldOut, tuple[Restart, ...]]:
    """A hypothesis may gain only because its fit found a better basin for the baseline's
    own factors: the baseline is re-fitted from each gaining hypothesis's factors (without
    the extension) and kept where it fits the training part better."""
    s = ctx.settings
    n = len(ctx.sensors)
    restarts = []
    for name, fitted in fits.items():
        if judge(ctx, EXTENSIONS[name], fitted, held.error).penalised_gain < s.min_gain:
            continue
        start = baseline_start(ctx, base, fitted)
        e0 = total_error(base.family, start, ctx.meas, s.floor)
        if e0 >= base.train_error:  # the extension's own factors do not fit better without it
            restarts.append(Restart(name, e0 / n, None, False))
            continue
        lo, hi = factor_bounds(ctx, base.layout.n_slots)
        alt = fit(ctx, "baseline", base.layout, base.family.slots, start, lo, hi)
        restarts.append(Restart(name, e0 / n, alt.train_error / n, bool(alt.train_error < base.train_error)))
        if alt.train_error < base.train_error:
            base = alt
            held = heldout(ctx, base)
            ctx.say(f"baseline re-fitted from the factors of {name}: held-out error {np.mean(held.error):.2f} x noise")
    return base, held, tuple(restarts)


def _refit_hypotheses(ctx: Context, base: Fitted, fits: dict[str, Fitted]) -> dict[str, Fitted]:
    """The hypotheses were fitted from a baseline that a re-fit has since left for a better
    basin, so their scans and starts described the old one: each is fitted again from the
    new baseline, and the better fit of the two on the training part kept."""
    out = {}
    for name, old in fits.items():
        new = EXTENSIONS[name].fit(ctx, base)[0]
        out[name] = new if new.train_error < old.train_error else old
        ctx.say(f"{name} fitted again from the re-fitted baseline: training error "
                f"{new.train_error / len(ctx.sensors):.2f} against {old.train_error / len(ctx.sensors):.2f}")
    return out


@one_blas_thread  # the answer must not depend on the machine's thread count (..threads)
def diagnose_excitation(campaign: Campaign, *, progress=None, model: BoxModel | None = None,
                        settings: ExcitationDiagnosisSettings = ExcitationDiagnosisSettings(),
                        factors: FactorSet | None = None, start: Mapping[str, float] | None = None,
                        start_fit_pct: float | None = None, model_keys: Mapping | None = None) -> ExcitationDiagnosis:
    """Diagnose an excitation-test campaign (kind ``stationary_excitation``; the package
    docstring tells how).

    ``progress``: a callable taking a message (and driving a progress bar), or None.
    ``model``: the assembled box model without effect (default: the Shinkansen-type vehicle
    at full order); pass the model the campaign should be compared with (e.g. a coarse one
    in tests). ``factors``: the factor set the baseline is fitted over (the model assembled
    from it when ``model`` is None; default: the grouped set), within the campaign's priors,
    else the set's ranges. ``start``: a calibration's factors by name, where the baseline's
    FRF refinement starts instead of after a swarm, and ``start_fit_pct`` that calibration's
    modal fit [%] (recorded with it). ``model_keys``: the calibration file's keys that
    describe ``model`` (``factor_set``, ``side_end_zone_m``, ``order_change``, ...), which the
    extended model's file repeats (:func:`extended_model_keys`).

    Bad input raises :class:`InputError` naming the campaign.toml key."""
    t0 = time.perf_counter()
    say = progress or (lambda msg: None)
    s = settings
    stages = counter(progress, 3 + len(EXTENSIONS), "shaker diagnosis", unit="stage")
    ctx = build_context(campaign, s, model, say, factors=factors, start=start, start_fit_pct=start_fit_pct)
    stages.update()
    base, swarm = fit_baseline(ctx)
    stages.update()
    held = heldout(ctx, base)
    say(f"baseline: held-out error {np.mean(held.error):.2f} x noise (training "
        f"{base.train_error / len(ctx.sensors):.2f})")
    fits = {}
    for ext in EXTENSIONS.values():
        fits[ext.name] = ext.fit(ctx, base)[0]
        stages.update()
        h = judge(ctx, ext, fits[ext.name], held.error)
        say(f"{ext.name}: held-out gain {h.gain:.1%} (training error {h.training_error_mean:.2f}), "
            + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in h.parameters.items()))
    base, held, restarts = _refit_baseline(ctx, base, held, fits)
    if any(r.kept for r in restarts):
        fits = _refit_hypotheses(ctx, base, fits)
        # the fits made again must not be credited with a basin of the baseline's either (one more
        # re-fit of the baseline, the hypotheses not fitted a third time)
        base, held, again = _refit_baseline(ctx, base, held, fits)
        restarts += again
    hypotheses = tuple(judge(ctx, EXTENSIONS[name], f, held.error) for name, f in fits.items())
    per_channel = {n: float(v) for n, v in zip(ctx.sensors, held.error)}
    one = confined_channel(per_channel, s)
    left_out = None
    if one is not None and len(ctx.sensors) > 2:
        try:
            left_out = without_channel(campaign, s, ctx.model, one[0], say, factors, start, start_fit_pct)
        except (CampaignError, InputError) as exc:  # e.g. no mode identified without it: the check is skipped
            say(f"re-calibration without {one[0]} not possible: {exc}")
    evidence = gather_evidence(ctx, base, held, compare_modes(ctx, base), swarm, left_out)
    alarms, notes = misfit_alarms(per_channel, evidence.unpaired, s, without_channel=left_out,
                                  local=evidence.local_resonances)
    cause, best = name_cause(hypotheses, alarms, s)
    confidence, intervals = confidences(hypotheses, best, s)
    detect = detectability(ctx, base)
    summary = tuple(summary_lines(cause, best, alarms, notes, evidence, hypotheses, confidence, intervals,
                                  detect)) \
        + (_ranges_words(campaign.meta.priors, ctx),)
    extension_modes = None if best is None else compare_modes(ctx, fits[best.name])
    stages.update()
    stages.close()
    record = BaselineRecord(base.factors(ctx.names), swarm, restarts,
                            {n: (a, b) for n, a, b in zip(ctx.names, ctx.low, ctx.high)}, modal_damping(base))
    return ExcitationDiagnosis(str(campaign.root), cause, summary, ctx.meas_test, evidence, record, hypotheses, best,
                               extension_modes, tuple(ctx.train.label), tuple(ctx.test.label), s, ctx.n_modes,
                               ctx.model.n_dof, time.perf_counter() - t0, confidence, intervals, detect,
                               extended_model_keys(campaign, ctx, model_keys or {}))


#: the keys of a box calibration file that describe its model, and so the extended model's
MODEL_KEYS = ("factor_set", "side_end_zone_m", "order_change", "sensors", "exciter", "identified_modes")


def extended_model_keys(campaign: Campaign, ctx: Context, given: Mapping) -> dict:
    """The extended model's calibration keys but its factors and extension: those ``given``
    of :data:`MODEL_KEYS` (the calibration's), else the model's panel orders, the factor set it
    was built from, the campaign's sensors and exciter and the training part's identified
    modes (whose damping the FMU takes). A model of other orders than the Shinkansen-type
    vehicle's plus one step gets ``order_change`` None, which no calibration file accepts:
    its extended model is refused, not built otherwise."""
    out = {k: given[k] for k in MODEL_KEYS if k in given}
    if "order_change" not in out:  # a model given as such: its orders say how it was built
        out["order_change"] = order_change_of(ctx.model.vehicle)
    if "factor_set" not in out and ctx.factors is not None:
        out["factor_set"] = ctx.factors.name
        if ctx.factors.side_end_zone:
            out["side_end_zone_m"] = ctx.factors.side_end_zone
    meta = campaign.meta
    out.setdefault("sensors", [point_record(meta.sensor(n)) for n in ctx.sensors])
    out.setdefault("exciter", point_record(meta.exciter()))
    out.setdefault("identified_modes", [m.to_json() for m in ctx.ident.modes])
    return out


def _ranges_words(priors, ctx) -> str:
    """Where the baseline's factor ranges came from: the campaign's priors, or (for the
    factors it gives none) the factor set's defaults, said so rather than assumed silently."""
    default = [(n, lo, hi) for n, lo, hi in zip(ctx.names, ctx.low, ctx.high) if n not in priors]
    head = "baseline" if ctx.factors is None else f"baseline ({ctx.factors.name} factors)"
    if not default:
        return f"{head}: every box factor within the campaign's priors"
    which = "any box factor" if len(default) == len(ctx.names) else ", ".join(n for n, _, _ in default)
    spans = ", ".join(sorted({f"{lo:g}-{hi:g}" for _, lo, hi in default}))
    return f"{head}: campaign.toml gives no prior for {which}; searched over the default ranges {spans} (x nominal)"
