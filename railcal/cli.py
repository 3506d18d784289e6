"""The ``railcal`` command line (shared/spec/interfaces.md).

Every command prints a one-line summary, writes JSON with ``--out``, exits 0 on success,
2 on bad input (the message names the file, key or column), 1 on internal failure.
Progress goes to stderr unless ``--quiet``.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import traceback
from pathlib import Path

from calibration.data.campaign import open_campaign, read_input_file
from calibration.data.outputs import check_campaign_output, check_outputs, read_result, write_result
from calibration.data.errors import InputError
from calibration.models.parameters import CAR_PARAMETER_SPECS, ParameterError
from calibration.swarm_defaults import (CAMPAIGN_DONE_PCT, CAMPAIGN_SWARMS, TYPED_MIN_MAC, TYPED_POLISH_STEPS,
                                        TYPED_REFINE_ROUNDS, TYPED_SWARMS)

EXIT_OK, EXIT_INTERNAL, EXIT_INPUT = 0, 1, 2


class _HelpFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows an option's default after its help unless the help already says it in words
    (which options with a default of None do: "None" tells a user nothing)."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (not action.option_strings or "default" in text.lower()
                or any(action.default is v for v in (None, False, argparse.SUPPRESS))):
            return text
        return f"{text} (default: %(default)s)"


class _DeprecatedAlias(argparse.Action):
    """An old option name that still works and says on stderr which name replaces it."""

    def __init__(self, option_strings, dest, *, replacement: str, **kwargs):
        self.replacement = replacement
        super().__init__(option_strings, dest, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"railcal: warning: {option_string} is deprecated and will be removed; use {self.replacement}",
              file=sys.stderr)
        setattr(namespace, self.dest, values)


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("railcal")
    except PackageNotFoundError:  # a source tree that was never installed
        return "unknown (not installed)"


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):  # argparse's own usage errors are bad input too: exit 2
        self.print_usage(sys.stderr)
        print(f"railcal: error: {message}", file=sys.stderr)
        raise SystemExit(EXIT_INPUT)


def _seed(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"seed must be a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"seed must be >= 0, got {value}")
    return value


def _truth_path(campaign_dir) -> Path:
    return Path(f"{Path(campaign_dir).resolve()}.truth.json")


def _names(*paths) -> str:
    """'a, b and c' of the files written (None: not written)."""
    names = [str(p) for p in paths if p is not None]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _truth_frequencies(campaign_dir) -> dict | None:
    """Frequencies from a synthetic campaign's truth beside it, for the plots; None otherwise."""
    path = _truth_path(campaign_dir)
    if not path.is_file():
        return None
    try:
        return {k: float(v) for k, v in json.loads(read_input_file(path))["frequencies_hz"].items()}
    except (InputError, ValueError, KeyError, TypeError, AttributeError) as e:
        print(f"railcal: warning: {path} is not a readable truth file ({e}); plotted without it", file=sys.stderr)
        return None


def _open_campaign(args):
    """The command's campaign, its run files held inside its folder unless --allow-outside."""
    return open_campaign(args.campaign, allow_outside=args.allow_outside)


def _allow_outside_option(parser) -> None:
    parser.add_argument("--allow-outside", action="store_true",
                        help="read run and track files that are links resolving outside the campaign folder "
                             "(refused by default: a campaign is read from its own folder only)")


def _progress(args):
    """Messages and counted bars on stderr (calibration/progress.py); None with --quiet."""
    if getattr(args, "quiet", False):
        return None
    from calibration.progress import Progress

    return Progress()


# ------------------------------------------------------------------------------ synth
def cmd_synth_in_service(args) -> int:
    from calibration.truth.effects import parse_effect
    from calibration.truth.in_service import InServiceSettings, synth_in_service
    from calibration.truth.track import LineSpec

    effect = parse_effect(args.effect, "in_service")
    if args.journeys < 1:
        raise InputError(f"--journeys must be >= 1, got {args.journeys}", key="--journeys")
    if not 5.0 <= args.length_km <= 500.0:
        raise InputError(f"--length-km must be within 5..500 km, got {args.length_km}", key="--length-km")
    check_campaign_output(args.out, overwrite=args.force)
    settings = InServiceSettings(journeys=args.journeys, line=LineSpec(length=args.length_km * 1000.0),
                                 carbody_sensors=args.carbody_sensors)
    truth = synth_in_service(args.out, seed=args.seed, settings=settings, effect=effect, fmt=args.format,
                             overwrite=args.force, progress=_progress(args))
    f = truth["frequencies_hz"]
    print(f"wrote {args.out} ({args.journeys} journeys x {args.length_km:g} km) and {args.out}.truth.json; "
          + ", ".join(f"{k} {v:.3f} Hz" for k, v in f.items()))
    return EXIT_OK


