"""The decision on the held-out part: each hypothesis judged by the reduction of the
held-out error it brings, the cause named (or ``none`` / ``unexplained``), and the
summary in words.

The gain of a hypothesis is the relative reduction of the held-out error summed over all
channels; the cause is the hypothesis with the largest gain less ``penalty`` per parameter
if that is at least ``min_gain``, no channel worsens by more than ``max_loss``, its fit
does not end where its effect vanishes (:attr:`.extensions.ExcitationExtension.null_end`),
and an effect that is one factor on every channel stands above the channels' own level
scatter (:attr:`.extensions.ExcitationExtension.uniform_level`).
Otherwise ``none`` when the baseline's held-out error is within ``noise_alarm`` of the noise
and no identified mode is left unpaired with the held-out FRF around it misfitted, else
``unexplained``.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ...identification.excitation import LocalResonance
from ..confidence import Confidence, from_units
from ..limits import Detectability
from .context import Context
from .evidence import ChannelLeftOut, Evidence, HeldOut, UnpairedMode, confined_channel, heldout
from .extensions import EXTENSIONS, ExcitationExtension
from .fitting import Fitted
from .force import UNIFORM
from .frf import level_scatter
from .settings import ExcitationDiagnosisSettings


@dataclass(frozen=True, eq=False)
class Hypothesis:
    """An extension fitted to the training part and judged on the held-out part.

    parameters : the extension's fitted parameters (SI units); factors : the box factors
        fitted with it
    training_error_mean : mean over channels of E on the training part [-]
    before, after : (n_s,) held-out E per channel of the baseline and of this model [-]
    gain : relative reduction of the held-out E summed over channels [-]
    worst_loss : largest worsening of a channel, in units of its error (>= the noise) [-]
    penalised_gain : gain less the penalty per parameter [-]
    heldout : this model against the held-out FRFs
    level_scatter : for a factor on every channel, the rms of the channels' level offsets
        about their common one that this model leaves on the held-out FRFs [-] (else None)
    at_limits : the extension's parameters that end on a limit of their search
    """

    name: str
    description: str
    parameters: dict
    n_params: int
    at_null_end: bool
    factors: dict
    training_error_mean: float
    sensors: tuple[str, ...]
    before: np.ndarray
    after: np.ndarray
    gain: float
    worst_loss: float
    penalised_gain: float
    heldout: HeldOut
    level_scatter: float | None = None
    at_limits: tuple[str, ...] = ()

    @property
    def mixed_level(self) -> bool:
        """Is this a factor on every channel that does not stand :data:`.force.UNIFORM`
        times above the channels' own level scatter?"""
        if self.level_scatter is None:
            return False
        return bool(abs(np.log(self.parameters["force_gain"])) < UNIFORM * self.level_scatter)

    @property
    def reduction(self) -> np.ndarray:
        """(n_s,) relative reduction of the held-out E per channel [-]."""
        return 1.0 - self.after / self.before

    @property
    def best_channel(self) -> str:
        return self.sensors[int(np.argmax(self.reduction))]

    @property
    def best_channel_reduction(self) -> float:
        return float(self.reduction[int(np.argmax(self.reduction))])

    def heldout_error_json(self) -> dict:
        """The held-out E before and after, summed over channels and per channel."""
        total_b, total_a = float(self.before.sum()), float(self.after.sum())
        return {"all_channels": {"before": total_b, "after": total_a, "reduction": self.gain},
                **{n: {"before": float(b), "after": float(a), "reduction": float(r)}
                   for n, b, a, r in zip(self.sensors, self.before, self.after, self.reduction)}}

    def to_json(self) -> dict:
        return {"name": self.name, "description": self.description, "parameters": dict(self.parameters),
                "n_params": self.n_params, "at_null_end": self.at_null_end, "factors": dict(self.factors),
                "training_error_mean": self.training_error_mean, "heldout_error": self.heldout_error_json(),
                "best_channel": self.best_channel, "best_channel_reduction": self.best_channel_reduction,
                "gain": self.gain, "worst_loss": self.worst_loss, "penalised_gain": self.penalised_gain,
                "at_limits": list(self.at_limits),
                **({} if self.level_scatter is None else {"level_scatter": self.level_scatter})}


def judge(ctx: Context, ext: ExcitationExtension, fitted: Fitted, before: np.ndarray) -> Hypothesis:
    """``fitted`` (extension ``ext``) judged on the held-out part against the baseline's
    held-out E per channel ``before``."""
    held = heldout(ctx, fitted)
    after = held.error
    gain = 1.0 - float(after.sum()) / float(before.sum())
    loss = (after - before) / np.maximum(before, 1.0)  # worsening in units of the channel's error (>= noise)
    params = fitted.extension_parameters(ctx.carbody_mass)
    scatter = level_scatter(ctx.meas_test, held.H, ctx.settings.floor) if ext.uniform_level else None
    return Hypothesis(ext.name, ext.description, params, ext.n_params, ext.at_null_end(params),
                      fitted.factors(ctx.names), fitted.train_error / len(ctx.sensors), ctx.sensors, before, after,
                      gain, float(loss.max()), gain - ctx.settings.penalty * ext.n_params, held, scatter,
                      tuple(fitted.extension_at_limits()))


