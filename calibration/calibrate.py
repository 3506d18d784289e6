"""Calibration of the 2D car against target frequencies (in-service seed, section 6).

Targets come from a file (``[[targets]] label, frequency_hz``) or from ``railcal identify``
on a campaign; parameter ranges from a priors file (``[NAME] nominal, low, high`` and,
optionally, ``std`` and ``convergence_range`` for Cross-Entropy), from the campaign's
priors, or from the seed's Table 7. The global search (Cross-Entropy or particle swarm,
:data:`calibration.optimisers.OPTIMISERS`) runs ``runs`` times with seeded generators; as
in the seed, the parameters reported are the average of the runs. Every run, the fit per
mode and the identifiability analysis at the result are reported.

The average of the runs is not itself a solution when the targets leave parameter
directions undetermined: each run ends at a different point of a curved solution set,
and their mean lies off it (two swarm runs that each fit to 1e-5 average to a 0.3 % misfit
in the tests). The fit table is therefore computed at the reported average, never copied
from a run. The constrained refinement of issue 3 (CasADi) is what should start from it.
"""
from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .data.campaign import read_input_file
from .data.errors import InputError
from .models.batch import MASS_NAMES, STIFFNESS_NAMES, LinearFamily
from .models.car2d import build_car
from .models.channel_shapes import model_shapes, response_channels
from .models.parameters import CarParameters
from .models.vehicles import INTERCITY_TRAILER
from .optimisers import OPTIMISERS, SearchParameter
from .optimisers.base import bounds
from .optimisers.cross_entropy import SEED_TABLE7
from .optimisers.identifiability import identifiability
from .optimisers.objectives import OBJECTIVES
from .optimisers.refine import refine
from .signals.modal import mac_matrix

LABELS = ("carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch")
SEARCHABLE = MASS_NAMES + STIFFNESS_NAMES


def read_targets(path, labels=LABELS, model: str = "car2d") -> dict[str, float]:
    """{label: frequency [Hz]} from [[targets]] tables; ``labels`` are the model's mode labels."""
    path = Path(path)
    try:
        data = tomllib.loads(read_input_file(path))  # checked first: a FIFO or device is refused, not read for ever
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"cannot read targets: {e}", path=path) from None
    rows = data.get("targets")
    if not isinstance(rows, list) or not rows:
        raise InputError("expected [[targets]] tables with label and frequency_hz", path=path, key="targets")
    out = {}
    for i, row in enumerate(rows):
        key = f"targets[{i}]"
        if not isinstance(row, dict) or "label" not in row or "frequency_hz" not in row:
            raise InputError("needs label and frequency_hz", path=path, key=key)
        label, f = row["label"], row["frequency_hz"]
        if label not in labels:
            raise InputError(f"unknown mode label {label!r}; {model} has {', '.join(labels)}", path=path,
                             key=f"{key}.label")
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not np.isfinite(f) or f <= 0:
            raise InputError(f"frequency must be a positive number of Hz, got {f!r}", path=path,
                             key=f"{key}.frequency_hz")
        if label in out:
            raise InputError(f"mode {label} targeted twice", path=path, key=f"{key}.label")
        out[label] = float(f)
    return out


def _convergence_range(nominal: float, low: float, high: float) -> float:
    """Table 7's habit, 0.5 % of the nominal; of the range where the nominal is zero."""
    return 0.005 * abs(nominal) if nominal else 0.005 * (high - low)