def cmd_synth_excitation(args) -> int:
    from calibration.truth.effects import parse_effect
    from calibration.truth.excitation import ExcitationSettings, synth_excitation

    effect = parse_effect(args.effect, "stationary_excitation")
    if args.runs < 1:
        raise InputError(f"--runs must be >= 1, got {args.runs}", key="--runs")
    if not 20.0 * args.runs <= args.duration <= 7200.0:
        raise InputError(f"--duration must be within {20 * args.runs:g}..7200 s (at least 20 s per run), "
                         f"got {args.duration:g}", key="--duration")
    check_campaign_output(args.out, overwrite=args.force)
    settings = ExcitationSettings(runs=args.runs, duration=args.duration)
    truth = synth_excitation(args.out, seed=args.seed, settings=settings, effect=effect, fmt=args.format,
                             overwrite=args.force, progress=_progress(args))
    elastic = [f"{k} {f:.2f} Hz" for k, f in truth["frequencies_hz"].items() if truth["mode_kinds"][k] == "elastic"]
    print(f"wrote {args.out} ({args.runs} runs x {settings.run_duration:g} s, {len(truth['sensors'])} floor "
          f"accelerometers and the exciter force at {settings.fs:g} Hz) and {args.out}.truth.json; "
          f"{truth['modes_kept']['count']} modes kept; elastic modes in 3-25 Hz: {', '.join(elastic)}")
    return EXIT_OK


# --------------------------------------------------------------------------- identify
def cmd_identify(args) -> int:
    from calibration.identification.fdd import FDDSettings
    from calibration.identification.in_service import IdentifySettings, identify_in_service
    from calibration.identification.plots import plot_identification, plot_spectra

    campaign = _open_campaign(args)
    png = Path(args.plot) if args.plot else Path(args.out).with_suffix(".png")
    second = png.with_name(png.stem + ("_mac.png" if campaign.meta.kind == "stationary_excitation" else "_spectra.png"))
    check_outputs([args.out, png, second], inputs=[args.campaign, _truth_path(args.campaign)])
    if campaign.meta.kind == "stationary_excitation":
        return _identify_excitation(campaign, args)
    settings = IdentifySettings(fdd=FDDSettings(seed=args.seed))
    result = identify_in_service(campaign, settings=settings, progress=_progress(args))
    out = result.to_json()
    plot_identification(result, png, truth=_truth_frequencies(args.campaign))
    spectra = plot_spectra(result, second)
    out["plot"] = str(png)
    out["plot_spectra"] = None if spectra is None else str(spectra)
    write_result(args.out, out, "identification")
    modes = ", ".join(f"{m.label} {m.frequency_hz:.3f} Hz" for m in result.modes)
    open_ = "".join(f"; {u.label} not determined" for u in result.undetermined)
    print(f"identified {len(result.modes)} modes ({modes}){open_}; {len(result.rejected_peaks)} peaks rejected; "
          f"{out['data']['gaps']} gaps in {len(result.runs)} runs reported; wrote "
          f"{_names(args.out, png, spectra)}")
    return EXIT_OK


def _identify_excitation(campaign, args) -> int:
    from calibration.identification.excitation import identify_excitation, write_identification

    result = identify_excitation(campaign)
    out = write_identification(result, args.out, args.plot)
    png, mac_png = out["plot"], out["plot_mac"]
    modes = ", ".join(f"{m.label} {m.frequency_hz:.3f} Hz ({100 * m.damping_ratio:.1f} %)" for m in result.modes)
    print(f"identified {len(result.modes)} modes ({modes}); {len(result.rejected)} peaks rejected; "
          f"{result.frf.n_averages} Welch segments over {result.records} records; wrote {_names(args.out, png, mac_png)}")
    return EXIT_OK


# ------------------------------------------------------------------------------ modes
def _parse_params(items) -> dict[str, float]:
    out = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        if not sep:
            raise InputError(f"expected NAME=VALUE, got {item!r}", key="--param")
        if name not in CAR_PARAMETER_SPECS:
            raise InputError(f"unknown parameter {name!r}; known: {', '.join(CAR_PARAMETER_SPECS)}", key="--param")
        try:
            out[name] = float(value)
        except ValueError:
            raise InputError(f"value of {name} is not a number: {value!r}", key="--param") from None
    return out


