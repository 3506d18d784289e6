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
from dataclasses import dataclass, field

import numpy as np

from .data.campaign import Campaign
from .data.errors import InputError
from .identification.excitation import ShakerIdentification, ShakerSettings, identify_excitation
from .models.box import SEARCH_PARAMETERS, assemble, shinkansen_vehicle
from .models.box.fit import BoxFit, ModeTarget, polish_box, refine_box, sensor_operator
from .optimisers.base import SearchParameter, bounds
from .optimisers.identifiability import identifiability
from .optimisers.pso import PSOSettings, particle_swarm

DEFAULT_RANGE = (0.5, 2.0)  # stiffness factors, when the campaign gives no priors
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

    def to_json(self, ident: ShakerIdentification | None = None) -> dict:
        """The calibration file; with the identification it was fitted to, its modes too
        (the FRF comparison takes their damping)."""
        out = {"model": "box", "method": "pso", "parameters": self.parameters, "fit": self.fit,
               "max_error_pct": self.max_error_pct, "pso": self.pso, "refinement": self.refinement,
               "reduced_vs_full_pct_at_pso_optimum": self.reduced_vs_full_pct,
               "identifiability": self.identifiability, "search": self.search}
        if ident is not None:
            out["identified_modes"] = ident.to_json()["modes"]
        return out


def box_search(priors=None, names=None) -> tuple[SearchParameter, ...]:
    """Search parameters from campaign priors ({name: Prior}) or the default factor range."""
    names = names or tuple(p.name for p in SEARCH_PARAMETERS)
    priors = dict(priors or {})
    unknown = sorted(set(priors) - set(names))
    if unknown:
        raise InputError(f"priors for unknown box parameter(s) {', '.join(unknown)}; known: {', '.join(names)}",
                         key="priors")
    out = []
    for n in names:
        pr = priors.get(n)
        lo, hi, nom = (pr.low, pr.high, pr.nominal) if pr else (*DEFAULT_RANGE, 1.0)
        out.append(SearchParameter(n, nom, 0.3 * nom, lo, hi, 0.01 * nom))
    return tuple(out)


def swarm_box(fit: BoxFit, search: tuple[SearchParameter, ...], rng: np.random.Generator, settings: PSOSettings, *,
              log_factors: bool = False):
    """The seed's swarm on ``fit`` (RTRI eq. 3), its basis built at the search's centre and
    adapted as the swarm narrows; with ``log_factors`` the particles move in the factors'
    logarithms (the same centre, a spread of 0.3). Returns (the PSO result, the best factors)."""
    fit.rebuild(np.array([q.mean for q in search]))
    if not log_factors:
        res = particle_swarm(fit, search, rng, settings=settings, adapt=fit.adapt)
        return res, res.best
    space = tuple(SearchParameter(q.name, np.log(q.mean), 0.3, np.log(q.low), np.log(q.high), 0.01) for q in search)
    res = particle_swarm(lambda Q: fit(np.exp(np.atleast_2d(Q))), space, rng, settings=settings,
                         adapt=lambda it, best, force=False: fit.adapt(it, np.exp(best), force=force))
    return res, np.exp(res.best)


