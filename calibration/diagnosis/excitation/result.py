"""The result of an excitation-test diagnosis: one object, made once, that the JSON file and
the figures are read from."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ...data.outputs import RESULT_FORMATS
from ..confidence import Confidence
from ..limits import Detectability
from .baseline import SwarmRecord
from .context import KIND
from .data import MeasuredFRF
from .decision import Hypothesis
from .evidence import Evidence, ModeComparison
from .settings import ExcitationDiagnosisSettings


@dataclass(frozen=True)
class Restart:
    """The baseline re-fitted from a gaining hypothesis's factors (without its extension):
    a hypothesis may gain only because its fit found a better basin for the baseline's own
    factors.

    source : the hypothesis whose factors started it
    start_error_mean : the start's mean training E over channels [-]
    training_error_mean : the re-fit's; None when not run (the start fitted no better)
    kept : whether the re-fit replaced the baseline
    """

    source: str
    start_error_mean: float
    training_error_mean: float | None
    kept: bool

    def to_json(self) -> dict:
        out = {"from": self.source, "start_error_mean": self.start_error_mean}
        if self.training_error_mean is not None:
            out["training_error_mean"] = self.training_error_mean
        out["kept"] = self.kept
        return out


@dataclass(frozen=True, eq=False)
class BaselineRecord:
    """The baseline as the result reports it.

    parameters : its box factors by name [-]
    bounds : each factor's (low, high) from the campaign's priors [-]
    modal_damping : damping ratio of each elastic mode in the band, by frequency [-]
    """

    parameters: dict
    swarm: SwarmRecord
    restarts: tuple[Restart, ...]
    bounds: dict
    modal_damping: dict

    def to_json(self) -> dict:
        return {"model": "box", "parameters": dict(self.parameters),
                "swarm": {**self.swarm.to_json(), "restarts": [r.to_json() for r in self.restarts]},
                "bounds": {n: [float(a), float(b)] for n, (a, b) in self.bounds.items()},
                "modal_damping": dict(self.modal_damping)}


@dataclass(frozen=True, eq=False)
class ExcitationDiagnosis:
    """What the calibrated box model gets wrong on an excitation test, the cause, the
    extended model and its held-out gain.

    campaign : the campaign's root directory
    cause : ``"none"``, a name of :data:`.extensions.EXTENSIONS`, or ``"unexplained"``
    summary : the diagnosis in words, one line each
    measured : the held-out part's H1 in the comparison band (the figures' measurement)
    evidence : what the baseline leaves (its held-out misfit and modes)
    baseline : the baseline's factors, swarm and damping
    hypotheses : every extension fitted and judged, in registry order
    extension : the hypothesis named as the cause (None for ``none`` and ``unexplained``)
    extension_modes : its modes against the identified ones (None without a cause)
    training_runs, heldout_runs : the split, as run labels
    basis_modes : full-model modes every reduced basis kept; model_dof : the full model's DOFs
    wall_s : [s] wall time of the diagnosis
    certainty : the cause's held-out gain with its 95 % interval over the channels and its
        word (None for ``none`` and ``unexplained``)
    intervals : each hypothesis's gain with its interval, by name
    detectability : each extension's weakest effect this campaign could have named
    model_keys : the calibration keys describing the model beside its factors
        (:func:`.diagnose.extended_model_keys`), which the extended model's file repeats
    """

    campaign: str
    cause: str
    summary: tuple[str, ...]
    measured: MeasuredFRF
    evidence: Evidence
    baseline: BaselineRecord
    hypotheses: tuple[Hypothesis, ...]
    extension: Hypothesis | None
    extension_modes: ModeComparison | None
    training_runs: tuple[str, ...]
    heldout_runs: tuple[str, ...]
    settings: ExcitationDiagnosisSettings
    basis_modes: int
    model_dof: int
    wall_s: float
    certainty: Confidence | None = None
    intervals: dict = field(default_factory=dict)
    detectability: Detectability | None = None
    model_keys: dict = field(default_factory=dict)

    @property
    def sensors(self) -> tuple[str, ...]:
        return self.evidence.sensors

    @property
    def confidence(self) -> str | None:
        """The cause's confidence word (``high``, ``moderate``, ``low``); None for ``none``
        and ``unexplained``."""
        return None if self.certainty is None else self.certainty.word

    def to_json(self) -> dict:
        """The diagnosis file's content (``railcal-diagnosis/1``), without the figures' paths;
        with a cause, also the extended model as a box calibration file's keys (``model``,
        ``parameters``, :attr:`model_keys`; ``extension`` is read as its addition:
        :mod:`calibration.models.box.extended`), so that the file is one."""
        s, best = self.settings, self.extension
        model = {} if best is None else {"model": "box", "parameters": dict(best.factors), **self.model_keys}
        return {**model,
            "format": RESULT_FORMATS["diagnosis"], "campaign": self.campaign, "kind": KIND, "cause": self.cause,
            "evidence": {"summary": list(self.summary), **self.evidence.to_json()},
            "extension": None if best is None else {
                "name": best.name, "parameters": dict(best.parameters),
                "model": {"model": "box", "parameters": dict(best.factors), best.name: dict(best.parameters)}},
            "gain": None if best is None else {"heldout_error": best.heldout_error_json(),
                                               "best_channel": best.best_channel, "reduction": best.gain,
                                               **({} if self.certainty is None else
                                                  {k: v for k, v in self.certainty.to_json().items()
                                                   if k != "gain"})},
            "confidence": self.confidence,
            "detectability": None if self.detectability is None else self.detectability.to_json(),
            "baseline": self.baseline.to_json(),
            "hypotheses": [{**h.to_json(), **self._interval_json(h.name)} for h in self.hypotheses],
            "split": {"training_runs": list(self.training_runs), "heldout_runs": list(self.heldout_runs),
                      "measure": f"normalised FRF error over {s.band[0]:g}-{s.band[1]:g} Hz per channel (1 = noise)"},
            "settings": {"min_gain": s.min_gain, "penalty_per_parameter": s.penalty, "max_loss": s.max_loss,
                         "noise_alarm": s.noise_alarm, "mode_band": s.mode_band, "band_hz": list(s.band),
                         "floor": s.floor,
                         "swarm": {"particles": s.pso.particles, "iterations": s.pso.iterations,
                                   "stop_pct": s.pso.target},
                         "basis": {"below_hz": s.basis_hz, "modes": self.basis_modes,
                                   "derivative_modes": s.derivative_modes, "extra": s.basis_extra},
                         "model_dof": self.model_dof},
            "wall_s": self.wall_s,
        }

    def _interval_json(self, name: str) -> dict:
        c = self.intervals.get(name)
        return {"interval_95": None if c is None or c.interval is None else list(c.interval),
                "heldout_channels": None if c is None else c.units}

    def plot(self, stem) -> list[Path]:
        """Write ``<stem>_frf.png`` (held-out FRFs measured, of the baseline and of the
        extended model, on the channels the baseline misses most) and ``<stem>_mac.png``
        (MAC of the identified modes against the model's); returns their paths."""
        from .plots import plot_excitation_diagnosis

        return plot_excitation_diagnosis(self, stem)
