"""``railcal diagnose`` on an in-service campaign: what the calibrated 2D car gets wrong,
the cause, the extended model and the gain.

1. **Data.** Gap-free records of rail input (axle boxes), responses (bogie and carbody
   sensors) and the axle-box consistency channel (:mod:`.records`); runs split into
   training (odd) and held-out (even) runs; a single run is split in halves. The wheel
   polygon is decided here, on the consistency channel: a trailing bogie's rail is taken
   from a round wheelset.
2. **Baseline.** The user's calibration when given, else the campaign's priors (a
   campaign with neither is refused; parameters neither gives are the seed's car's and the
   summary lists them, :mod:`.baseline`): its masses, inertias, stiffnesses and dampings
   fitted to the training runs by residual energy (:mod:`.response`) within the priors'
   ranges, or a factor ``prior_spread`` around the start where there is no prior.
3. **Evidence** from the baseline's residuals (:mod:`.evidence`).
4. **Hypotheses.** Every extension of :data:`.extensions.EXTENSIONS` is scored by the
   evidence that speaks for it and ranked; the leading ones are fitted and judged on
   held-out data (:mod:`.hypotheses`).
5. **Decision** (:mod:`.selection`). A hypothesis *passes* when its penalised gain
   exceeds ``min_gain`` (for a response extension, on a channel the model it extends gets
   wrong: held-out NRP x input coherence at or above ``systematic_floor``), it makes no
   held-out channel worse by more than ``max_loss`` of its error (unless that worsening is
   under ``max_loss`` of what the hypothesis removes over the channels it improves, in the
   same units) and, for a response extension, it explains the systematic residual on the
   channel it gains on (held-out error times the residual's coherence with the rail input
   falls to ``max_systematic_left`` of the baseline's or below: an extension that only
   rescales what it cannot model, e.g. a gyro gain against a bogie resonance, leaves the
   residual as coherent as before). The rail side (track), the
   wheels and the vehicle are decided apart; on the vehicle, response extensions are
   added one after the other while one passes on top of those found, or found in pairs
   when two effects hide each other. Each finding carries its held-out gain's interval
   and a confidence word (:mod:`.confidence`). A passing extension
   fitted at a size every vehicle or track has (a carbody bending above 12 Hz, a track
   stiffer than 80 MN/m per wheelset), or one for what every vehicle has at any size
   (equipment on its mounts, the load of each journey), is a property, kept and reported,
   not a cause; a property is kept when it gains enough and loses nothing even if it leaves
   systematic residual, which the next step must then explain. The causes, joined by
   ``+``, are the answer; without one, ``none`` when what is left shows nothing systematic
   (residual input-coherence, or the coherent part of the held-out error when it is within
   a model's accuracy, peaks and lines all below their thresholds once the properties are
   in the model), else ``unexplained`` with the evidence.
6. **Detectability** (:mod:`.detectability`): for every extension, the weakest effect this
   campaign could have named, predicted at the baseline fit; ``none`` lists them ("no
   effect above these sizes") and names effects the sensor set cannot observe.

Held-out error per channel kind: response channels, NRP over the bands where the
measured channel stands ``signal_factor`` above its own spectral floor (noise-only bands
excluded, the same bands before and after); consistency, its mean square after the wheel
line is removed; axle boxes, the mean squared log10 misfit of the spectra's collapse over
speed less their sampling variance, held out by speed (:func:`.track.speed_folds`).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from ...data.campaign import Campaign
from ...data.errors import CampaignError
from ...progress import counter
from ..threads import one_blas_thread
from .baseline import BaselineStart, baseline_start
from .confidence import hypothesis_intervals
from .detectability import Detectability, detectability, with_track_fit
from .evidence import DiagnosisData, Evidence, alarms, baseline_evidence, notes, scores
from .extensions import EXTENSIONS
from .hypotheses import Hypothesis, fit_hypothesis
from .records import BOGIE_SPACING_SHARE, Layout, Record, layout, read_records, statistics
from .response import fit_response
from .result import InServiceDiagnosis
from .selection import Selection, select
from .settings import DiagnosisSettings


def _halves(records: list[Record]) -> list[Record]:
    """One run: its records' first and second halves play training and held-out runs."""
    split = []
    for r in records:
        h = r.z.shape[1] // 2
        for tag, sl in (("a", slice(0, h)), ("b", slice(h, None))):
            split.append(Record(f"{r.run_id}#{tag}", r.t0, r.speed[sl], r.distance[sl], r.z[:, sl]))
    return split


