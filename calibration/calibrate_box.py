"""Parameter determination of the extended box model (RTRI seed, section 4).

The seed's flow (its Figure 6): particles are stiffness factors of the box model; each is
evaluated by seed eq. 3 with every measured mode paired to the model mode of largest MAC
(eq. 4); 1000 particles, 1000 iterations, stop at 0.5 %. Then railcal goes further: the
CasADi refinement (eigen-equations as constraints) takes the swarm's answer to the
measured frequencies, every figure is re-solved on the full model, and the identifiability
of the factors from the measured frequencies is reported.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from . import checks
from .data.campaign import Campaign, Sensor
from .data.errors import InputError
from .identification.excitation import (ExcitationIdentification, ExcitationIdentifySettings, IdentifiedShapes,
                                        identify_excitation)
from .box_refine import polish_box, refine_box
from .models.box import FactorSet, assemble, factor_set, shinkansen_vehicle
from .models.box.fit import MIN_CARBODY_SHARE, BoxFit, ModeTarget, sensor_operator
from .models.box.rig import point_record
from .models.box.shinkansen import GROUPED_RANGE, ZONED, indefinite_plates, side_end_zone_of
from .optimisers.base import SearchParameter, bounds
from .optimisers.identifiability import identifiability
from .optimisers.pso import PSOSettings, particle_swarm
from .progress import counter
from .signals.modal import mac_matrix
from .swarm_defaults import CAMPAIGN_DONE_PCT, CAMPAIGN_SWARMS

DEFAULT_RANGE = GROUPED_RANGE  # stiffness factors, when the campaign gives no priors
PAPER_STOP_PCT = 0.5  # RTRI seed: stop when the evaluation function reaches 0.5 %


@dataclass(frozen=True)
class BoxCalibration:
    parameters: dict
    fit: list
    max_error_pct: float
    pso: dict
    refinement: dict | None
    reduced_vs_full_pct: list
    identifiability: dict
    search: dict = field(default_factory=dict)
    factor_set: str = "grouped"
    side_end_zone: float = 0.0  # [m] the windowed set's end strips (rebuilding its model needs it)
    order_change: int = 0  # added to every panel order of the model calibrated (negative: coarse)
    sensors: tuple[Sensor, ...] = ()  # the points the target shapes are given at
    exciter: Sensor | None = None  # where the force acted (the FMU's force input)

    def to_json(self, ident: ExcitationIdentification | IdentifiedShapes | None = None) -> dict:
        """The calibration file; with the identification it was fitted to, its modes too
        (the FRF comparison takes their damping)."""
        out = {"model": "box", "method": "pso", "factor_set": self.factor_set, "parameters": self.parameters,
               "fit": self.fit,
               "max_error_pct": self.max_error_pct, "pso": self.pso, "refinement": self.refinement,
               "reduced_vs_full_pct_at_pso_optimum": self.reduced_vs_full_pct,
               "identifiability": self.identifiability, "search": self.search}
        if self.side_end_zone:
            out["side_end_zone_m"] = self.side_end_zone
        if self.order_change:  # a coarse model: whoever rebuilds it from the file must use the same orders
            out["order_change"] = self.order_change
        if self.sensors:
            out["sensors"] = [point_record(s) for s in self.sensors]
        if self.exciter is not None:
            out["exciter"] = point_record(self.exciter)
        if ident is not None:
            out["identified_modes"] = [m.to_json() for m in ident.modes]
        return out


def box_search(priors=None, names=None, factors: FactorSet | None = None) -> tuple[SearchParameter, ...]:
    """Search parameters from campaign priors ({name: Prior}), else each factor's range in
    ``factors`` (default: the grouped set; ``names``: other factors, in the default range)."""
    factors = factor_set(None) if factors is None else factors
    ranges = dict(zip(factors.names, factors.ranges))
    names = names or factors.names
    priors = dict(priors or {})
    unknown = sorted(set(priors) - set(names))
    if unknown:
        which = "the box model" if names != factors.names else f"the {factors.name} factor set"
        raise InputError(f"priors name {', '.join(unknown)}, which {which} does not have (its factors: "
                         f"{', '.join(names)}); give priors for its factors or none", key="priors")
    out = []
    for n in names:
        pr = priors.get(n)
        lo, hi, nom = (pr.low, pr.high, pr.nominal) if pr else (*ranges.get(n, DEFAULT_RANGE), 1.0)
        if not lo > 0:  # a stiffness factor scales a stiffness: zero or less is no structure
            raise InputError(f"a box factor is positive: priors.{n}.low must be above 0, got {lo:g}",
                             key=f"priors.{n}.low")
        out.append(SearchParameter(n, nom, 0.3 * nom, lo, hi, 0.01 * nom))
    indefinite = indefinite_plates({q.name: q.low for q in out}, {q.name: q.high for q in out})
    if indefinite:
        raise InputError("the ranges reach a plate that is not positive definite, where the stiffness has no "
                         "meaning: " + "; ".join(indefinite) + "; raise the cross-direction factor's low or lower "
                         "the lengthwise one's high", key="priors")
    return tuple(out)


def wide_search(search: tuple[SearchParameter, ...]) -> bool:
    """Does the search span a ratio of 16 or more in some factor? Then a swarm moves in the
    factors' logarithms (:class:`SwarmSettings`)."""
    return max(q.high / q.low for q in search) >= 16


