"""What every fit of one diagnosis reads: the campaign split and identified, the measured
FRFs of both parts, the full model's operators and the factors' bounds."""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ...calibrate_box import box_search, wide_search
from ...data.campaign import Campaign
from ...data.errors import CampaignError, InputError
from ...identification.excitation import ExcitationIdentification, identify_excitation
from ...models.box import BoxModel, FactorSet, assemble
from ...models.box.assembly import carbody_mass
from ...models.box.shinkansen import shinkansen_model, shinkansen_vehicle
from ...optimisers.base import SearchParameter
from .basis import Operators, modes_below
from .data import MeasuredFRF, Part, measured_frf, split_campaign
from .settings import ExcitationDiagnosisSettings

#: the campaign kind this diagnosis reads (fixed by the campaign format, docs/campaign-format.md)
KIND = "stationary_excitation"


@dataclass(frozen=True, eq=False)
class Context:
    """One diagnosis's fixed inputs (the training part's identification and FRFs are what
    every fit is fitted to; the held-out ones are used once, to judge)."""

    campaign: Campaign
    settings: ExcitationDiagnosisSettings
    ops: Operators
    train: Part
    test: Part
    ident: ExcitationIdentification  # of the training part
    ident_test: ExcitationIdentification
    meas: MeasuredFRF  # training FRFs in the band
    meas_test: MeasuredFRF
    low: np.ndarray  # factor bounds (priors)
    high: np.ndarray
    nominal: np.ndarray  # the priors' means within the bounds: the nominal factors
    default_zeta: float  # median identified damping ratio
    carbody_mass: float  # [kg]
    say: Callable[[str], None]
    n_modes: int  # full-model modes kept in every reduced basis (those below settings.basis_hz)
    search: tuple[SearchParameter, ...]  # each factor's prior (or its set's range), as the swarms search it
    factors: FactorSet | None  # the factor set the model was assembled from (None: a model given as such)
    start: np.ndarray | None = None  # a calibration's factors, where the baseline starts instead of a swarm
    start_fit_pct: float | None = None  # that calibration's largest modal frequency error [%]
    #: reduced models one stage builds and a later one reuses (e.g. the softening's per-panel
    #: bases, which the detectability evaluates again), keyed by what they were built at
    memo: dict = field(default_factory=dict, repr=False)

    @property
    def log_factors(self) -> bool:
        """Do the swarms move in the factors' logarithms (:func:`wide_search`)?"""
        return wide_search(self.search)

    @property
    def model(self) -> BoxModel:
        return self.ops.model

    @property
    def names(self) -> tuple[str, ...]:
        return self.ops.model.names

    @property
    def sensors(self) -> tuple[str, ...]:
        return self.ident.sensors


def build_context(campaign: Campaign, settings: ExcitationDiagnosisSettings, model: BoxModel | None, say,
                  without: tuple[str, ...] = (), factors: FactorSet | None = None,
                  start: Mapping[str, float] | None = None, start_fit_pct: float | None = None) -> Context:
    """Check the campaign (kind, excitation, priors), split it, identify both parts and
    build the operators; ``without``: channels left out; ``factors``: the factor set of the
    model (assembled from it when ``model`` is None), whose ranges bound the factors the
    campaign gives no prior for. Bad input raises :class:`InputError` naming the
    campaign.toml key; a training part without modes, :class:`CampaignError`. ``start``: a
    calibration's factors by name (those it lacks nominal), clipped into the bounds, and
    ``start_fit_pct`` its modal fit."""
    meta = campaign.meta
    toml = campaign.root / "campaign.toml"
    if meta.kind != KIND:
        raise InputError(f"diagnose_excitation reads {KIND} campaigns, not {meta.kind}", path=toml, key="kind")
    if meta.excitation is None:
        raise InputError(f"a {KIND} campaign needs [excitation] sensor = ...", path=toml, key="excitation")
    if model is None:
        model = shinkansen_model() if factors is None else assemble(shinkansen_vehicle(parameters=factors.parameters))
    try:  # a set's own factors and ranges, else the model's factors in the default ranges
        search = box_search(meta.priors, None if factors is not None else model.names, factors=factors)
    except InputError as e:
        raise e.located(toml) from None
    if tuple(q.name for q in search) != model.names:
        raise ValueError(f"the factor set {factors.name} is not the model's ({', '.join(model.names)})")
    train, test = split_campaign(campaign, without)
    ident = identify_excitation(train, settings.identify)
    ident_test = identify_excitation(test, settings.identify)
    if not ident.modes:
        raise CampaignError(f"no mode identified in {settings.identify.band} Hz of the training part "
                            f"({', '.join(train.label)}); nothing to calibrate to", path=campaign.root / "runs")
    meas, meas_test = measured_frf(ident.frf, settings.band), measured_frf(ident_test.frf, settings.band)
    if meas.frequency.size < 20:
        raise InputError(f"the comparison band {settings.band} Hz holds {meas.frequency.size} spectral lines; "
                         "need at least 20", path=toml, key="sampling.rate")
    sensors = tuple(meta.sensor(n) for n in ident.sensors)
    exciter = meta.exciter()
    try:
        ops = Operators.build(model, sensors, exciter)
    except ValueError as exc:
        raise InputError(f"{exc}", path=toml, key="sensors") from None
    low = np.array([q.low for q in search])
    high = np.array([q.high for q in search])
    zetas = [m.damping_ratio for m in ident.modes if m.damping_ratio]
    default = float(np.clip(np.median(zetas), *settings.damping_range)) if zetas else 0.02
    p_nom = np.clip([q.mean for q in search], low, high)
    n_modes = modes_below(model, p_nom, settings.basis_hz)
    say(f"training {', '.join(train.label)}: {len(ident.modes)} modes; held out {', '.join(test.label)}; "
        f"reduced bases keep the model's {n_modes} modes below {settings.basis_hz:g} Hz")
    return Context(campaign, settings, ops, train, test, ident, ident_test, meas, meas_test, low, high, p_nom, default,
                   carbody_mass(model), say, n_modes, search, factors,
                   None if start is None else np.clip([float(start.get(n, 1.0)) for n in model.names],
                                                      low * (1 + 1e-6), high * (1 - 1e-6)),
                   start_fit_pct)
