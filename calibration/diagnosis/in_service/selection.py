"""Which of the fitted hypotheses are causes, which are properties of a normal vehicle or
track, and which are neither.

The data has three parts that no extension shares, each decided on its own:

* **rail side**: the axle boxes' spectra over speed (the track extension);
* **wheels**: the axle-box consistency channel (the wheel polygon);
* **vehicle**: the bogie and carbody channels (the response extensions), where effects
  add up in one transfer function, so they are found one after the other (forward
  selection): the best hypothesis that passes (:meth:`.hypotheses.Hypothesis.passes`) is
  kept, every other response extension is fitted again on top of it and judged by what
  it adds on held-out data, and so on while one passes, up to ``MAX_RESPONSE_STEPS`` causes.
  When none passes at a step because each leaves the systematic residual of another effect
  or loses on the channel the other explains (two effects hide each other), the leading
  ones are tried in pairs (:func:`_pair`), at the first step and at later ones alike, and
  one that loses on a channel with each that mends that channel (:func:`_menders`).

A passing hypothesis whose fitted size is what every vehicle or track has (a carbody
bending above the catalogue's range, a track stiffer than its soft track:
:attr:`.extensions.Extension.normal_above`), or whose extension is what every vehicle has
at any size (:attr:`.extensions.Extension.always_normal`), is a *property*: kept in the model, so that
what it explains is not blamed on anything else, and reported, but not a cause. A
property is kept when it gains enough and loses nothing, even when it leaves systematic
residual (it is not the answer; what it leaves is for the next step), :func:`kept`. A size
whose range over held-out folds (the track's stiffness over the speed folds) reaches across
that line is a cause of low confidence: the data cannot tell the fault from the property.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .evidence import DiagnosisData, Evidence, channel_evidence, response_errors, within_accuracy
from .extensions import EXTENSIONS, Extension, combined
from .confidence import Confidence, held_out_confidence, response_confidence
from .amplitude import FRICTION, viscous
from .hypotheses import (Hypothesis, best_reduction, fit_hypothesis, heldout_losses, reductions, response_model,
                         systematic_left)
from .response import ResponseFit, fit_response

#: response causes found one after the other, at most (a third is rare enough on a campaign
#: of a few journeys that its held-out gain would not be trusted); properties found on the
#: way (a bending above the fault range, equipment on its mounts, the load of each journey)
#: do not count, since every vehicle has several
MAX_RESPONSE_STEPS = 3
#: response hypotheses tried in pairs when none passes alone (the best by gain)
PAIR_CANDIDATES = 3


@dataclass(frozen=True)
class Finding:
    """One extension the data asks for: its name, whether it is a cause or a property,
    its fitted parameters and what it gained on held-out data (over what was found before
    it, for the vehicle's later steps)."""

    name: str
    role: str  # "cause" or "property"
    parameters: dict
    gain: float
    best_channel: str
    hypothesis: Hypothesis  # as fitted (a vehicle step: the combination of every step so far)
    confidence: Confidence

    def to_json(self) -> dict:
        return {"name": self.name, "role": self.role, "parameters": self.parameters, "gain": self.gain,
                "best_channel": self.best_channel, **self.confidence.to_json()}


@dataclass(frozen=True)
class Selection:
    """The findings in the order found, and the response fit with every vehicle finding
    (None: no vehicle finding)."""

    findings: tuple[Finding, ...]
    vehicle_fit: ResponseFit | None
    vehicle_hypothesis: Hypothesis | None

    @property
    def causes(self) -> tuple[Finding, ...]:
        return tuple(f for f in self.findings if f.role == "cause")

    @property
    def properties(self) -> tuple[Finding, ...]:
        return tuple(f for f in self.findings if f.role == "property")

    def cause_name(self) -> str | None:
        """The causes joined by ``+`` in name order, or None."""
        return "+".join(sorted(f.name for f in self.causes)) or None

    def evidence_left(self, data: DiagnosisData, ev: Evidence) -> Evidence:
        """The baseline's evidence with the response channels' residuals of the vehicle's
        findings (what is left systematic once they are in the model)."""
        if self.vehicle_fit is None:
            return ev
        channels, _ = channel_evidence(data, self.vehicle_fit, ev.masks)
        return replace(ev, channels=channels)


def _stands_in(ext: Extension, h: Hypothesis) -> bool:
    """An extension for what every vehicle has (:attr:`.extensions.Extension.always_normal`)
    fitted with a parameter on a bound of its range is standing in for something it cannot
    model (a mount at its stiffest standing for a centre of mass off the middle, its damping
    at the top for a low-frequency misfit): it is not that property, and not kept. A
    parameter whose low end means the effect is absent there (:attr:`.extensions.Extension.absent_at_low`:
    no friction in the primary) may end there."""
    def standing(r) -> bool:
        if r.name not in h.parameters_at_bounds:
            return False
        return not (r.name in ext.absent_at_low and h.parameters[r.name] < np.sqrt(r.low * r.high))
    return ext.always_normal and any(standing(r) for r in ext.params)


def kept(ext: Extension, h: Hypothesis, s) -> bool:
    """Is ``h`` (``ext`` added) kept in the model: it passes, or it is a property that gains
    enough and loses nothing? A property need not explain the whole systematic residual:
    it is not the answer, and what it leaves is for the next step (a carbody's own 14 Hz
    bending leaves what a centre of mass 1 m off adds; bench seeds 8055, 8058, 8059)."""
    if _stands_in(ext, h):
        return False
    return h.passes(s) or (ext.is_property(h.parameters) and h.gains_enough(s))


def _own(ext: Extension, h: Hypothesis) -> dict:
    """The parameters of ``ext`` among those of ``h`` (``ext`` combined with others)."""
    names = [r.name for r in ext.params] + (["load_spread", "journey_loads"] if ext.per_run else [])
    return {n: h.parameters[n] for n in names}


def _finding(ext: Extension, h: Hypothesis, parameters: dict, confidence: Confidence) -> Finding:
    """A cause, or a property when its parameters say so. Fitted ranges across the property
    line (a track found at 82 MN/m, its speed folds from 76 to 88) make it a cause of low
    confidence: the data cannot rule the fault out, and `none` would claim they do."""
    across = ext.straddles(parameters, h.parameter_ranges)
    role = "property" if ext.is_property(parameters) and not across else "cause"
    between = ext.in_between(parameters)
    if across:
        confidence = replace(confidence, word="low", why=f"{confidence.why}, but {across}")
    elif between and confidence.word == "high":
        confidence = replace(confidence, word="moderate", why=f"{confidence.why}, but {between}")
    return Finding(ext.name, role, parameters, h.gain, h.best_channel, h, confidence)


def _confidence(data: DiagnosisData, ev: Evidence, before: ResponseFit, h: Hypothesis, ext: Extension,
                rivals: list[Hypothesis]) -> Confidence:
    """A response finding's confidence: ``h`` improving on ``before``, ``ext`` the extension
    it adds, ``rivals`` the other hypotheses that passed at that step."""
    s = data.settings
    return response_confidence(data, before, h.fit, h.best_channel, ev.masks, s.bar(ext.n_params),
                               [r.gain for r in rivals if r is not h])


def _pair_findings(data: DiagnosisData, ev: Evidence, pair) -> list[Finding]:
    """The findings of a pair (:func:`_pair`), each by what it adds to the other."""
    ea, eb, a, b, ab, ba = pair
    return [_finding(e, added, _own(e, ab), _confidence(data, ev, alone.fit, added, e, []))
            for e, alone, added in ((ea, b, ba), (eb, a, ab))]


def _under_floor(s, tried: list[tuple[Extension, Hypothesis]]) -> tuple[Extension, Hypothesis] | None:
    """The cause that no channel's model error asked for but the held-out data do: of the
    hypotheses that gain only where every channel was within a model's accuracy, the best
    that gains ``under_floor_gain`` (penalised) with no loss, no parameter of its own on a
    bound of its range and not a property (what every vehicle has is kept by its own rule).
    A small reservoir is a fault the model misses by less than the floor; a relative gain
    this large is not the noise of an adequate model (clean cars: 0-0.5 %)."""
    if s.under_floor_gain is None:
        return None
    def candidate(e: Extension, h: Hypothesis) -> bool:
        own_bounds = {r.name for r in e.params} & set(h.parameters_at_bounds)
        return not h.on_model_error and h.penalised_gain >= s.under_floor_gain and not h.losses \
            and not own_bounds and not e.is_property(_own(e, h))
    found = [(e, h) for e, h in tried if candidate(e, h)]
    return max(found, key=lambda eh: eh[1].penalised_gain, default=None)


def _under_floor_finding(data: DiagnosisData, ev: Evidence, before: ResponseFit, e: Extension,
                         h: Hypothesis) -> Finding:
    """:func:`_under_floor`'s cause as a finding of confidence ``low``, saying why."""
    c = _confidence(data, ev, before, h, e, [])
    c = replace(c, word="low", why=f"{c.why}; but every channel it gains on was within a model's accuracy before "
                                   "it (the floor), so no model error asked for it")
    return _finding(e, h, _own(e, h), c)


def _blocked(s, tried: list[tuple[Extension, Hypothesis]]) -> list[tuple[Extension, Hypothesis]]:
    """The (extension, hypothesis) pairs that gain the bar on a channel with a model error
    but are held back by the systematic rule or by a loss on another channel: what two
    effects that hide each other look like, each alone (the best by gain, at most
    ``PAIR_CANDIDATES``)."""
    return sorted(((e, h) for e, h in tried if h.penalised_gain >= s.min_gain and h.on_model_error
                   and (h.leaves_systematic(s) or h.losses)),
                  key=lambda eh: -eh[1].penalised_gain)[:PAIR_CANDIDATES]


def _menders(s, a: Hypothesis, tried: list[tuple[Extension, Hypothesis]]) -> list[tuple[Extension, Hypothesis]]:
    """The (extension, hypothesis) pairs of ``tried`` other than ``a`` that cut the held-out
    error of a channel ``a`` loses on by ``min_gain`` or more: the effect that may be behind
    the channel ``a`` overshoots on, though it gains too little alone to be held back by a
    rule (bench seed 8103: a mount explaining the rear floor but overshooting on the bogie,
    the reservoir's gain alone under the bar)."""
    def mends(h: Hypothesis) -> bool:
        return any((h.heldout_error[c]["reduction"] or 0.0) >= s.min_gain for c in a.losses)
    return [(e, h) for e, h in tried if h is not a and mends(h)]


def _pair(data: DiagnosisData, tried: list[tuple[Extension, Hypothesis]], before: ResponseFit,
          channels: dict, base_fit: ResponseFit, ev: Evidence, say
          ) -> tuple[Extension, Extension, Hypothesis, Hypothesis, Hypothesis, Hypothesis] | None:
    """Two effects that hide each other: each hypothesis of ``tried`` (an extension added
    to ``before``, whose residual's evidence per channel is ``channels``) that gains enough
    but leaves the systematic residual or loses on a channel (the other effect's part) is
    fitted together with each other such one, and one that loses on a channel with each
    that mends it (:func:`_menders`). A pair is found when each, added to the
    other, gains enough and loses on no channel (:func:`_needed`), neither stands in for something else
    (:func:`_stands_in`), and together they explain the systematic residual ``before``
    leaves as one hypothesis must. (e_a, e_b, a, b, a then b, b then a); None when no pair
    passes."""
    s = data.settings
    blocked = _blocked(s, tried)
    pairs = [(x, y) for i, x in enumerate(blocked) for y in blocked[i + 1:]]
    held = {id(h) for _, h in blocked}
    pairs += [(x, y) for x in blocked if x[1].losses for y in _menders(s, x[1], tried) if id(y[1]) not in held]
    best = None
    for (ea, a), (eb, b) in pairs:
        ab = fit_hypothesis(data, combined(a.extension, eb), base_fit, ev, 0.0, added_to=a)
        ba = fit_hypothesis(data, combined(b.extension, ea), base_fit, ev, 0.0, added_to=b)
        say(f"{a.name} with {eb.name}: held-out gain {ab.gain:.1%} over {a.name}, {ba.gain:.1%} over {b.name}")
        if _needed(s, ab, a) and _needed(s, ba, b) and not any(_stands_in(e, ab) for e in (ea, eb)) \
                and _explains(data, ab, before, channels, ev.masks) \
                and (best is None or ab.penalised_gain > best[4].penalised_gain):
            best = (ea, eb, a, b, ab, ba)
    return best


def _needed(s, h: Hypothesis, partner: Hypothesis) -> bool:
    """Does ``h``, one effect added to its ``partner``, gain enough and lose nothing? Its gain
    counts on a channel with a model error, or on one the partner alone made worse (a mount
    that explains the carbody's residual but overshoots on the bogie, which the reservoir
    on top of it mends: development campaign 61)."""
    return h.penalised_gain >= s.min_gain and not h.losses \
        and (h.on_model_error or h.best_channel in partner.losses)


def _explains(data: DiagnosisData, h: Hypothesis, before: ResponseFit, channels: dict, masks: np.ndarray) -> bool:
    """Does response hypothesis ``h``, judged as a whole against ``before`` (its residual's
    evidence ``channels``), meet the rules each single hypothesis meets: no channel made
    worse than ``before`` left it (:func:`.hypotheses.heldout_losses`), and on the channel
    with a model error where it gains most, at most ``max_systematic_left`` of the
    systematic residual left or what is left within a model's accuracy
    (:meth:`.hypotheses.Hypothesis.leaves_systematic`)? A pair's members are each judged
    against the other, so a loss both share would go unseen without the first rule."""
    s = data.settings
    names = data.layout.response_names
    errors = response_errors(data, before, masks)
    after = np.array([h.heldout_error[n]["after"] for n in names])
    red = reductions(errors, after)
    c = best_reduction(red, np.array([not within_accuracy(channels[n], s) for n in names]))
    if c is None:
        return False
    if heldout_losses(names, errors, after, s.max_loss):
        return False
    coherence = h.residual[names[c]]["after"]["input_coherence"]
    return systematic_left(float(red[c]), h.residual[names[c]]["after"], channels[names[c]]) \
        <= s.max_systematic_left or after[c] * coherence < s.systematic_floor


def select(data: DiagnosisData, hyps: list[Hypothesis], base_fit: ResponseFit, ev: Evidence,
           progress=None) -> Selection:
    """The findings of the fitted hypotheses ``hyps`` (each fitted alone on the baseline
    ``base_fit`` with evidence ``ev``); see the module's description."""
    s = data.settings
    say = progress or (lambda msg: None)
    findings: list[Finding] = []
    for kind in ("track", "wheel"):
        for h in hyps:
            if h.kind == kind and h.passes(s):
                how = "by speed (each speed bin from the others)" if kind == "track" else "on held-out runs"
                findings.append(_finding(h.extension, h, h.parameters, held_out_confidence(h.gain, how)))
    response = [h for h in hyps if h.kind == "response"]
    passed = [h for h in response if kept(h.extension, h, s)]
    current = max(passed, key=lambda h: h.penalised_gain, default=None)
    if current is not None:
        findings.append(_finding(current.extension, current, current.parameters,
                                 _confidence(data, ev, base_fit, current, current.extension, passed)))
        used = [current.name]
    else:
        pair = _pair(data, [(h.extension, h) for h in response], base_fit, ev.channels, base_fit, ev, say)
        if pair is None:
            under = _under_floor(s, [(h.extension, h) for h in response])
            if under is None:
                return Selection(tuple(findings), None, None)
            findings.append(_under_floor_finding(data, ev, base_fit, *under))
            return _consistent(data, Selection(tuple(findings), under[1].fit, under[1]))
        findings += _pair_findings(data, ev, pair)
        used, current = [pair[0].name, pair[1].name], pair[4]
    def causes():
        return sum(f.role == "cause" for f in findings if f.hypothesis.kind == "response")

    while causes() < MAX_RESPONSE_STEPS:
        tried = []
        for name, e in EXTENSIONS.items():
            e = e.on(data.layout)
            if e is None or e.kind != "response" or name in used:
                continue
            h = fit_hypothesis(data, combined(current.extension, e), base_fit, ev, 0.0, added_to=current)
            say(f"{' + '.join(used)} + {name}: held-out gain {h.gain:.1%} on {h.best_channel}")
            tried.append((e, h))
        ok = [(e, h) for e, h in tried if kept(e, h, s)]
        if not ok:  # two effects may hide each other here as at the first step
            pair = None if not _blocked(s, tried) else \
                _pair(data, tried, current.fit, channel_evidence(data, current.fit, ev.masks)[0], base_fit, ev, say)
            new = [] if pair is None else _pair_findings(data, ev, pair)
            if not new or causes() + sum(f.role == "cause" for f in new) > MAX_RESPONSE_STEPS:
                under = None if causes() else _under_floor(s, tried)
                if under is not None:
                    findings.append(_under_floor_finding(data, ev, current.fit, *under))
                    current = under[1]
                break
            findings += new
            used += [pair[0].name, pair[1].name]
            current = pair[4]
            continue
        e, h = max(ok, key=lambda eh: eh[1].penalised_gain)
        own = _own(e, h)
        findings.append(_finding(e, h, own, _confidence(data, ev, current.fit, h, e, [x for _, x in ok])))
        used.append(e.name)
        current = h
    return _consistent(data, Selection(tuple(findings), current.fit, current))


def _consistent(data: DiagnosisData, sel: Selection) -> Selection:
    """``sel`` with the vehicle's model refitted with its amplitude classes consistent with
    the friction found (:mod:`.amplitude`): the sizes reported and the model handed on. The
    decision stands on the fits it was made with; the refit moves a friction's size, not
    whether the data asks for it."""
    h = sel.vehicle_hypothesis
    if h is None or not any(r.name in FRICTION for r in h.extension.params):
        return sel
    ext, fit = h.extension, h.fit
    known = {r.name: fit.values[r.name] for r in ext.params}
    again = fit_response(data.stats, data.layout, data.keys(data.train), viscous(fit.parameters, fit.values),
                         data.bounds, ext_params=ext.params, make=ext.make, known=known, per_run=ext.per_run,
                         heldout_keys=data.keys(data.test), relinearise=True)
    h = replace(h, fit=again, parameters=again.values, model=response_model(again),
                parameters_at_bounds=tuple(n for n in again.at_bounds if n in again.values))
    findings = tuple(replace(f, parameters={n: again.values.get(n, v) for n, v in f.parameters.items()})
                     if f.hypothesis.kind == "response" else f for f in sel.findings)
    return Selection(findings, again, h)