def cmd_modes(args) -> int:
    """Eigen-analysis of a model: every mode with a unique ``label`` and its spec v1
    ``family`` (``bogie_bounce_in_phase`` and ``bogie_bounce_anti_phase`` are both of
    family ``bogie_bounce``)."""
    from calibration.data.outputs import check_outputs, write_result

    if args.model not in ("car2d", "box"):
        raise InputError(f"unknown model {args.model!r}; have: car2d, box", key="--model")
    if args.out:
        check_outputs([args.out])
    if args.model == "box":
        out = _box_modes(args)
    else:
        from calibration.models.car2d import build_car, damped_modes, undamped_modes
        from calibration.models.vehicles import VEHICLES

        p = VEHICLES[args.vehicle].replace(**_parse_params(args.param))
        asm = build_car(p)
        damped = {m.name: m for m in damped_modes(asm)}
        modes = []
        for m in undamped_modes(asm):  # both analyses name a mode by its shape alike
            d = damped.get(m.name)
            modes.append({"label": m.name, "family": m.label, "frequency_hz": m.frequency_hz,
                          "damping_ratio": None if d is None else d.damping_ratio,
                          "damped_frequency_hz": None if d is None else d.damped_frequency_hz})
        out = {"model": "car2d", "vehicle": args.vehicle, "parameters": p.as_dict(), "modes": modes}
    if args.out:
        write_result(args.out, out, "modes")
    wrote = f"; wrote {args.out}" if args.out else ""
    print("; ".join(f"{m['label']} {m['frequency_hz']:.3f} Hz" for m in out["modes"]) + wrote)
    return EXIT_OK


def _box_modes(args) -> dict:
    """``railcal modes --model box``: the box-type vehicle (default factor set) with
    ``--param NAME=FACTOR`` stiffness factors."""
    from calibration.models.box.shinkansen import calibrated_box_model
    from calibration.models.vehicles import box_modes

    factors = {}
    for item in args.param or []:
        name, sep, value = item.partition("=")
        try:
            factors[name] = float(value) if sep else None
        except ValueError:
            raise InputError(f"value of {name} is not a number: {value!r}", key="--param") from None
        if factors[name] is None:
            raise InputError(f"expected NAME=FACTOR, got {item!r}", key="--param")
    if not args.max_hz > 0:
        raise InputError(f"--max-hz must be positive, got {args.max_hz:g}", key="--max-hz")
    try:
        model, p = calibrated_box_model({"model": "box", "parameters": factors})
    except InputError as e:  # it names the calibration file's key; here the factors come from --param
        raise InputError(str(e).replace("key 'parameters': ", ""), key="--param") from None
    modes = box_modes(model, p, max_hz=args.max_hz)
    return {"model": "box", "parameters": p, "max_hz": args.max_hz,
            "modes": [{"label": m.label, "family": m.family, "frequency_hz": m.frequency_hz,
                       "damping_ratio": m.damping_ratio, "kind": m.kind} for m in modes]}


# -------------------------------------------------------------------------- calibrate
def cmd_calibrate(args) -> int:
    check_outputs([args.out], inputs=[args.campaign, args.targets, args.priors])
    if args.model == "car2d" and args.method == "pso" and args.targets is not None and args.priors is None:
        raise InputError("--method pso searches within a range for every parameter and there is no default "
                         "for the 2D car (the seed's Table 7 gives no range for J_v and J_b): give the ranges "
                         "with --priors P.toml ([NAME] nominal, low, high)", key="--priors")
    from calibration.calibrate import DEFAULT_SEARCH, calibrate_campaign, calibrate_car, read_priors, read_targets

    if args.campaign is not None and args.priors is not None:
        raise InputError("a campaign brings its own [priors.NAME]; --priors goes with --targets", key="--priors")
    if args.model == "box":
        return _calibrate_box(args)
    if args.model != "car2d":
        raise InputError(f"unknown model {args.model!r}; have: car2d, box", key="--model")
    if args.runs < 1:
        raise InputError(f"--runs must be >= 1, got {args.runs}", key="--runs")
    if (args.campaign is None) == (args.targets is None):
        raise InputError("give either a CAMPAIGN or --targets T.toml", key="CAMPAIGN / --targets")
    if args.campaign is not None:
        result, ident = calibrate_campaign(_open_campaign(args), method=args.method, objective=args.objective,
                                           runs=args.runs, seed=args.seed, refine_result=args.refine,
                                           progress=_progress(args))
        out = result.to_json()
        out["identified_modes"] = [m.to_json() for m in ident.modes]
        write_result(args.out, out, "calibration")
        print(f"calibrated to {len(result.targets)} identified modes: max error {result.max_error_pct:.3g} %; "
              f"{result.identifiability['summary']}; wrote {args.out}")
        return EXIT_OK
    targets = read_targets(args.targets)
    search = read_priors(args.priors) if args.priors else DEFAULT_SEARCH
    result = calibrate_car(targets, search, method=args.method, objective=args.objective, runs=args.runs,
                           seed=args.seed, refine_result=args.refine)
    write_result(args.out, result.to_json(), "calibration")
    refined = ""
    if result.refinement is not None:
        refined = (" after CasADi refinement" if result.refinement["improved"]
                   else " (refinement did not improve; global result kept)")
    within = "" if args.priors else " within the seed's Table 7 ranges (intercity trailer car)"
    print(f"{args.method} x {args.runs} runs{within}{refined}: max error {result.max_error_pct:.3g} %; "
          f"{result.identifiability['summary']}; wrote {args.out}")
    return EXIT_OK


