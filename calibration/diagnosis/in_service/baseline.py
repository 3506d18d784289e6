"""Where the in-service diagnosis's baseline starts, and how far its fit may go.

The baseline is the user's model when a calibration is given (its parameters, damping
included), else the campaign's priors. A parameter that neither gives comes from the
seed's intercity trailer car and is listed as a default, so that the summary says so; a
campaign with no priors and no calibration is refused rather than silently diagnosed
against the seed's car.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from ...data.campaign import Campaign
from ...data.errors import CampaignError, InputError
from ...models.parameters import CAR_PARAMETER_SPECS, CarParameters, ParameterError
from ...identification.in_service import prior_parameters
from ...models.vehicles import INTERCITY_TRAILER
from .response import FIT_NAMES

#: where a parameter missing from the calibration and the priors comes from (prior_parameters' base)
DEFAULT_CAR = INTERCITY_TRAILER
DEFAULT_CAR_NAME = "the seed's intercity trailer car"


@dataclass(frozen=True)
class BaselineStart:
    """The car the baseline fit starts from, the box it searches ({name: (low, high)}),
    where it came from in words, and which parameters are the built-in defaults."""

    parameters: CarParameters
    bounds: dict[str, tuple[float, float]]
    source: str
    defaults: tuple[str, ...]
    widened: tuple[str, ...] = ()  # calibrated values outside the campaign's prior range: the box holds them

    def describe(self) -> list[str]:
        """The summary's lines on the baseline."""
        lines = [f"baseline: {self.source}"]
        if self.defaults:
            values = ", ".join(f"{n} = {getattr(self.parameters, n):.4g} {CAR_PARAMETER_SPECS[n].unit}"
                               for n in self.defaults)
            lines.append(f"baseline defaults (neither the calibration nor the campaign's priors give them; "
                         f"from {DEFAULT_CAR_NAME}): {values}")
        if self.widened:
            lines.append("the calibration lies outside the campaign's prior range of " + ", ".join(self.widened)
                         + "; the search box was widened to hold it")
        return lines

    def to_json(self) -> dict:
        return {"source": self.source, "start": self.parameters.as_dict(), "defaults": list(self.defaults),
                "widened": list(self.widened), "bounds": {k: list(v) for k, v in self.bounds.items()}}


def baseline_start(campaign: Campaign, spread: float, calibration: Mapping | None = None,
                   calibration_path: Path | None = None) -> BaselineStart:
    """The baseline of ``campaign``'s diagnosis.

    With ``calibration`` (a car2d calibration file's content): its parameters are the
    start; each fitted parameter searches the campaign's prior range when there is one,
    else its calibrated value times or divided by ``spread``. Without: the priors'
    nominals are the start and their ranges the box; the vehicle geometry comes from the
    campaign. Raises CampaignError when the campaign has no priors and no calibration is
    given, InputError when the calibration is not a car's."""
    priors = campaign.meta.priors
    where = f"calibration {calibration_path}" if calibration_path else "the calibration"
    if calibration is not None:
        if calibration.get("model", "car2d") != "car2d":
            raise InputError(f"the in-service diagnosis needs a car2d calibration; {where} is of model "
                             f"{calibration.get('model')!r}", path=calibration_path, key="model")
        given = calibration.get("parameters")
        if not isinstance(given, Mapping):
            raise InputError(f"{where} has no parameters table", path=calibration_path, key="parameters")
        try:
            start = CarParameters.from_mapping({k: v for k, v in given.items() if k in CAR_PARAMETER_SPECS},
                                               base=DEFAULT_CAR)
        except ParameterError as e:
            raise InputError(str(e), path=calibration_path, key="parameters") from None
        defaults = tuple(n for n in CAR_PARAMETER_SPECS if n not in given)
        source = f"{where} (its parameters, damping included, are the start)"
    else:
        usable = {k: p for k, p in priors.items() if k in CAR_PARAMETER_SPECS}
        if not usable:
            raise CampaignError("the diagnosis needs a baseline car: this campaign has no priors (campaign.toml "
                                "[priors.*]) and no calibration was given (--calibration FILE from railcal "
                                "calibrate)", path=campaign.root, key="priors")
        start = prior_parameters(campaign)  # the priors' nominals and the geometry over DEFAULT_CAR
        given = set(usable) | {n for n, key in (("L_v", "bogie_semi_spacing"), ("L_b", "semi_wheelbase"))
                               if key in campaign.meta.geometry}
        defaults = tuple(n for n in CAR_PARAMETER_SPECS if n not in given)
        source = "the campaign's priors (their nominals are the start, their ranges the search box)"
    bounds, widened = {}, []
    for n in FIT_NAMES:
        if n in priors:
            bounds[n] = (priors[n].low, priors[n].high)
        else:
            v = getattr(start, n)
            bounds[n] = (v / spread, v * spread)
        lo, hi = bounds[n]
        v = getattr(start, n)
        if not lo <= v <= hi:
            bounds[n] = (min(lo, v), max(hi, v))
            widened.append(n)
    return BaselineStart(start, bounds, source, defaults, tuple(widened))