def read_priors(path, searchable=None) -> tuple[SearchParameter, ...]:
    """Search ranges from a priors file; missing std / convergence_range follow Table 7's habit
    (a quarter of the range, and 0.5 % of the nominal). ``searchable``: the names a model
    can search (default: the 2D car's at fixed geometry)."""
    searchable = SEARCHABLE if searchable is None else tuple(searchable)
    path = Path(path)
    try:
        data = tomllib.loads(read_input_file(path))
    except tomllib.TOMLDecodeError as e:
        raise InputError(f"cannot read priors: {e}", path=path) from None
    params = []
    for name, spec in data.items():
        if name not in searchable:
            raise InputError(f"{name!r} cannot be searched; searchable: {', '.join(searchable)}", path=path, key=name)
        if not isinstance(spec, dict) or not {"nominal", "low", "high"} <= set(spec):
            raise InputError("needs nominal, low, high", path=path, key=name)
        for k in ("nominal", "low", "high", "std", "convergence_range"):
            v = spec.get(k)
            if k in spec and (isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v)):
                raise InputError(f"expected a finite number, got {v!r}", path=path, key=f"{name}.{k}")
        try:
            nominal, low, high = (float(spec[k]) for k in ("nominal", "low", "high"))
            std = float(spec.get("std", (high - low) / 4))
            conv = float(spec.get("convergence_range", _convergence_range(nominal, low, high)))
            params.append(SearchParameter(name, nominal, std, low, high, conv))
        except (TypeError, ValueError) as e:
            raise InputError(str(e), path=path, key=name) from None
    if not params:
        raise InputError("no parameter ranges given", path=path)
    return tuple(params)


@dataclass(frozen=True)
class CalibrationResult:
    method: str
    objective: str
    targets: dict
    parameters: CarParameters
    runs: list = field(repr=False)
    fit: list = field(default_factory=list)
    identifiability: dict = field(default_factory=dict)
    refinement: dict | None = None
    search: dict = field(default_factory=dict)  # each parameter's search range [low, high] (None: open)
    mac_matrix: dict | None = None  # identified x model modes at the response channels (a campaign's)

    @property
    def max_error_pct(self) -> float:
        return max(abs(r["error_pct"]) for r in self.fit)

    def to_json(self) -> dict:
        return {"model": "car2d", "method": self.method, "objective": self.objective,
                "parameters": self.parameters.as_dict(), "fit": self.fit, "max_error_pct": self.max_error_pct,
                "identifiability": self.identifiability, "refinement": self.refinement, "search": self.search,
                "mac_matrix": self.mac_matrix, "runs": self.runs}


def _history(r) -> dict:
    """A search's convergence for the figures: Cross-Entropy's sampling mean per generation, its
    change C_g (the stopping measure) and the elite's best objective; a swarm's best objective
    per iteration, each to 6 figures (a figure's precision, not the result's)."""
    def six(v) -> float:
        return float(f"{float(v):.6g}")

    if hasattr(r, "generations"):
        return {"mean": [[six(v) for v in h["mean"]] for h in r.history],
                "change": [six(h["C_g"]) for h in r.history],
                "best_objective": [six(h["elite_best"]) for h in r.history]}
    return {"best_objective": [six(v) for v in r.history]}