def _calibrate_box(args) -> int:
    from calibration.calibrate_box import calibrate_box_campaign
    from calibration.optimisers.pso import PSOSettings

    if args.method != "pso":
        raise InputError("the box model is calibrated by particle swarm (the RTRI seed's method): --method pso",
                         key="--method")
    if (args.campaign is None) == (args.targets is None):
        raise InputError("give either a stationary excitation CAMPAIGN or --targets T.toml", key="CAMPAIGN / --targets")
    if args.particles < 2 or args.iterations < 1 or not args.stop_pct >= 0:
        raise InputError("need --particles >= 2, --iterations >= 1 and --stop-pct >= 0", key="--particles")
    settings = PSOSettings(particles=args.particles, iterations=args.iterations, target=args.stop_pct)
    swarms = args.swarms if args.swarms is not None else CAMPAIGN_SWARMS if args.campaign is not None else TYPED_SWARMS
    if swarms < 1 or args.particles // swarms < 2:
        raise InputError(f"--swarms {swarms} with --particles {args.particles}: each swarm needs 2 or more particles",
                         key="--swarms")
    if args.campaign is not None:
        if args.factors not in (None, "grouped"):
            raise InputError(f"a campaign is calibrated over the grouped factor set (its priors name them), not "
                             f"{args.factors!r}", key="--factors")
        result, ident = calibrate_box_campaign(_open_campaign(args), settings=settings, seed=args.seed,
                                               refine=args.refine, progress=_progress(args), swarms=swarms)
        out = result.to_json(ident)
    else:
        result = _calibrate_box_targets(args, settings, swarms)
        out = result.to_json()
    write_result(args.out, out, "calibration")
    pso = result.pso
    runs = pso.get("swarms", ())
    ends = ", ".join(f"{r['end_max_error_pct']:.3g} %" for r in runs)
    split = f" in {len(runs)} swarms (each refined: {ends}; the best kept)" if runs else ""
    print(f"pso {pso['particles']} x {pso['iterations']} iterations{split} over {len(pso['factors'])} of the "
          f"{len(result.parameters)} {result.factor_set} factors ({pso['evaluations_per_s']:.0f} evaluations/s): "
          f"{pso['best_full_pct']:.3g} %{' -> refined' if result.refinement else ''} to "
          f"{result.max_error_pct:.3g} % over {len(result.fit)} modes, MAC >= {min(r['mac'] for r in result.fit):.3f}"
          f"{_unsound(result.fit)}; {result.identifiability['summary']}; wrote {args.out}")
    return EXIT_OK


def _unsound(fit) -> str:
    """The summary's note of pairings that do not count as they are (under the MAC floor or
    sharing a partner; :meth:`BoxFit.sound`), with the MAC to six places: a MAC of 0.799999
    prints as 0.800 but is under a floor of 0.8."""
    bad = [r for r in fit if not r["sound"]]
    return "".join(f", {r['label']} unsound (MAC {r['mac']:.6f})" for r in bad)


def _calibrate_box_targets(args, settings, swarms: int):
    """Targets given by mode type and frequency: each paired by MAC with the type's floor
    pattern at the assumed accelerometer grid of the shaker test."""
    from calibration.calibrate import read_priors, read_targets
    from calibration.calibrate_box import box_search, calibrate_box
    from calibration.data.campaign import Prior
    from calibration.models.box import factor_set
    from calibration.models.box.mode_types import MODE_TYPES, typed_targets
    from calibration.models.box.shinkansen import Geometry
    from calibration.models.box.rig import EXCITER, SENSOR_GRID

    try:
        factors = factor_set(args.factors or "credible")
    except ValueError as e:
        raise InputError(str(e), key="--factors") from None
    targets = read_targets(args.targets, labels=tuple(MODE_TYPES), model="the box model (mode types)")
    given = read_priors(args.priors, searchable=factors.names) if args.priors else ()
    search = box_search({q.name: Prior(q.mean, q.low, q.high) for q in given}, factors=factors)
    g = Geometry()
    typed = typed_targets(targets, SENSOR_GRID, g.length, g.width)
    return calibrate_box(typed, SENSOR_GRID, search, settings=settings, seed=args.seed, refine=args.refine,
                         factors=factors, progress=_progress(args),
                         min_mac=TYPED_MIN_MAC, log_factors=True, refine_rounds=TYPED_REFINE_ROUNDS,
                         polish_steps=TYPED_POLISH_STEPS if args.refine else 0, swarms=swarms,
                         exciter=EXCITER)


