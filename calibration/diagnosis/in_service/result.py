"""The in-service diagnosis's result: made once by
:func:`~calibration.diagnosis.in_service.diagnose_in_service`, written as JSON by
:meth:`InServiceDiagnosis.to_json` and drawn by :meth:`InServiceDiagnosis.plot`."""
from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path

from ...models.car2d import extras_to_json
from .amplitude import FRICTION
from .baseline import BaselineStart
from .detectability import Detectability
from .evidence import Evidence
from .hypotheses import Hypothesis
from .records import Layout, Statistics
from .response import ResponseFit, SensorModel
from .selection import Finding
from .settings import DiagnosisSettings

FORMAT = "railcal-diagnosis/1"


@dataclass(frozen=True)
class InServiceDiagnosis:
    """What the calibrated 2D car gets wrong on an in-service campaign, and why.

    ``cause`` is an extension's name (:data:`.extensions.EXTENSIONS`), ``"none"`` (nothing
    systematic left) or ``"unexplained"`` (something systematic that no extension explains);
    ``summary`` says why in words. ``best`` is the hypothesis named as the cause (None for
    the other two answers); ``hypotheses`` every one fitted, best evidence first.
    """

    campaign: Path  # the campaign folder
    cause: str
    summary: tuple[str, ...]
    evidence: Evidence
    hypotheses: tuple[Hypothesis, ...]
    best: Hypothesis | None
    baseline: ResponseFit  # the baseline car fitted to the training runs
    start: BaselineStart  # where that fit started (the user's calibration or the priors) and its defaults
    bounds: dict  # baseline parameter -> (low, high) searched
    training_runs: tuple[str, ...]
    heldout_runs: tuple[str, ...]
    settings: DiagnosisSettings
    layout: Layout
    statistics: Statistics  # the band statistics every error and figure is computed from
    detectability: Detectability  # each extension's weakest detectable effect on this campaign
    findings: tuple[Finding, ...] = ()  # causes and properties, in the order found (:mod:`.selection`)
    # each response hypothesis's gain with its 95 % interval (:func:`.confidence.hypothesis_intervals`)
    intervals: dict = field(default_factory=dict)
    extended: ResponseFit | None = None  # the car with every vehicle finding (cause or property) in it

    def model_json(self) -> dict:
        """The extended model as a calibration file's keys: ``model``, ``parameters``,
        ``extras`` (:func:`~calibration.models.car2d.extras_to_json`), the bogie sensors'
        ``sensor_model`` where a finding moved them, ``not_in_model``: the findings on the
        track and wheels, which a vehicle model does not carry, and ``linearised``: friction
        found in the suspension, which the linear model carries as its equivalent damping at
        the training runs' amplitude."""
        fit = self.extended or self.baseline
        out = {"model": "car2d", "parameters": fit.parameters.as_dict(), "extras": extras_to_json(fit.extras)}
        if fit.sensors != SensorModel():
            out["sensor_model"] = {"bogie_dx": fit.sensors.dx, "gyro_gain": fit.sensors.gyro_gain,
                                   **({"floor": fit.sensors.floor_json()} if fit.sensors.floor else {})}
        out["not_in_model"] = [f.name for f in self.findings if f.hypothesis.kind != "response"]
        reference = fit.values.get("amplitude_reference_m_per_s")
        if reference is not None:  # a linear model carries friction as its damping at one amplitude
            out["linearised"] = {"amplitude_dependent_suspension": {
                **{n: fit.values[n] for n in FRICTION}, "reference_rms_velocity_m_per_s": reference,
                "note": "c_s and c_p include the friction's equivalent damping at these rms relative velocities "
                        "(the training runs'); at other amplitudes the linear model does not follow it"}}
        return out

    @property
    def confidence(self) -> str | None:
        """The answer's confidence: the weakest of its causes' words (``high``, ``moderate``,
        ``low``; :mod:`.confidence`); None for ``none`` and ``unexplained``, which carry
        the detectability table and the evidence instead."""
        words = [f.confidence.word for f in self.findings if f.role == "cause"]
        return min(words, key=("low", "moderate", "high").index) if words else None

    def to_json(self) -> dict:
        """The result as JSON values (a new dict on each call): ``format``, ``campaign``,
        ``cause``, ``evidence`` (``summary`` first), ``extension``, ``gain``, ``baseline``,
        ``hypotheses``, ``split``, ``settings``, ``detectability`` ({extension: parameter,
        unit, detectable_beyond (None: not within its range or not observable), observable,
        why}), ``findings`` (each cause and property with its held-out gain, interval and
        confidence), ``confidence`` (:attr:`confidence`) and the extended model as a
        calibration file's keys (:meth:`model_json`), so that the file is one."""
        best, s = self.best, self.settings
        out = {
            "format": FORMAT, "campaign": str(self.campaign), "cause": self.cause,
            "evidence": {"summary": list(self.summary), **self.evidence.to_json()},
            "extension": None if best is None else {"name": best.name, "parameters": best.parameters,
                                                   "model": best.model},
            "gain": None if best is None else {"heldout_error": best.heldout_error, "best_channel": best.best_channel,
                                               "reduction": best.gain},
            "baseline": {"parameters": self.baseline.parameters.as_dict(),
                         "parameters_at_bounds": list(self.baseline.at_bounds),
                         "bounds": {k: list(v) for k, v in self.bounds.items()},
                         "source": self.start.source, "start": self.start.parameters.as_dict(),
                         "defaults": list(self.start.defaults), "widened": list(self.start.widened)},
            "hypotheses": [{**h.to_json(), **self._interval_json(h.name)} for h in self.hypotheses],
            "split": {"training_runs": list(self.training_runs), "heldout_runs": list(self.heldout_runs)},
            "settings": {"min_gain": s.min_gain, "penalty_per_parameter": s.penalty, "max_loss": s.max_loss,
                         "max_systematic_left": s.max_systematic_left},
            "detectability": self.detectability.to_json(),
            "findings": [f.to_json() for f in self.findings],
            "confidence": self.confidence,
            **self.model_json(),
        }
        return copy.deepcopy(out)  # the caller may change it; the result stays as made

    def _interval_json(self, name: str) -> dict:
        c = self.intervals.get(name)
        return {"interval_95": None if c is None or c.interval is None else list(c.interval),
                "heldout_cells": None if c is None else c.units}

    def plot(self, stem: Path) -> list[Path]:
        """Draw the residual PSD before and after the extension (``<stem>_residual_psd.png``)
        and the baseline residual's speed-frequency map (``<stem>_speed_map.png``)."""
        from .plots import plot_diagnosis

        return plot_diagnosis(self, stem)