def calibrate_car(targets: dict[str, float], search: tuple[SearchParameter, ...], *, base: CarParameters = INTERCITY_TRAILER,
                  method: str = "ce", objective: str = "sse", runs: int = 10, seed: int = 0, settings=None,
                  sigma_f=0.005, refine_result: bool = False) -> CalibrationResult:
    """``sigma_f``: relative uncertainty of the target frequencies, one number or {label: value}."""
    if method not in OPTIMISERS:
        raise InputError(f"unknown method {method!r}; have {', '.join(OPTIMISERS)}", key="--method")
    if objective not in OBJECTIVES:
        raise InputError(f"unknown objective {objective!r}; have {', '.join(OBJECTIVES)}", key="--objective")
    optimiser, settings_type = OPTIMISERS[method]
    settings = settings_type() if settings is None else settings
    if method == "pso":
        open_ended = [p.name for p in search if p.low is None or p.high is None]
        if open_ended:
            raise InputError(f"a swarm needs a range for every parameter; none given for {', '.join(open_ended)} "
                             "(give them with --priors)", key="--priors")
    names = tuple(p.name for p in search)
    family = LinearFamily.of_car(base.replace(**{p.name: p.mean for p in search}), names=names)
    fn = OBJECTIVES[objective]

    def evaluate(X):
        return fn(family.frequencies(X), targets)

    results = []
    for k in range(runs):
        r = optimiser(evaluate, search, np.random.default_rng([seed, k]), settings=settings)
        x = r.mean if method == "ce" else r.best
        F = family.frequencies(x[None, :])
        results.append({"run": k + 1, "parameters": dict(zip(names, map(float, x))),
                        "frequencies_hz": {lbl: float(F[lbl][0]) for lbl in targets},
                        "objective": float(evaluate(x[None, :])[0]),
                        "iterations": int(getattr(r, "generations", getattr(r, "iterations", 0))),
                        "history": _history(r)})
    finite = [run for run in results if np.isfinite(run["objective"])]
    if not finite:
        raise InputError("no run found parameters with a finite objective: the targets or ranges give no "
                         "model with every targeted mode", key="--targets")
    mean = np.mean([[run["parameters"][n] for n in names] for run in finite], axis=0)
    low, high = bounds(search)
    refinement = None
    if refine_result:
        r = refine(family, mean, targets, low, high, judge=lambda f, t: float(np.asarray(fn(f, t))))
        refinement = {"status": r.status, "improved": r.improved, "objective_start": r.objective_start,
                      "objective_end": r.objective_end, "max_relative_error": r.max_relative_error,
                      "start_parameters": dict(zip(names, map(float, mean)))}
        mean = r.parameters
    final = family.base.replace(**dict(zip(names, map(float, mean))))
    F = family.frequencies(mean[None, :])
    fit = [{"label": lbl, "measured_hz": f, "model_hz": float(F[lbl][0]),
            "error_pct": float(100 * (F[lbl][0] / f - 1)), "mac": None} for lbl, f in targets.items()]
    sigma = [sigma_f[k] for k in targets] if isinstance(sigma_f, dict) else sigma_f
    ident = identifiability(family, mean, tuple(targets), sigma_f=sigma, low=low, high=high).to_json()
    ranges = {p.name: [p.low, p.high] for p in search}
    return CalibrationResult(method, objective, dict(targets), final, results, fit, ident, refinement, search=ranges)


SEED_TABLE4 = {"carbody_bounce": 1.08, "carbody_pitch": 2.19, "bogie_bounce": 6.53, "bogie_pitch": 4.31}
DEFAULT_SEARCH = SEED_TABLE7


def search_from_priors(priors) -> tuple[SearchParameter, ...]:
    """Search ranges from a campaign's [priors.NAME] (the searchable ones), Table 7's habits
    for the deviation (a quarter of the range) and convergence range (0.5 % of nominal)."""
    return tuple(SearchParameter(name, p.nominal, (p.high - p.low) / 4, p.low, p.high,
                                 _convergence_range(p.nominal, p.low, p.high))
                 for name, p in priors.items() if name in SEARCHABLE)


SYSTEMATIC_FLOOR = 0.005  # relative; see calibrate_campaign


def mode_uncertainties(modes) -> dict[str, float]:
    """Relative uncertainty per identified mode: its standard error combined with the
    systematic floor (see :func:`calibrate_campaign`)."""
    return {m.label: float(np.hypot((m.frequency_std_hz or 0.0) / m.frequency_hz, SYSTEMATIC_FLOOR))
            for m in modes if m.label in LABELS}


def calibrate_campaign(campaign, *, method: str = "ce", objective: str = "sse", runs: int = 10, seed: int = 0,
                       refine_result: bool = True, identified=None, progress=None):
    """Identify the campaign's modes (``identified``: its identification made before, an
    identification file's modes read back), then calibrate the car to them within its priors.

    One identified mode is enough: it fixes one parameter combination as two fix two, and
    the identifiability analysis names every combination left to the priors.

    The identifiability intervals use, per mode, the identification's standard error (a
    delete-one-journey jackknife) combined with a systematic floor of 0.5 %: the largest bias of the input-output estimate seen on
    noise-free synthetic data (carbody bounce -0.62 %, seed 1; a single bogie sees both the
    in-phase and the anti-phase bogie bounce, 0.1-0.2 %), which no spread reveals."""
    from .data.errors import CampaignError
    from .identification.in_service import identify_in_service, prior_parameters

    modes = identify_in_service(campaign, progress=progress).modes if identified is None else tuple(identified)
    targets = {m.label: m.frequency_hz for m in modes if m.label in LABELS}
    if not targets:
        raise CampaignError("no rigid-body mode identified: nothing to calibrate to (the identification says "
                            "why per mode)", path=campaign.root)
    search = search_from_priors(campaign.meta.priors)
    if not search:
        raise CampaignError("no [priors.NAME] of a searchable parameter "
                            f"({', '.join(SEARCHABLE)}): nothing to calibrate", path=campaign.root / "campaign.toml",
                            key="priors")
    base = prior_parameters(campaign)
    result = calibrate_car(targets, search, base=base, method=method, objective=objective, runs=runs, seed=seed,
                           refine_result=refine_result, sigma_f=mode_uncertainties(modes))
    fit, matrix = pair_shapes(result.fit, modes, result.parameters, campaign.meta.sensors)
    return replace(result, fit=fit, mac_matrix=matrix), modes