def passes(h: Hypothesis, settings: ExcitationDiagnosisSettings) -> bool:
    """Whether ``h`` gains enough, loses little, does not end at its null end and, as a factor
    on every channel, stands above the channels' level scatter."""
    s = settings
    return h.penalised_gain >= s.min_gain and h.worst_loss <= s.max_loss and not h.at_null_end \
        and not h.mixed_level


def name_cause(hypotheses: Sequence[Hypothesis], alarms: Sequence[str],
               settings: ExcitationDiagnosisSettings) -> tuple[str, Hypothesis | None]:
    """The cause and the hypothesis named (None for ``none`` and ``unexplained``): of the
    hypotheses that pass (:func:`passes`), the one of the largest penalised gain (the first
    of equals); without one, ``unexplained`` if anything alarms, else ``none``."""
    ok = [h for h in hypotheses if passes(h, settings)]
    best = max(ok, key=lambda h: h.penalised_gain) if ok else None
    return (best.name if best else ("unexplained" if alarms else "none")), best


def confidences(hypotheses: Sequence[Hypothesis], best: Hypothesis | None,
                settings: ExcitationDiagnosisSettings) -> tuple[Confidence | None, dict[str, Confidence]]:
    """(the cause's confidence, each hypothesis's gain with its interval judged against the
    bar alone): the held-out channels are the units resampled
    (:mod:`calibration.diagnosis.confidence`). A channel's E adds to the total the gain is
    taken over, and which points of the floor were instrumented is a choice the gain should
    not hang on. A cause whose fit ends on a search limit of its own parameters is at most
    ``moderate``: the in-service diagnosis's reading of a property at a bound (standing in
    for something it cannot model), here for a rigidly bolted mass fitted as resiliently
    mounted equipment with its mount damping at the lowest the search allows (seed 6752)."""
    s = settings
    bar = {h.name: s.bar(h.n_params) for h in hypotheses}
    intervals = {h.name: from_units(h.before, h.after, bar[h.name], [], "channels") for h in hypotheses}
    if best is None:
        return None, intervals
    rivals = [h.gain for h in hypotheses if h is not best and passes(h, s)]
    confidence = from_units(best.before, best.after, bar[best.name], rivals, "channels")
    if best.at_limits and confidence.word == "high":
        confidence = replace(confidence, word="moderate",
                             why=f"its fit ends on the edge of the range searched ({', '.join(best.at_limits)}): "
                                 "the effect as modelled does not meet the data inside its range, so it may stand "
                                 "in for another cause")
    return confidence, intervals


def misfit_alarms(heldout_error: Mapping[str, float], unpaired: Sequence[UnpairedMode],
                  settings: ExcitationDiagnosisSettings, *, without_channel: ChannelLeftOut | None = None,
                  local: Sequence[LocalResonance] = ()) -> tuple[list[str], list[str]]:
    """(alarms, notes): what the baseline leaves systematic, and what is reported without
    alarm, from its held-out E per channel ``heldout_error``, the identified modes it does
    not pair, the resonances identified at one channel alone (``local``: each alarms, as the
    model has no dynamics of its measurement points) and, where the misfit is confined to
    one channel, the baseline calibrated without it. An unpaired identified mode alarms only
    where the held-out FRF within ``mode_band`` of it is misfitted; one the FRF explains is an
    identification artefact (a weak or merged mode), one outside the comparison band is not
    judged."""
    s = settings
    alarms, notes = [], []
    alarms += [f"a resonance at {r.frequency_hz:.2f} Hz identified at {r.channel} alone ({r.share:.0%} of its shape): "
               "a resonance of that measurement point (its mounting, e.g. a resilient bracket, or its cable), not a "
               "mode of the carbody; not calibrated to" for r in local]
    mean = float(np.mean(list(heldout_error.values())))
    if mean > s.noise_alarm:
        worst = sorted(heldout_error.items(), key=lambda kv: -kv[1])
        alarms.append(f"held-out FRF misfit {mean:.1f} x the noise on average "
                      f"(> {s.noise_alarm:g}); worst " + ", ".join(f"{n} {v:.1f}" for n, v in worst[:3]))
        one = confined_channel(heldout_error, s)
        if one is not None:
            line = (f"the misfit is confined to one channel: {one[0]} carries {one[1]:.0%} of the excess over the "
                    "noise, where a change of the structure's modes would show at many points")
            rest = without_channel
            if rest is None:
                line += "; it points at that measurement point (the sensor's mounting or calibration, or a local " \
                        "feature there)"
            elif rest.heldout_error_mean <= s.noise_alarm:
                line += (f"; calibrated without it, the baseline explains the other {rest.channels} channels at "
                         f"{rest.heldout_error_mean:.2f} x the noise: the measurement at {one[0]} (the sensor's "
                         "mounting or calibration, or a local feature there), not the carbody, is what the model "
                         "does not explain")
            else:
                line += (f"; calibrated without it, the baseline still leaves {rest.heldout_error_mean:.1f} x the "
                         f"noise on the other {rest.channels} channels: more than that channel is wrong")
            alarms.append(line)
    for r in unpaired:
        why = "shares its model partner with another identified mode" if r.shares_partner else \
            f"best model partner MAC {r.mac:.2f}, {r.error_pct:+.1f} %"
        head, near = f"identified mode at {r.identified_hz:.2f} Hz not paired by the model ({why})", \
            r.heldout_error_near
        if near is None:
            notes.append(f"{head}, outside the FRF comparison band {s.band[0]:g}-{s.band[1]:g} Hz: not judged")
        elif near <= s.noise_alarm:
            notes.append(f"{head}, but the held-out FRF within {s.mode_band:.0%} of it is explained "
                         f"({near:.2f} x the noise): taken as an identification artefact")
        else:
            alarms.append(f"{head}; held-out error within {s.mode_band:.0%} of it {near:.1f} x the noise")
    return alarms, notes