# --------------------------------------------------------------------------- validate
def _read_calibration(path) -> dict:
    """A calibration file (railcal calibrate --out) with a parameters table, or exit 2."""
    path = Path(path)
    calibration = read_result(path, ("calibration", "diagnosis"))
    if "parameters" not in calibration:
        raise InputError("not a calibration result: no 'parameters'", path=path, key="parameters")
    params = calibration["parameters"]
    if not isinstance(params, dict):
        raise InputError(f"'parameters' must map names to values, got {type(params).__name__}", path=path,
                         key="parameters")
    return calibration


def cmd_validate(args) -> int:
    from calibration.models.parameters import CarParameters
    from calibration.validation.in_service import validate
    from calibration.validation.plots import plot_validation

    path = Path(args.calibration)
    check_outputs([args.out, Path(args.out).with_suffix(".png")], inputs=[args.campaign, path])
    calibration = _read_calibration(path)
    params = calibration["parameters"]
    campaign = _open_campaign(args)
    if campaign.meta.kind == "stationary_excitation":
        return _validate_excitation(campaign, calibration, args)
    try:
        p = CarParameters.from_mapping(params)
    except ParameterError as e:
        raise InputError(str(e), path=path, key="parameters") from None
    result = validate(campaign, p, progress=_progress(args))
    png = plot_validation(result, Path(args.out).with_suffix(".png"))
    out = result.to_json()
    out["plot"] = str(png)
    write_result(args.out, out, "validation")
    summary = "; ".join(f"{k}: NRMSE {v['nrmse']:.3f}, PSD {v['psd_log_error_db']:.2f} dB"
                        for k, v in out["channels"].items())
    print(f"validated over {result.track} ({len(result.runs)} runs, band {result.band_m[0]:g}-{result.band_m[1]:g} m): "
          f"{summary}; wrote {_names(args.out, png)}")
    return EXIT_OK


def cmd_diagnose(args) -> int:
    from calibration.diagnosis.diagnose import diagnose
    from calibration.diagnosis.plots import plot_diagnosis

    campaign = _open_campaign(args)
    out_path = Path(args.out)
    stem = out_path.with_suffix("")
    ends = ("_frf", "_mac") if campaign.meta.kind == "stationary_excitation" else ("_residual_psd", "_speed_map")
    check_outputs([out_path, *(stem.with_name(stem.name + e + ".png") for e in ends)], inputs=[args.campaign])
    if campaign.meta.kind == "stationary_excitation":
        from calibration.diagnosis.stationary import diagnose_stationary, plot_stationary_diagnosis

        result = diagnose_stationary(campaign, progress=_progress(args))
        result["plots"] = [str(p) for p in plot_stationary_diagnosis(result, out_path.with_suffix(""))]
    else:
        result = diagnose(campaign, progress=_progress(args))
        result["plots"] = [str(p) for p in plot_diagnosis(result, out_path.with_suffix(""))]
    result.pop("_plot")
    write_result(out_path, result, "diagnosis")
    if not args.quiet:  # the evidence in full; the summary line stays one line
        for line in result["evidence"]["summary"]:
            print(f"  {line}", file=sys.stderr)
    print(f"cause: {result['cause']}; wrote {_names(out_path, *result['plots'])}")
    return EXIT_OK


def _validate_excitation(campaign, calibration: dict, args) -> int:
    from calibration.validation.excitation import compare_frf
    from calibration.validation.plots import plot_frf_comparison

    if calibration.get("model") != "box":
        raise InputError("a stationary excitation test validates a box calibration (model = box)",
                         path=Path(args.calibration), key="model")
    result = compare_frf(campaign, calibration)
    png = plot_frf_comparison(result, Path(args.out).with_suffix(".png"))
    out = result.to_json()
    out["plot"] = str(png)
    write_result(args.out, out, "validation")
    print(f"FRF from the exciter to {len(result.sensors)} accelerometers over {result.band[0]:g}-{result.band[1]:g} Hz: "
          f"FRAC median {out['frac_median']:.3f}, min {out['frac_min']:.3f}; log-magnitude error up to "
          f"{result.log_error_db.max():.2f} dB rms; wrote {_names(args.out, png)}")
    return EXIT_OK