def _data(campaign: Campaign, settings: DiagnosisSettings, start: BaselineStart, say
          ) -> tuple[DiagnosisData, Hypothesis | None]:
    """The campaign read into records and band statistics, split into training (odd) and
    held-out (even) runs, with the baseline's start and search bounds; and the wheel
    polygon's hypothesis (None when the wheel extension does not apply to the campaign's sensors).

    The wheels are decided first, on the consistency channel alone: a leading wheelset
    found out of round carries its polygon in its axle boxes, so a trailing wheelset
    without axle boxes takes its rail from the round one (:meth:`.records.Layout.rail_sources`)
    and the records are read again. Otherwise the polygon would drive the model's trailing
    bogie, which has none, and its response would stand as a carbody model error for a
    response extension to absorb (bench seed 8257: floor sensor gains on their bounds)."""
    lay = layout(campaign)
    data = _read(campaign, lay, settings, start, say)
    ext = EXTENSIONS["wheel_out_of_round"].on(lay)
    if ext is None:
        return data, None
    wheel = fit_hypothesis(data, ext, None, None, 0.0)
    trailing_unsensed = not (lay.axle["axle3"] and lay.axle["axle4"])
    if wheel.passes(settings) and trailing_unsensed:
        w = wheel.fit.wheelset
        say(f"wheelset {w} out of round: the trailing bogie's rail is taken from wheelset {3 - w}")
        data = _read(campaign, replace(lay, out_of_round=w), settings, start, say)
    return data, wheel


def _read(campaign: Campaign, lay: Layout, settings: DiagnosisSettings, start: BaselineStart, say
          ) -> DiagnosisData:
    """:func:`_data`'s records and statistics for layout ``lay``."""
    records = read_records(campaign, lay, settings.records, progress=say)
    if len(campaign.run_ids) == 1:
        records = _halves(records)
    stats = statistics(records, lay.channels, settings.records)
    if len(stats.runs) < 2:
        raise CampaignError(f"the diagnosis needs data from two runs (or one long run) to hold one out; usable "
                            f"{settings.records.segment_s:g} s segments came from {len(stats.runs)}",
                            path=campaign.root)
    runs = stats.runs
    train, test = frozenset(runs[0::2]), frozenset(runs[1::2])
    return DiagnosisData(campaign.root, frozenset(campaign.run_ids), lay, tuple(records), stats, train, test,
                         start.parameters, start.bounds, settings)


@one_blas_thread  # the answer must not depend on the machine's thread count (threads.py)
def diagnose_in_service(campaign: Campaign, *, settings: DiagnosisSettings = DiagnosisSettings(),
                        calibration: Mapping | None = None, calibration_path: Path | None = None,
                        progress=None) -> InServiceDiagnosis:
    """Diagnose an in-service campaign: the baseline car fitted to the training runs, the
    evidence of its residuals, the leading extensions fitted and judged on held-out data,
    and the cause (see the module's description). ``calibration``: a car2d calibration
    file's content (read from ``calibration_path``), the baseline's start; without it the
    campaign's priors. ``progress``: None or a callable taking a message
    (:mod:`calibration.progress`)."""
    say = progress or (lambda msg: None)
    start = baseline_start(campaign, settings.prior_spread, calibration, calibration_path)
    stages = counter(progress, 3 + settings.fit_leading, "in-service diagnosis", unit="stage")
    data, wheel = _data(campaign, settings, start, say)
    stages.update()
    stats = data.stats
    say(f"{len(data.records)} records, {sum(stats.seconds.values()):.0f} s in {len(stats.S)} (run, speed) cells; "
        f"training runs {sorted(data.train)}, held out {sorted(data.test)}")
    base_fit = fit_response(stats, data.layout, data.keys(data.train), data.prior, data.bounds)
    stages.update()
    say(f"baseline fitted ({base_fit.evaluations} evaluations)")
    ev = baseline_evidence(data, base_fit)
    score = scores(ev, data.layout, settings)
    ranked = sorted(score, key=lambda k: -score[k])
    hyps = []
    on_car = {n: e.on(data.layout) for n, e in EXTENSIONS.items()}  # None: no sensor of the campaign's to act on
    for name in [n for n in ranked if on_car[n] is not None][:settings.fit_leading]:
        if name == "wheel_out_of_round" and wheel is not None:  # fitted in _data: the consistency channel is kept
            h = replace(wheel, evidence_score=score[name])
        else:
            h = fit_hypothesis(data, on_car[name], base_fit, ev, score[name])
        stages.update()
        hyps.append(h)
        say(f"{name}: held-out gain {h.gain:.1%} on {h.best_channel}")
    sel = select(data, hyps, base_fit, ev, say)
    # no vehicle cause: a cause of any size would have been judged after the properties found
    vehicle_cause = any(f.hypothesis.kind == "response" for f in sel.causes)
    detect = detectability(data, base_fit, None if vehicle_cause else sel.vehicle_fit)
    detect = with_track_fit(detect, next((h for h in hyps if h.kind == "track"), None), settings)
    intervals = hypothesis_intervals(data, base_fit, hyps, ev.masks)
    left = sel.evidence_left(data, ev)
    words = alarms(left, settings)
    cause = sel.cause_name() or ("unexplained" if words else "none")
    best = None
    if sel.causes:  # the extended model: every vehicle finding together, else the rail or wheel cause
        best = sel.vehicle_hypothesis if vehicle_cause else max((f.hypothesis for f in sel.causes),
                                                                key=lambda h: h.penalised_gain)
    summary = _summary(cause, sel, words + notes(left, settings), ev, hyps, settings, detect, intervals) \
        + start.describe()
    lay = data.layout
    if lay.out_of_round is not None:
        summary.append(f"rail input: wheelset {lay.out_of_round} is out of round, so the trailing bogie's rail is "
                       f"taken from wheelset {3 - lay.out_of_round}'s axle boxes")
    if lay.length_assumed and lay.carbody_sensed:
        summary.append(f"carbody length: campaign.toml's [vehicle] gives none; a bending's shape assumed "
                       f"{lay.length:.1f} m (the bogie spacing over {BOGIE_SPACING_SHARE})")
    stages.update(stages.total - stages.n)  # fewer hypotheses than fit_leading: the rest skipped
    stages.close()
    return InServiceDiagnosis(
        campaign=campaign.root, cause=cause, summary=tuple(summary), evidence=ev, hypotheses=tuple(hyps), best=best,
        baseline=base_fit, start=start, bounds=data.bounds, training_runs=tuple(sorted(data.train)),
        heldout_runs=tuple(sorted(data.test)), settings=settings, layout=data.layout, statistics=stats,
        detectability=detect, findings=sel.findings, intervals=intervals, extended=sel.vehicle_fit)