#: A channel moves in a model mode when its entry is at least this share of the mode's largest.
#: A mode that moves one channel alone has a MAC that only weighs how much of the identified
#: shape lies on that channel (any shape concentrated there scores near 1), not a shape.
MOVING_SHARE = 0.1


def pair_shapes(fit: list, modes, p: CarParameters, sensors) -> tuple[list, dict | None]:
    """(``fit`` with each row's ``mac``, the MAC matrix or None): the identified modes' shapes
    (:mod:`.identification.shapes`) against the damped modes of the car ``p`` at the same
    response channels (:mod:`.models.channel_shapes`; axle boxes are the rail input, not a
    response, and are not among them). A row's MAC is None, with ``mac_note`` saying why,
    where the identification gives no shape, the shape has one channel, or the paired model
    mode moves one channel only (:data:`MOVING_SHARE`)."""
    shaped = [m for m in modes if m.label in LABELS and m.shape is not None]
    if not shaped:
        return [{**r, "mac": None, "mac_note": "the identification gives no mode shape"} for r in fit], None
    names = shaped[0].shape.channels
    by_name = {c.name: c for c in response_channels(sensors, L_v=p.L_v, L_b=p.L_b)}
    if not set(names) <= set(by_name):
        raise InputError(f"the identified shapes' channels {', '.join(sorted(set(names) - set(by_name)))} are not "
                         "response channels of this campaign", key="modes[0].shape.channels")
    # the identification's levers, so that both shapes weigh a pitch alike
    channels = tuple(replace(by_name[n], lever=lever) for n, lever in zip(names, shaped[0].shape.levers))
    model = model_shapes(build_car(p), channels)
    A = np.array([m.shape.values for m in shaped]).T  # (channels, identified)
    B = np.array([v for _, v in model]).T  # (channels, model modes)
    mac = mac_matrix(A, B)
    excluded = [s.name for s in sensors if s.name not in by_name]
    matrix = {"identified": [m.label for m in shaped], "model": [m.name for m, _ in model],
              "model_pole_hz": [m.frequency_hz for m, _ in model], "channels": list(names),
              "values": [[float(v) for v in row] for row in mac], "excluded_channels": excluded,
              "note": "complex MAC of displacement shapes at the response channels against the model's damped "
                      "modes (model_pole_hz: |lambda| / 2 pi); axle-box channels are the rail input, not a response "
                      "of the car, and are excluded"}
    out = []
    for r in fit:
        i = next((k for k, m in enumerate(shaped) if m.label == r["label"]), None)
        j = next((k for k, (m, _) in enumerate(model) if m.label == r["label"]), None)  # the lowest: in phase
        if i is None or j is None:
            note = "no identified shape for this mode"
        elif len(names) < 2:
            note = f"one response channel ({names[0]}): a MAC over one entry is 1 for any shape"
        elif len(moving := [n for n, v in zip(names, np.abs(B[:, j])) if v >= MOVING_SHARE * max(abs(B[:, j]))]) < 2:
            note = (f"in the model this mode moves {moving[0]} alone (the other channels less than "
                    f"{MOVING_SHARE:.0%} of it): a MAC then weighs only the identified shape's share on that "
                    f"channel ({mac[i, j]:.3f} in the matrix), not its shape")
        else:
            out.append({**r, "mac": float(mac[i, j]), "mac_model_mode": model[j][0].name})
            continue
        out.append({**r, "mac": None, "mac_note": note})
    return out, matrix