# ------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from railcal.demo import run_demo

    out = Path(args.out)
    if os.path.lexists(out) and not out.is_dir():
        raise InputError("exists and is not a folder; --out takes the folder to write the demo into", path=out,
                         key="--out")
    # the demo replaces its own campaigns there: refuse before any work if one is not railcal's
    for name in ("campaign", "shaker"):
        check_campaign_output(out / name, overwrite=True)
    report = run_demo(Path(args.out), progress=_progress(args), full=args.full)
    print(f"demo finished: report {report}; wrote its results, figures and FMUs into {args.out}")
    return EXIT_OK


# ------------------------------------------------------------------------------ FMUs
def cmd_export_fmu(args) -> int:
    from fmu_src.build import BuildError
    from fmu_src.export import export_fmu

    check_outputs([args.out], inputs=[args.calibration, args.track, args.campaign])
    calibration = _read_calibration(args.calibration)
    campaign = _open_campaign(args) if args.campaign else None
    try:
        built = export_fmu(calibration, args.fmi_version, Path(args.out), track=args.track, campaign=campaign,
                           cutoff_hz=args.cutoff_hz)
    except ParameterError as e:
        raise InputError(str(e), path=Path(args.calibration), key="parameters") from None
    except BuildError as e:
        print(f"railcal: cannot build the FMU: {e}", file=sys.stderr)
        return EXIT_INTERNAL
    print(f"FMI {built.fmi_version} co-simulation FMU with binaries for {', '.join(built.platforms)}"
          f"{' and a stand-alone track' if args.track else ''}: wrote {built.path}")
    return EXIT_OK


def cmd_crosscheck(args) -> int:
    from railcal.crosscheck import crosscheck_car

    from calibration.models.parameters import CarParameters

    calibration = _read_calibration(args.calibration)
    model = calibration.get("model", "car2d")
    if model not in ("car2d", "box"):
        raise InputError(f"crosscheck covers car2d and box calibrations, not {model!r}", path=Path(args.calibration),
                         key="model")
    png = Path(args.out).with_suffix(".png") if model == "car2d" else None  # the box cross-check draws no figure
    check_outputs([args.out, png], inputs=[args.calibration, args.track])
    if not (args.speed > 0 and args.duration > 0):
        raise InputError("--speed and --duration must be positive", key="--speed")
    if model == "box":
        return _crosscheck_box(calibration, args)
    try:
        p = CarParameters.from_mapping(calibration["parameters"])
    except ParameterError as e:
        raise InputError(str(e), path=Path(args.calibration), key="parameters") from None
    distance, level = _track_for_crosscheck(args)
    try:
        report = crosscheck_car(p, distance, level, speed=args.speed, duration=args.duration,
                                with_fmu=not args.no_fmu, plot=png)
    except ValueError as e:
        raise InputError(str(e), path=Path(args.track) if args.track else None) from None
    write_result(args.out, report, "crosscheck")
    e, t = report["eigen"], report["time"]
    print(f"exudyn vs railcal: eigenfrequencies {e['undamped']['max_relative_error']:.1e}, damped eigenvalues "
          f"{e['damped']['max_relative_error']:.1e}; {t['duration_s']:g} s at {t['speed_m_s']:g} m/s worst NRMSE "
          f"{t['worst_nrmse']:.1e} (exudyn, railcal{'' if args.no_fmu else ', FMU'}); verdict {report['verdict']} "
          f"(wall time {report['wall_time_s']:.1f} s, not judged); wrote {_names(args.out, report.get('plot'))}")
    return EXIT_OK


def _track_for_crosscheck(args):
    from calibration.data.campaign import read_track_file

    if args.track:
        rec = read_track_file(Path(args.track))
        return rec.distance, rec.level
    from fmu_src.reference import smooth_profile  # a synthetic track: German low-disturbance spectrum, 3-70 m

    s, z, _ = smooth_profile(args.speed * args.duration + 60.0, seed=3)
    return s, z


def _crosscheck_box(calibration: dict, args) -> int:
    from railcal.crosscheck import crosscheck_box

    distance, level = _track_for_crosscheck(args)
    try:
        report = crosscheck_box(calibration, distance, level, speed=args.speed, duration=args.duration,
                                with_fmu=not args.no_fmu)
    except ValueError as e:
        raise InputError(str(e), path=Path(args.track) if args.track else None) from None
    write_result(args.out, report, "crosscheck")
    e, t = report["eigen"], report["time"]
    print(f"exudyn vs railcal (box): frequencies below 20 Hz {e['max_relative_error_vs_reduced']:.1e} (reduced), "
          f"{e['max_relative_error_vs_full']:.1e} (full model); {t['duration_s']:g} s at {t['speed_m_s']:g} m/s worst "
          f"floor NRMSE {t['worst_nrmse']:.1e}; verdict {report['verdict']} (wall time "
          f"{report['wall_time_s']:.1f} s, not judged); wrote {args.out}")
    return EXIT_OK