def _values(parameters: dict) -> str:
    def one(v):
        if isinstance(v, dict):
            return "(" + ", ".join(f"{k} {one(x)}" for k, x in v.items()) + ")"
        return f"{v:.4g}" if isinstance(v, float) else f"{v}"
    return ", ".join(f"{k} = {one(v)}" for k, v in parameters.items())


def _summary(cause: str, sel: Selection, alarm_words: list[str], ev: Evidence, hyps: list[Hypothesis],
             s: DiagnosisSettings, detect: Detectability, intervals: Mapping) -> list[str]:
    """The diagnosis in words: the causes (``none`` with the smallest effects this campaign
    could have detected, :mod:`.detectability`), the properties found, the alarms left, the
    hypotheses that gained but were not named and why, all hypotheses by gain, the
    baseline's parameters at bounds."""
    out = []
    for f in sel.causes:
        c = f.confidence
        out.append(f"cause: {f.name} ({EXTENSIONS[f.name].description}); held-out error on {f.best_channel} "
                   f"reduced by {f.gain:.0%}{c.interval_words()}; confidence {c.word}: {c.why}; {_values(f.parameters)}")
    if not sel.causes and cause == "unexplained":
        out.append("unexplained: the baseline leaves systematic residuals and no extension in the registry "
                   "reduces the held-out error enough")
    elif not sel.causes:
        out.append("none: no effect above these sizes: " + detect.words())
    for f in sel.properties:
        out.append(f"property, not a cause: {f.name} with {_values(f.parameters)} "
                   f"({EXTENSIONS[f.name].normal_words()}; kept in the model, it gains {f.gain:.0%} on "
                   f"{f.best_channel})")
    out += alarm_words
    found = [f.hypothesis for f in sel.findings]
    for h in hyps:
        if any(h is x for x in found) or h.penalised_gain < s.min_gain:
            continue
        if h.losses:
            worse = ", ".join(f"{n} ({h.heldout_error[n]['before']:.3g} -> {h.heldout_error[n]['after']:.3g})"
                              for n in h.losses)
            out.append(f"{h.name} gains {h.gain:.0%} on {h.best_channel} but makes held-out {worse} worse")
        if not h.on_model_error:
            out.append(f"{h.name} gains {h.gain:.0%} on {h.best_channel}, a channel already within a model's "
                       "accuracy: no model error it explains")
        if h.leaves_systematic(s):
            out.append(f"{h.name} gains {h.gain:.0%} on {h.best_channel} but leaves "
                       f"{h.systematic_left:.0%} of its systematic residual (error x input coherence): "
                       "it does not explain it")
    others = sorted(hyps, key=lambda h: -h.penalised_gain)
    def gain(h):
        c = intervals.get(h.name)
        return f"{h.gain:.0%}" if c is None or c.interval is None else \
            f"{h.gain:.0%} ({c.interval[0]:.0%} to {c.interval[1]:.0%})"

    out.append("hypotheses by held-out gain (95 % interval): " + ", ".join(f"{h.name} {gain(h)}" for h in others))
    if ev.parameters_at_bounds:
        out.append("baseline parameters at their bounds: " + ", ".join(ev.parameters_at_bounds))
    return out
