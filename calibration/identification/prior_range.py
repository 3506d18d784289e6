"""Where the campaign's priors allow each rigid-body mode to be, and identified modes checked
against it: a fitted pole far outside, in frequency or in damping, is another resonance (an
air-spring reservoir, a carbody bending, equipment, the track), reported undetermined with its
reason rather than as the mode."""
from __future__ import annotations

import itertools

from ..data.campaign import Campaign
from ..models.car2d import build_car, damped_modes, frequencies_by_label, undamped_modes
from ..models.parameters import CarParameters

#: the parameters that set the rigid-body frequencies; the check needs a prior for each
FREQUENCY_PARAMETERS = ("m_v", "J_v", "m_b", "J_b", "k_p", "k_s")
#: how far beyond the priors' range a mode may lie: the car model is linear and rigid, a
#: vehicle's air springs and flexible carbody move its modes by some per cent, not by factors
MARGIN = 1.25
#: the dampers that set the rigid-body modes' damping ratios, with FREQUENCY_PARAMETERS
DAMPING_PARAMETERS = ("c_p", "c_s")
#: how far beyond the priors' range a damping ratio may lie: a vehicle's dampers are nonlinear
#: (bi-linear primary dampers, air-spring orifices) and its effective damping moves with the
#: amplitude by tens of per cent, not by factors
DAMPING_MARGIN = 2.0


def _over_corners(campaign: Campaign, prior: CarParameters, names: tuple[str, ...], values):
    """(low, high) per label of ``values(car)`` ((label, value) pairs) over the corners of the
    campaign's prior box in ``names``; None when any of them has no prior (a range would rest
    on a default car)."""
    priors = campaign.meta.priors
    if not all(n in priors for n in names):
        return None
    lo: dict[str, float] = {}
    hi: dict[str, float] = {}
    for corner in itertools.product(*((priors[n].low, priors[n].high) for n in names)):
        for label, v in values(build_car(prior.replace(**dict(zip(names, corner))))):
            lo[label], hi[label] = min(lo.get(label, v), v), max(hi.get(label, v), v)
    return lo, hi


def prior_frequency_ranges(campaign: Campaign, prior: CarParameters) -> dict[str, tuple[float, float]]:
    """label -> (low, high) [Hz]: each rigid-body frequency of the 2D car over the corners of
    the campaign's prior box, widened by :data:`MARGIN`; empty when any of
    :data:`FREQUENCY_PARAMETERS` has no prior."""
    found = _over_corners(campaign, prior, FREQUENCY_PARAMETERS,
                          lambda asm: frequencies_by_label(undamped_modes(asm)).items())
    if found is None:
        return {}
    lo, hi = found
    return {label: (lo[label] / MARGIN, hi[label] * MARGIN) for label in lo}


def _missed(label: str, value: float | None, ranges: dict[str, tuple[float, float]]) -> tuple[float, float] | None:
    """The range of ``label`` when ``value`` lies outside it (None: inside, no range or no value)."""
    if value is None or label not in ranges or ranges[label][0] <= value <= ranges[label][1]:
        return None
    return ranges[label]


def outside(label: str, frequency_hz: float, ranges: dict[str, tuple[float, float]]) -> str | None:
    """Why ``frequency_hz`` cannot be mode ``label`` (None when it can, or when there is no range)."""
    if (missed := _missed(label, frequency_hz, ranges)) is None:
        return None
    a, b = missed
    return (f"the fitted {frequency_hz:.3g} Hz lies outside {a:.3g}-{b:.3g} Hz, where the campaign's priors put "
            f"{label} (with a {MARGIN - 1:.0%} margin): another resonance, not taken as this mode")


def prior_damping_ranges(campaign: Campaign, prior: CarParameters) -> dict[str, tuple[float, float]]:
    """label -> (low, high): each rigid-body mode's damping ratio over the corners of the
    campaign's prior box (both members of a bogie pair), widened by the factor
    :data:`DAMPING_MARGIN`; empty without a prior for each of :data:`FREQUENCY_PARAMETERS`
    and :data:`DAMPING_PARAMETERS`."""
    found = _over_corners(campaign, prior, FREQUENCY_PARAMETERS + DAMPING_PARAMETERS,
                          lambda asm: [(m.label, m.damping_ratio) for m in damped_modes(asm)
                                       if m.damping_ratio is not None])
    if found is None:
        return {}
    lo, hi = found
    return {label: (lo[label] / DAMPING_MARGIN, min(hi[label] * DAMPING_MARGIN, 1.0)) for label in lo}


def damping_outside(label: str, damping_ratio: float | None, ranges: dict[str, tuple[float, float]]) -> str | None:
    """Why a pole of ``damping_ratio`` cannot be mode ``label`` (None when it can, or when
    there is no range or no ratio)."""
    if (missed := _missed(label, damping_ratio, ranges)) is None:
        return None
    a, b = missed
    return (f"the fitted pole's damping ratio {damping_ratio:.3g} lies outside {a:.3g}-{b:.3g}, where the campaign's "
            f"priors put {label}'s (within a factor {DAMPING_MARGIN:g}): another resonance, not taken as this mode")
