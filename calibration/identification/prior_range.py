"""Where the campaign's priors allow each rigid-body mode to be, and identified modes checked
against it: a fitted pole far outside is another resonance (an air-spring reservoir, a
carbody bending, equipment), reported undetermined with its reason rather than as the
mode."""
from __future__ import annotations

import itertools

from ..data.campaign import Campaign
from ..models.car2d import build_car, frequencies_by_label, undamped_modes
from ..models.parameters import CarParameters

#: the parameters that set the rigid-body frequencies; the check needs a prior for each
FREQUENCY_PARAMETERS = ("m_v", "J_v", "m_b", "J_b", "k_p", "k_s")
#: how far beyond the priors' range a mode may lie: the car model is linear and rigid, a
#: vehicle's air springs and flexible carbody move its modes by some per cent, not by factors
MARGIN = 1.25


def prior_frequency_ranges(campaign: Campaign, prior: CarParameters) -> dict[str, tuple[float, float]]:
    """label -> (low, high) [Hz]: each rigid-body frequency of the 2D car over the corners of
    the campaign's prior box, widened by :data:`MARGIN`; empty when any of
    :data:`FREQUENCY_PARAMETERS` has no prior (the range would rest on a default car)."""
    priors = campaign.meta.priors
    if not all(n in priors for n in FREQUENCY_PARAMETERS):
        return {}
    lo: dict[str, float] = {}
    hi: dict[str, float] = {}
    for corner in itertools.product(*((priors[n].low, priors[n].high) for n in FREQUENCY_PARAMETERS)):
        f = frequencies_by_label(undamped_modes(build_car(prior.replace(**dict(zip(FREQUENCY_PARAMETERS, corner))))))
        for label, v in f.items():
            lo[label], hi[label] = min(lo.get(label, v), v), max(hi.get(label, v), v)
    return {label: (lo[label] / MARGIN, hi[label] * MARGIN) for label in lo}


def outside(label: str, frequency_hz: float, ranges: dict[str, tuple[float, float]]) -> str | None:
    """Why ``frequency_hz`` cannot be mode ``label`` (None when it can, or when there is no range)."""
    if label not in ranges:
        return None
    a, b = ranges[label]
    if a <= frequency_hz <= b:
        return None
    return (f"the fitted {frequency_hz:.3g} Hz lies outside {a:.3g}-{b:.3g} Hz, where the campaign's priors put "
            f"{label} (with a {MARGIN - 1:.0%} margin): another resonance, not taken as this mode")