def calibrate_box(targets: tuple[ModeTarget, ...], sensors, search: tuple[SearchParameter, ...], *,
                  settings: PSOSettings = PSOSettings(target=PAPER_STOP_PCT), seed: int = 0, refine: bool = True,
                  sigma_f=0.002, model=None, progress=None, min_carbody_share: float = 0.0,
                  min_mac: float = 0.0, log_factors: bool = False, polish_steps: int = 0) -> BoxCalibration:
    """``sensors``: the campaign sensors the target shapes are given at (for the operator);
    ``sigma_f``: relative uncertainty of the measured frequencies for the identifiability;
    ``min_carbody_share``, ``min_mac``: which pairings count (:class:`BoxFit`);
    ``log_factors``: the swarm moves in the factors' logarithms (a box spanning ratios of
    16 or more, where a linear swarm crowds the upper end); ``polish_steps``: after the
    refinement, up to this many sequential-LP steps on the full model that keep the MAC
    floor (:func:`polish_box`; each costs 1 + 2 d full eigen-solves with a floor, d factors)."""
    model = assemble(shinkansen_vehicle()) if model is None else model
    names = tuple(p.name for p in search)
    if names != model.names:
        raise InputError(f"the search must name the model's parameters {model.names}, got {names}", key="priors")
    fit = BoxFit(model, sensor_operator(model, sensors), targets, min_carbody_share=min_carbody_share,
                 min_mac=min_mac)
    low, high = bounds(search)
    t0 = time.perf_counter()
    res, best = swarm_box(fit, search, np.random.default_rng(seed), settings, log_factors=log_factors)
    wall = time.perf_counter() - t0
    check = fit.full_check(best)
    pso = {"particles": settings.particles, "iterations": res.iterations, "evaluations": res.evaluations,
           "wall_s": wall, "evaluations_per_s": res.evaluations / wall, "basis_rebuilds": fit.rebuilds,
           "best_reduced_pct": res.best_value, "best_full_pct": check["max_error_pct"],
           "reached_stop": res.reached_target, "stop_pct": settings.target,
           "history_pct": [float(v) for v in res.history]}
    p = best
    refinement = None
    if refine:
        if progress:
            progress("refining on the reduced model in rounds, checked on the full model (CasADi/IPOPT)")
        r = refine_box(fit, p, low, high)
        refinement = {"rounds": r.rounds, "statuses": list(r.statuses), "start_max_error_pct": r.start_max_error_pct,
                      "end_max_error_pct": r.max_error_pct, "improved": r.max_error_pct < r.start_max_error_pct}
        p = r.parameters
        if polish_steps > 0:
            if progress:
                progress(f"polishing on the full model (sequential LP{', MAC floor kept' if min_mac > 0 else ''})")
            pol = polish_box(fit, p, low, high, steps=polish_steps, progress=progress)
            refinement["polish"] = {"steps": pol.rounds, "kept": pol.statuses.count("kept"),
                                    "start_max_error_pct": pol.start_max_error_pct,
                                    "end_max_error_pct": pol.max_error_pct}
            refinement["end_max_error_pct"] = pol.max_error_pct
            refinement["improved"] = pol.max_error_pct < r.start_max_error_pct
            p = pol.parameters
    final = check if refinement is None else fit.full_check(p)  # unrefined: the swarm's best, already checked
    fit.rebuild(p)  # exact eigenpairs at p for the sensitivities
    sigma = np.broadcast_to(np.asarray(sigma_f, float), (len(targets),))
    ident = identifiability(fit, p, tuple(t.label for t in targets), sigma_f=sigma, low=low, high=high).to_json()
    rows = [{"label": t.label, "measured_hz": t.frequency_hz, "model_hz": float(final["frequency_hz"][i]),
             "error_pct": float(final["error_pct"][i]), "mac": float(final["mac"][i]),
             "sound": bool(final["sound"][i]),
             "model_mode": int(final["index"][i]) + 1} for i, t in enumerate(targets)]
    return BoxCalibration(dict(zip(names, map(float, p))), rows, float(final["max_error_pct"]), pso, refinement,
                          [float(x) for x in check["reduced_vs_full_pct"]], ident,
                          {p.name: [p.low, p.high] for p in search})


def targets_from_identification(ident: ShakerIdentification, *, band: bool = False) -> tuple[ModeTarget, ...]:
    """The identified modes as targets; with ``band`` each carries its half-power band
    (its damping ratio), so that a mode identified at a close pair of model modes is
    compared with the pair's span (:func:`calibration.models.box.fit.band_pairing`)."""
    return tuple(ModeTarget(m.label, m.frequency_hz, m.shape, m.damping_ratio if band else 0.0) for m in ident.modes)


def calibrate_box_campaign(campaign: Campaign, *, settings: PSOSettings = PSOSettings(target=PAPER_STOP_PCT),
                           seed: int = 0, refine: bool = True, shaker: ShakerSettings = ShakerSettings(),
                           progress=None) -> tuple[BoxCalibration, ShakerIdentification]:
    if campaign.meta.kind != "stationary_excitation":
        raise InputError(f"the box model is calibrated from stationary excitation tests, not {campaign.meta.kind}",
                         path=campaign.root / "campaign.toml", key="kind")
    ident = identify_excitation(campaign, shaker)
    if not ident.modes:
        raise InputError("no mode identified in the analysis band; nothing to calibrate to",
                         path=campaign.root / "runs")
    sensors = tuple(campaign.meta.sensor(n) for n in ident.sensors)
    search = box_search(campaign.meta.priors)
    if progress:
        progress(f"identified {len(ident.modes)} modes; particle swarm on the box model")
    return calibrate_box(targets_from_identification(ident, band=True), sensors, search, settings=settings, seed=seed,
                         refine=refine, progress=progress), ident