def swarm_box(fit: BoxFit, search: tuple[SearchParameter, ...], rng: np.random.Generator, settings: PSOSettings, *,
              log_factors: bool = False, progress=None, desc: str = "particle swarm"):
    """The seed's swarm on ``fit`` (RTRI eq. 3), its basis built at the search's centre and
    adapted as the swarm narrows; with ``log_factors`` the particles move in the factors'
    logarithms (the same centre, a spread of 0.3). ``progress``: a bar of the iterations
    (:func:`calibration.progress.counter`; the swarm may stop before the last at its
    target). Returns (the PSO result, the best factors)."""
    with counter(progress, settings.iterations, f"{desc} ({settings.particles} particles)", unit="it") as bar:
        def tick(it, best):
            bar.set_postfix_str(f"best {best:.3g} %, {fit.rebuilds} bases", refresh=False)
            bar.update()

        fit.rebuild(np.array([q.mean for q in search]))
        if not log_factors:
            res = particle_swarm(fit, search, rng, settings=settings, adapt=fit.adapt, on_iteration=tick)
            return res, res.best
        space = tuple(SearchParameter(q.name, np.log(q.mean), 0.3, np.log(q.low), np.log(q.high), 0.01)
                      for q in search)
        res = particle_swarm(lambda Q: fit(np.exp(np.atleast_2d(Q))), space, rng, settings=settings,
                             adapt=lambda it, best, force=False: fit.adapt(it, np.exp(best), force=force),
                             on_iteration=tick)
        return res, np.exp(res.best)


@dataclass(frozen=True, kw_only=True)
class SwarmSettings:
    """How the particles search.

    pso : the seed's swarm (particles, iterations, its stop [%]).
    seed : of the random generator every swarm draws from.
    swarms : the particles are split into this many independent swarms, run one after the
        other (one: the seed's single swarm); each swarm's best is refined and polished as
        soon as it ends and the lowest full-model error is the answer, the others reported
        beside it.
    done_pct : no further swarm runs once one ends, refined, at or below this error [%] on
        the full model (None, and always without a refinement: ``pso.target``, where a swarm
        itself stops).
    log_factors : the particles move in the factors' logarithms (a box spanning ratios of 16
        or more, where a linear swarm crowds the upper end).
    """

    pso: PSOSettings = PSOSettings(target=PAPER_STOP_PCT)
    seed: int = 0
    swarms: int = 1
    done_pct: float | None = None
    log_factors: bool = False

    def __post_init__(self):
        checks.whole(self, "seed", minimum=0)
        checks.whole(self, "swarms")
        if self.pso.particles // self.swarms < 2:
            raise ValueError(f"SwarmSettings: {self.swarms} swarms of {self.pso.particles} particles: each swarm "
                             "needs 2 or more")
        if self.done_pct is not None and not self.done_pct >= 0:  # inf: the first swarm ends the search
            raise ValueError(f"SwarmSettings.done_pct must be >= 0 (or None), got {self.done_pct!r}")