# ------------------------------------------------------------------------------- main
def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="railcal", description="Calibrate railway vehicle vibration models from measured data.")
    p.add_argument("--version", action="version", version=f"railcal {_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    synth = sub.add_parser("synth", help="write a synthetic campaign and its truth")
    ssub = synth.add_subparsers(dest="kind", required=True, parser_class=_Parser)

    def synth_parser(name, help, func):  # what every synthetic campaign takes
        s = ssub.add_parser(name, help=help)
        s.add_argument("out", help="campaign folder to create (its truth goes beside it, as OUT.truth.json)")
        s.add_argument("--seed", type=_seed, default=0, help="seed of every random draw")
        s.add_argument("--format", choices=("csv", "parquet"), default="csv", help="run file format")
        s.add_argument("--effect", default=None, help="hidden physical effect NAME[=MAGNITUDE] "
                       "(default: none, the model's own physics only)")
        s.add_argument("--force", action="store_true", help="replace a campaign railcal wrote there before (and "
                       "its truth file); a folder railcal did not write is never removed")
        s.add_argument("--quiet", action="store_true", help="no progress on stderr")
        s.set_defaults(func=func)
        return s

    s = synth_parser("in-service", "in-service journeys (bogie and axle-box sensors)", cmd_synth_in_service)
    s.add_argument("--journeys", type=int, default=10, help="number of journeys (run files)")
    s.add_argument("--length-km", type=float, default=40.0, help="length of the line [km]")
    s.add_argument("--carbody-sensors", action="store_true",
                   help="add floor accelerometers above both bogies and at the car centre")
    s = synth_parser("excitation", "stationary excitation test (exciter force and floor accelerometers)",
                     cmd_synth_excitation)
    s.add_argument("--duration", type=float, default=600.0, help="total recording [s], split over the runs")
    s.add_argument("--runs", type=int, default=2, help="number of test runs (run files)")

    s = sub.add_parser("identify", help="modal identification of a campaign")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--out", required=True, help="JSON result to write")
    s.add_argument("--plot", default=None, help="PNG of the identification; a second figure goes beside it "
                   "(default: --out with .png)")
    s.add_argument("--seed", type=_seed, default=0, help="seed of the random segment draw")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _allow_outside_option(s)
    s.set_defaults(func=cmd_identify)

    s = sub.add_parser("modes", help="eigen-analysis of a model")
    s.add_argument("--model", choices=("car2d", "box"), default="car2d",
                   help="model to analyse: the 2D car or the box-type vehicle (Shinkansen-type carbody)")
    s.add_argument("--vehicle", choices=("intercity", "manchester"), default="intercity",
                   help="base parameter set: the seed's intercity trailer or the Manchester benchmark coach")
    s.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="set one parameter [SI units] (box: a stiffness factor, nominal 1), repeatable (default: "
                        "none, the --vehicle set as it is)")
    s.add_argument("--max-hz", type=float, default=25.0, help="box model: modes below this [Hz]")
    s.add_argument("--out", default=None, help="JSON result to write (default: none, the summary only)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.set_defaults(func=cmd_modes)

    s = sub.add_parser("calibrate", help="parameters from target frequencies (global search + identifiability)")
    s.add_argument("campaign", nargs="?", default=None,
                   help="campaign folder to identify and calibrate to (or give --targets)")
    s.add_argument("--targets", default=None, help="TOML with [[targets]] label, frequency_hz (default: none; give this or a "
                   "CAMPAIGN)")
    s.add_argument("--priors", default=None,
                   help="with --targets: TOML with [NAME] nominal, low, high (default: with --model car2d --method "
                        "ce the in-service seed's Table 7 ranges of the intercity trailer car; --method pso needs "
                        "this file; with --model box each factor's own range); a campaign brings its own priors")
    s.add_argument("--model", choices=("car2d", "box"), default="car2d", help="model to calibrate")
    s.add_argument("--method", choices=("ce", "pso"), default="ce",
                   help="global search: Cross-Entropy or particle swarm")
    s.add_argument("--objective", choices=("sse", "max_rel"), default="sse",
                   help="car2d: sum of squared relative errors or the largest relative error")
    s.add_argument("--runs", type=int, default=10, help="car2d: independent search runs, averaged")
    s.add_argument("--particles", type=int, default=1000, help="box model: swarm size (RTRI seed: 1000)")
    s.add_argument("--iterations", type=int, default=1000, help="box model: iteration cap (RTRI seed: 1000)")
    s.add_argument("--stop-pct", type=float, default=0.5, help="box model: stop at this evaluation value [%%]")
    s.add_argument("--swarms", type=int, default=None,
                   help="box model: split the particles into this many independent swarms, each refined as it "
                        "ends, the best kept; with --refine no further swarm once one ends within the done "
                        f"error (default: {TYPED_SWARMS} swarms with --targets, done at the stop; "
                        f"{CAMPAIGN_SWARMS} swarms with a campaign, done at {CAMPAIGN_DONE_PCT:g} %%)")
    s.add_argument("--refine", action="store_true",
                   help="constrained refinement (CasADi/IPOPT) after the search")
    s.add_argument("--factors", default=None, metavar="SET",
                   help="box model: the factor set searched, grouped or credible (default: credible with "
                        "--targets, grouped with a campaign, the truth simulator's factors)")
    s.add_argument("--seed", type=_seed, default=0, help="seed of the search")
    s.add_argument("--out", required=True, help="calibration JSON to write")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _allow_outside_option(s)
    s.set_defaults(func=cmd_calibrate)

    s = sub.add_parser("validate", help="simulate the runs over the track recording and compare")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--calibration", required=True, help="JSON from railcal calibrate")
    s.add_argument("--out", required=True, help="JSON result to write (the plot goes beside it, .png)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _allow_outside_option(s)
    s.set_defaults(func=cmd_validate)

    s = sub.add_parser("diagnose", help="find what the model gets wrong on a campaign, name the cause, "
                       "extend the model and measure the gain")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--out", required=True, help="JSON to write (plots go beside it)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _allow_outside_option(s)
    s.set_defaults(func=cmd_diagnose)

    s = sub.add_parser("export-fmu", help="build an FMI co-simulation FMU of a calibrated model")
    s.add_argument("--calibration", required=True, help="JSON from railcal calibrate")
    s.add_argument("--fmi-version", type=int, choices=(2, 3), default=2, help="FMI version of the FMU")
    s.add_argument("--track", default=None, help="track recording CSV (distance, level) for stand-alone running "
                   "(default: none, the rail inputs come from the importer)")
    s.add_argument("--campaign", default=None,
                   help="campaign whose accelerometers become extra outputs (default: none)")
    s.add_argument("--cutoff-hz", type=float, default=None,
                   help="box model: carbody modes kept below this [Hz] (default: 100), the rest statically corrected")
    s.add_argument("--out", required=True, help="the .fmu to write")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    _allow_outside_option(s)
    s.set_defaults(func=cmd_export_fmu)

    s = sub.add_parser("crosscheck", help="exudyn re-computation against railcal's model and its FMU")
    s.add_argument("--calibration", required=True, help="JSON from railcal calibrate")
    s.add_argument("--track", default=None, help="track recording CSV (distance, level) (default: a synthetic "
                   "track, German low-disturbance spectrum, 3-70 m)")
    s.add_argument("--profile", dest="track", action=_DeprecatedAlias, replacement="--track",
                   help="deprecated name of --track")
    s.add_argument("--speed", type=float, default=40.0, help="running speed [m/s]")
    s.add_argument("--duration", type=float, default=10.0,
                   help="[s] of simulated time (the wall time is reported beside the verdict, not judged)")
    s.add_argument("--no-fmu", action="store_true", help="leave the FMU out (no C compiler)")
    s.add_argument("--out", required=True, help="JSON result to write (car2d: the plot goes beside it, .png)")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.set_defaults(func=cmd_crosscheck)

    s = sub.add_parser("demo", help="the whole job on the built-in example")
    s.add_argument("--out", default="demo_output", help="folder to write the demo's results into")
    s.add_argument("--full", action="store_true",
                   help="the published methods' sizes (10 journeys over 40 km, the seed's 1000 particles, the "
                        "full-order box model; much longer); default: off, the quick demo")
    s.add_argument("--quiet", action="store_true", help="no progress on stderr")
    s.set_defaults(func=cmd_demo)
    return p


def main(argv=None) -> int:
    # figures are files here, never windows; set for this process only, not by the library modules
    os.environ.setdefault("MPLBACKEND", "Agg")
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (InputError, ParameterError) as e:
        print(f"railcal: error: {e}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print("railcal: interrupted", file=sys.stderr)
        return EXIT_INTERNAL
    except Exception:  # an internal failure: say so, with the traceback for a bug report
        traceback.print_exc()
        print("railcal: internal error (exit 1); please report the traceback above", file=sys.stderr)
        return EXIT_INTERNAL


if __name__ == "__main__":
    sys.exit(main())