def _null_words(name: str) -> str:
    """Where extension ``name``'s effect vanishes or its search ends, in words."""
    ext = EXTENSIONS[name]
    parameter, value = ext.null_end
    return f"{parameter} within {ext.null_tol:.0%} of {value:g}"


def _values(parameters: dict, fmt: str) -> str:
    return ", ".join(f"{k} = {v:{fmt}}" if isinstance(v, float) else f"{k} = {v}" for k, v in parameters.items())


def summary_lines(cause: str, best: Hypothesis | None, alarms: list[str], notes: list[str], evidence: Evidence,
                  hypotheses: Sequence[Hypothesis], confidence: Confidence | None = None,
                  intervals: Mapping[str, Confidence] | None = None, detect: Detectability | None = None
                  ) -> list[str]:
    """The diagnosis in words: the cause, why and how sure, the alarms and notes, the
    hypotheses by gain with their intervals, those not named for ending at their null end,
    factors at their bounds."""
    out = []
    intervals = intervals or {}
    if best is not None:
        sure = "" if confidence is None else \
            f"{confidence.interval_words()}; confidence {confidence.word}: {confidence.why}"
        out.append(f"cause: {cause} ({best.description}); held-out FRF error over all channels reduced by "
                   f"{best.gain:.0%} (most on {best.best_channel}, {best.best_channel_reduction:.0%}){sure}")
        out.append("extension parameters: " + _values(best.parameters, ".4g"))
    elif cause == "unexplained":
        out.append("unexplained: the calibrated box model leaves a systematic misfit and no extension in the registry "
                   "reduces the held-out error enough")
    else:
        out.append("none: the calibrated box model explains the held-out FRFs within the noise "
                   f"(mean normalised error {evidence.heldout_error_mean:.2f}) and around every identified mode"
                   + ("" if detect is None else f"; no effect above these sizes: {detect.words()}"))
    out += alarms + notes
    def spread(h: Hypothesis) -> str:
        c = intervals.get(h.name)
        return "" if c is None or c.interval is None else f" ({c.interval[0]:.0%} to {c.interval[1]:.0%})"
    out.append("hypotheses by held-out gain (95 % interval over the channels): " + ", ".join(
        f"{h.name} {h.gain:.0%}{spread(h)}" for h in sorted(hypotheses, key=lambda h: -h.penalised_gain)))
    out += [f"{h.name} not named: its fit ends at its null end ({_null_words(h.name)}; "
            + _values(h.parameters, ".3g") + "); its gain comes from re-adjusting the baseline"
            for h in hypotheses if h.at_null_end and h.gain > 0]
    out += [f"{h.name} not named: its gain {h.parameters['force_gain']:.4g} removes a common level offset of "
            f"{abs(np.log(h.parameters['force_gain'])):.1%}, but the channels' own level offsets scatter by "
            f"{h.level_scatter:.1%} (rms) about it, more than 1/{UNIFORM:g} of it: a level error that differs by "
            "channel is the model's (its masses or modal constants), not the load cell's"
            for h in hypotheses if h.mixed_level and not h.at_null_end and h.gain > 0]
    if evidence.parameters_at_bounds:
        out.append("baseline factors at their bounds: " + ", ".join(evidence.parameters_at_bounds))
    return out