@dataclass(frozen=True, kw_only=True)
class RefineSettings:
    """What follows each swarm.

    enabled : the CasADi refinement on the reduced model, in rounds judged on the full model.
    rounds : at most this many rounds; they stop early at ``tol_pct`` [%] on the full model.
    polish_steps : then up to this many sequential-LP steps on the full model that keep the
        MAC floor (:func:`calibration.box_refine.polish_box`; each costs one full eigen-solve).
    """

    enabled: bool = True
    rounds: int = 10
    tol_pct: float = 1e-4
    polish_steps: int = 0

    def __post_init__(self):
        checks.whole(self, "rounds")
        checks.whole(self, "polish_steps", minimum=0)
        checks.non_negative(self, "tol_pct")


@dataclass(frozen=True, kw_only=True)
class PairingSettings:
    """Which model modes a target may pair with (:class:`calibration.models.box.fit.BoxFit`):
    at least ``min_carbody_share`` of the mode's kinetic energy in the carbody, and a MAC with
    the target of at least ``min_mac`` for the pairing to count."""

    min_carbody_share: float = MIN_CARBODY_SHARE
    min_mac: float = 0.0

    def __post_init__(self):
        checks.fraction(self, "min_carbody_share", "min_mac", closed=True)


def calibrate_box(targets: tuple[ModeTarget, ...], sensors, search: tuple[SearchParameter, ...], *,
                  swarm: SwarmSettings = SwarmSettings(), refinement: RefineSettings = RefineSettings(),
                  pairing: PairingSettings = PairingSettings(), sigma_f=0.002, model=None,
                  factors: FactorSet | None = None, order_change: int = 0, exciter: Sensor | None = None,
                  progress=None) -> BoxCalibration:
    """The seed's swarm over the box model's stiffness factors, each swarm refined
    (``swarm``, ``refinement``, ``pairing``: the grouped settings).

    ``sensors``: the campaign sensors the target shapes are given at (for the operator);
    ``exciter``: where the test's force acted (recorded with the sensors for the FMU);
    ``search``: one entry per factor of ``factors`` (a named set, default grouped) or, for a
    ``model`` assembled elsewhere, of that model (its file then records the set "custom");
    ``sigma_f``: relative uncertainty of the measured frequencies for the identifiability.
    A set's ``polish_only`` factors stay nominal in the swarm and the refinement (a model
    without them) and join the polish (a model with them); without a polish they stay
    nominal. ``order_change``: added to every panel order of a set's model (negative: a
    coarse, fast model for tests)."""
    settings, seed, swarms = swarm.pso, swarm.seed, swarm.swarms
    refine, refine_rounds, refine_tol_pct = refinement.enabled, refinement.rounds, refinement.tol_pct
    polish_steps, log_factors, done_pct = refinement.polish_steps, swarm.log_factors, swarm.done_pct
    min_carbody_share, min_mac = pairing.min_carbody_share, pairing.min_mac
    if model is not None and factors is not None:
        raise ValueError("give a model or a factor set, not both")
    if model is None:
        factors = factor_set(None) if factors is None else factors
        model = assemble(shinkansen_vehicle(order_increase=order_change, parameters=factors.swarm_parameters))
    set_name = "custom" if factors is None else factors.name
    names = tuple(p.name for p in search)
    expected = model.names if factors is None else factors.names
    if names != expected:
        raise InputError(f"the search must name the model's parameters {expected}, got {names}", key="priors")
    staged = len(names) - len(model.names)  # factors joining only in the polish (without one: nominal)
    fit = BoxFit(model, sensor_operator(model, sensors), targets, min_carbody_share=min_carbody_share,
                 min_mac=min_mac)
    low, high = bounds(search)
    rng = np.random.default_rng(seed)
    each = settings if swarms == 1 else replace(settings, particles=settings.particles // swarms)
    done_pct = settings.target if done_pct is None or not refine else done_pct
    polish_fit = None
    if refine and polish_steps > 0 and staged:  # the set's remaining factors join, nominal: the same error
        polish_model = assemble(shinkansen_vehicle(order_increase=order_change, parameters=factors.parameters))
        polish_fit = BoxFit(polish_model, sensor_operator(polish_model, sensors), targets,
                            min_carbody_share=min_carbody_share, min_mac=min_mac)
    runs = []
    for k in range(swarms):
        tag = f"swarm {k + 1}: " if swarms > 1 else ""
        rebuilds, t0 = fit.rebuilds, time.perf_counter()
        res, best = swarm_box(fit, search[:len(model.names)], rng, each, log_factors=log_factors, progress=progress,
                              desc=f"swarm {k + 1} of {swarms}" if swarms > 1 else "particle swarm")
        run = {"res": res, "best": best, "check": fit.full_check(best), "wall": time.perf_counter() - t0,
               "rebuilds": fit.rebuilds - rebuilds, "p": best, "refinement": None, "fit": fit}
        runs.append(run)
        if refine:
            _refine_swarm_best(run, fit, polish_fit, low, high, names, rounds=refine_rounds,
                               tol_pct=refine_tol_pct, polish_steps=polish_steps, progress=progress, tag=tag)
        end = run["check"]["max_error_pct"] if run["refinement"] is None else run["refinement"]["end_max_error_pct"]
        run["end"] = end
        if progress and swarms > 1:
            progress(f"{tag}ends at {end:.3g} % on the full model"
                     f"{'' if end > done_pct else f' (at or below {done_pct:g} %: no further swarm)'}")
        if end <= done_pct:
            break
    end = [run["end"] for run in runs]
    chosen = runs[int(np.argmin(end))]
    res, check, p, refinement, fit = chosen["res"], chosen["check"], chosen["p"], chosen["refinement"], chosen["fit"]
    wall = sum(run["wall"] for run in runs)
    evaluations = sum(run["res"].evaluations for run in runs)
    pso = {"particles": settings.particles, "iterations": res.iterations, "evaluations": evaluations,
           "wall_s": wall, "evaluations_per_s": evaluations / wall, "basis_rebuilds": sum(r["rebuilds"] for r in runs),
           "best_reduced_pct": res.best_value, "best_full_pct": check["max_error_pct"],
           "reached_stop": res.reached_target, "stop_pct": settings.target, "done_pct": done_pct,
           "factors": list(model.names), "history_pct": [float(v) for v in res.history]}
    if swarms > 1:
        pso["swarms"] = [{"particles": each.particles, "iterations": run["res"].iterations,
                          "evaluations": run["res"].evaluations,
                          "best_full_pct": run["check"]["max_error_pct"], "end_max_error_pct": e,
                          "basis_rebuilds": run["rebuilds"], "wall_s": run["wall"], "chosen": run is chosen,
                          "best": dict(zip(model.names, map(float, run["best"])))}
                         for run, e in zip(runs, end)]
    final = check if refinement is None else fit.full_check(p)  # unrefined: the swarm's best, already checked
    fit.rebuild(p)  # exact eigenpairs at p for the sensitivities
    sigma = np.broadcast_to(np.asarray(sigma_f, float), (len(targets),))
    ident = identifiability(fit, p, tuple(t.label for t in targets), sigma_f=sigma, low=low[:p.size],
                            high=high[:p.size]).to_json()
    rows = [{"label": t.label, "measured_hz": t.frequency_hz, "model_hz": float(final["frequency_hz"][i]),
             "error_pct": float(final["error_pct"][i]), "mac": float(final["mac"][i]),
             "sound": bool(final["sound"][i]),
             "model_mode": int(final["index"][i]) + 1} for i, t in enumerate(targets)]
    p = np.r_[p, np.ones(len(names) - p.size)]  # factors never freed: nominal
    return BoxCalibration(dict(zip(names, map(float, p))), rows, float(final["max_error_pct"]), pso, refinement,
                          [float(x) for x in check["reduced_vs_full_pct"]], ident,
                          {q.name: [q.low, q.high] for q in search}, set_name,
                          0.0 if factors is None else factors.side_end_zone,
                          order_change if factors is not None else 0, tuple(sensors), exciter)


def _refine_swarm_best(run: dict, fit: BoxFit, polish_fit: BoxFit | None, low, high, names, *, rounds: int,
                       polish_steps: int, progress, tag: str, tol_pct: float = 1e-4) -> None:
    """One swarm's best, refined on the reduced model (CasADi) and, with ``polish_steps``,
    polished on the full model: on ``fit``, or on ``polish_fit`` where the set stages
    factors for the polish (``names`` beyond ``fit``'s, joining nominal); sets the run's
    ``p``, ``refinement`` and ``fit``."""
    d = len(fit.model.names)
    if progress:
        progress(f"{tag}refining on the reduced model in rounds, checked on the full model (CasADi/IPOPT)")
    r = refine_box(fit, run["best"], low[:d], high[:d], rounds=rounds, tol_pct=tol_pct)
    refinement = {"rounds": r.rounds, "statuses": list(r.statuses), "start_max_error_pct": r.start_max_error_pct,
                  "end_max_error_pct": r.max_error_pct, "improved": r.max_error_pct < r.start_max_error_pct}
    p = r.parameters
    if polish_steps > 0:
        if polish_fit is not None:
            run["fit"] = polish_fit
            p = np.r_[p, np.ones(len(names) - d)]
            polish_fit.rebuild(p)
        if progress:
            progress(f"polishing {len(names)} factors on the full model "
                     f"(sequential LP{', MAC floor kept' if fit.min_mac > 0 else ''})")
        pol = polish_box(run["fit"], p, low, high, steps=polish_steps, progress=progress)
        refinement["polish"] = {"steps": pol.rounds, "kept": pol.statuses.count("kept"),
                                "statuses": list(pol.statuses), "factors": list(names),
                                "start_max_error_pct": pol.start_max_error_pct,
                                "end_max_error_pct": pol.max_error_pct}
        refinement["end_max_error_pct"] = pol.max_error_pct
        refinement["improved"] = pol.max_error_pct < r.start_max_error_pct
        p = pol.parameters
    run["p"], run["refinement"] = p, refinement


def targets_from_identification(ident: ExcitationIdentification, *, band: bool = False) -> tuple[ModeTarget, ...]:
    """The identified modes as targets; with ``band`` each carries its half-power band
    (its damping ratio), so that a mode identified at a close pair of model modes is
    compared with the pair's span (:func:`calibration.models.box.fit.band_pairing`).

    With ``band``, identified modes of which one lies inside the other's half-power band
    and whose shapes are alike (MAC >= ``SPAN_MIN_MAC``) are one target: a single exciter
    does not separate modes that overlap so, and what it reports as two is two mixtures of
    the same pair, split by its estimation error (a close pair 0.1 % apart came out as two
    modes 0.5 % apart, each with both shapes in its span, and no model met both: 0.21 %
    left). Unlike shapes in one band are two modes, resolved by their shapes. The target is
    the span of the group: its mean frequency, the shape that best represents the group's
    shapes (their first singular vector) and a band reaching every member's band."""
    modes = ident.modes
    if not band:
        return tuple(ModeTarget(m.label, m.frequency_hz, m.shape) for m in modes)
    groups: list[list] = []
    for m in sorted(modes, key=lambda m: m.frequency_hz):
        last = groups[-1][-1] if groups else None
        if last is not None and _overlap(last, m):
            groups[-1].append(m)
        else:
            groups.append([m])
    targets = []
    for g in groups:
        if len(g) == 1:
            targets.append(ModeTarget(g[0].label, g[0].frequency_hz, g[0].shape, g[0].damping_ratio or 0.0))
            continue
        f = np.array([m.frequency_hz for m in g])
        centre = float(np.mean(f))
        reach = max(abs(m.frequency_hz - centre) + (m.damping_ratio or 0.0) * m.frequency_hz for m in g)
        shapes = np.column_stack([m.shape / np.linalg.norm(m.shape) for m in g])
        u = np.linalg.svd(shapes, full_matrices=False)[0][:, 0]
        targets.append(ModeTarget("+".join(m.label for m in g), centre, u, reach / centre))
    return tuple(targets)


#: targets_from_identification: two identified modes in one band are one close pair's
#: mixtures only if their shapes are alike, MAC at least this (more than half of one along
#: the other). The demo's modes 4 and 5 (14.13 and 14.35 Hz, each inside the other's band,
#: MAC 0.001) are two true modes identified within 0.03 %; the test campaign's 13.235 and
#: 13.307 Hz (MAC 0.68) are one pair 0.1 % apart.
SPAN_MIN_MAC = 0.5


def _overlap(a, b) -> bool:
    """Two identified modes, one inside the other's half-power band, with alike shapes."""
    gap = abs(a.frequency_hz - b.frequency_hz)
    inside = gap < max((a.damping_ratio or 0.0) * a.frequency_hz, (b.damping_ratio or 0.0) * b.frequency_hz)
    return bool(inside and mac_matrix(a.shape[:, None], b.shape[:, None])[0, 0] >= SPAN_MIN_MAC)


def campaign_factor_set(name: str | None, campaign: Campaign) -> FactorSet:
    """The factor set ``name`` (None: grouped) for ``campaign``: the windowed and orthotropic
    sets' end strips beyond the side walls' windowed middle, from its [vehicle]
    windowed_length (InputError naming the key without it); ValueError for an unknown set."""
    zone = None
    if name in ZONED:
        windows = campaign.meta.geometry.get("windowed_length")
        if windows is None:
            raise InputError(f"the {name} factor set needs the length of the side walls' windowed middle: "
                             "[vehicle] windowed_length = METRES", path=campaign.root / "campaign.toml",
                             key="vehicle.windowed_length")
        zone = side_end_zone_of(windows)
        if not zone > 0:
            raise InputError(f"windowed_length {windows:g} m leaves no side wall beyond the windows on the box model's "
                             f"{windows + 2 * zone:g} m carbody", path=campaign.root / "campaign.toml",
                             key="vehicle.windowed_length")
    return factor_set(name, side_end_zone=zone)


def calibrate_box_campaign(campaign: Campaign, *,
                           swarm: SwarmSettings = SwarmSettings(swarms=CAMPAIGN_SWARMS, done_pct=CAMPAIGN_DONE_PCT),
                           refinement: RefineSettings = RefineSettings(),
                           identify: ExcitationIdentifySettings = ExcitationIdentifySettings(),
                           order_change: int = 0, identified: IdentifiedShapes | None = None,
                           factors: FactorSet | None = None,
                           progress=None) -> tuple[BoxCalibration, ExcitationIdentification | IdentifiedShapes]:
    """Identify a stationary excitation campaign's modes and calibrate the box model to them
    (:func:`calibrate_box`; by default in CAMPAIGN_SWARMS swarms, done at CAMPAIGN_DONE_PCT);
    ``order_change``: added to every panel order of the model (negative: a coarse, fast model,
    e.g. for a campaign synthesised on the same one); ``identified``: the campaign's
    identification made before (an identification file read back), not made again;
    ``factors``: the factor set searched (default grouped), each factor within the campaign's
    prior for it, else within the set's own range; priors naming a factor the set does not
    have are refused."""
    if campaign.meta.kind != "stationary_excitation":
        raise InputError(f"the box model is calibrated from stationary excitation tests, not {campaign.meta.kind}",
                         path=campaign.root / "campaign.toml", key="kind")
    factors = factor_set(None) if factors is None else factors
    try:
        search = box_search(campaign.meta.priors, factors=factors)
    except InputError as e:
        raise e.located(campaign.root / "campaign.toml") from None
    ident = identify_excitation(campaign, identify) if identified is None else identified
    if not ident.modes:
        raise InputError("no mode identified in the analysis band; nothing to calibrate to",
                         path=campaign.root / "runs")
    meta = campaign.meta
    sensors = tuple(meta.sensor(n) for n in ident.sensors)
    exciter = meta.exciter()
    if progress:
        progress(f"identified {len(ident.modes)} modes; particle swarm on the box model")
    return calibrate_box(targets_from_identification(ident, band=True), sensors, search, swarm=swarm, factors=factors,
                         refinement=refinement, order_change=order_change, exciter=exciter, progress=progress), ident
