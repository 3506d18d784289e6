"""The ``railcal`` command line (shared/spec/interfaces.md).

Every command prints a one-line summary, writes JSON with ``--out``, exits 0 on success,
2 on bad input (the message names the file, key or column), 1 on internal failure.
Progress goes to stderr unless ``--quiet``.
"""
from __future__ import annotations

import argparse
import os
import sys
import traceback
from contextlib import nullcontext
from pathlib import Path

from calibration.data.errors import InputError
from calibration.data.outputs import check_campaign_output, check_outputs, write_result
from calibration.models.parameters import ParameterError
from calibration.swarm_defaults import CAMPAIGN_DONE_PCT, CAMPAIGN_SWARMS, TYPED_SWARMS

from .common import (EXIT_INPUT, EXIT_INTERNAL, EXIT_OK, about_calibration, campaign_of, names, progress_for,
                     read_calibration, track_for_crosscheck)
from .registry import MODELS, model_for_campaign, model_named, model_of_calibration
from .synth import cmd_synth_excitation, cmd_synth_in_service


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


def _finish(parser, func, *, reads_campaign: bool = False) -> None:
    """What every subcommand takes last: --quiet, --allow-outside where it reads a campaign,
    and the function that runs it."""
    parser.add_argument("--quiet", action="store_true", help="no progress on stderr")
    if reads_campaign:
        parser.add_argument("--allow-outside", action="store_true",
                            help="read run and track files that are links resolving outside the campaign folder "
                                 "(refused by default: a campaign is read from its own folder only)")
    parser.set_defaults(func=func)


# ------------------------------------------------------------------- model commands
def cmd_identify(args) -> int:
    campaign = campaign_of(args)
    model = model_for_campaign(campaign)
    png = Path(args.plot) if args.plot else Path(args.out).with_suffix(".png")
    second = png.with_name(png.stem + model.identification_figure + ".png")
    check_outputs([args.out, png, second], inputs=[args.campaign, _truth_path(args.campaign)])
    print(model.identify(campaign, args, png, second))
    return EXIT_OK


def cmd_modes(args) -> int:
    """Eigen-analysis of a model: every mode with a unique ``label`` and its spec v1
    ``family`` (``bogie_bounce_in_phase`` and ``bogie_bounce_anti_phase`` are both of
    family ``bogie_bounce``)."""
    model = model_named(args.model)
    if args.out:
        check_outputs([args.out])
    out = model.modes(args)
    if args.out:
        write_result(args.out, out, "modes")
    wrote = f"; wrote {args.out}" if args.out else ""
    print("; ".join(f"{m['label']} {m['frequency_hz']:.3f} Hz" for m in out["modes"]) + wrote)
    return EXIT_OK


def cmd_calibrate(args) -> int:
    model = model_named(args.model)
    png = Path(args.out).with_suffix(".png")
    check_outputs([args.out, png, *(png.with_name(png.stem + s + ".png") for s in model.calibration_figures)],
                  inputs=[args.campaign, args.targets, args.priors, args.identification])
    if args.campaign is not None and args.priors is not None:
        raise InputError("a campaign brings its own [priors.NAME]; --priors goes with --targets", key="--priors")
    if args.identification is not None and args.campaign is None:
        raise InputError("--identification is a campaign's identification; give the CAMPAIGN too", key="--identification")
    print(model.calibrate(args))
    return EXIT_OK


def _model_for(campaign, calibration: dict, path):
    """The calibration's model, which must be the one the campaign's kind calibrates."""
    model = model_of_calibration(calibration, path)
    if model.campaign_kind != campaign.meta.kind:
        expected = model_for_campaign(campaign)
        raise InputError(f"a {campaign.meta.kind} campaign goes with a {expected.name} calibration, not "
                         f"{model.name} (model = {expected.name})", path=Path(path), key="model")
    return model


def cmd_validate(args) -> int:
    path = Path(args.calibration)
    campaign = campaign_of(args)
    png = Path(args.out).with_suffix(".png")
    figures = [png] + [png.with_name(png.stem + s + ".png") for s in model_for_campaign(campaign).validation_figures]
    check_outputs([args.out, *figures], inputs=[args.campaign, path])
    calibration = read_calibration(path)
    model = _model_for(campaign, calibration, path)
    with about_calibration(path):
        print(model.validate(campaign, calibration, args, figures))
    return EXIT_OK


def cmd_diagnose(args) -> int:
    campaign = campaign_of(args)
    model = model_for_campaign(campaign)
    out_path = Path(args.out)
    stem = out_path.with_suffix("")
    figures = [stem.with_name(stem.name + suffix + ".png") for suffix in model.diagnosis_figures]
    path = Path(args.calibration) if args.calibration else None
    check_outputs([out_path, *figures], inputs=[args.campaign, *([path] if path else [])])
    calibration = None if path is None else read_calibration(path)
    if calibration is not None:
        _model_for(campaign, calibration, path)
    with about_calibration(path) if path else nullcontext():
        diagnosis = model.diagnose(campaign, progress_for(args), calibration, path)
    plots = [str(p) for p in diagnosis.plot(stem)]
    write_result(out_path, {**diagnosis.to_json(), "plots": plots}, "diagnosis")
    if not args.quiet:  # the evidence in full; the summary line stays one line
        for line in diagnosis.summary:
            print(f"  {line}", file=sys.stderr)
    sure = diagnosis.confidence
    print(f"cause: {diagnosis.cause}{f' (confidence {sure})' if sure else ''}; wrote {names(out_path, *plots)}")
    return EXIT_OK


def cmd_export_fmu(args) -> int:
    from fmu_src.build import BuildError
    from fmu_src.export import export_fmu

    check_outputs([args.out, args.check], inputs=[args.calibration, args.track, args.campaign])
    calibration = read_calibration(args.calibration)
    model = model_of_calibration(calibration, args.calibration)
    campaign = campaign_of(args) if args.campaign else None
    try:
        with about_calibration(args.calibration):
            built = export_fmu(calibration, args.fmi_version, Path(args.out), spec_for=model.fmu_spec,
                               track=args.track, campaign=campaign, cutoff_hz=args.cutoff_hz)
    except ParameterError as e:
        raise InputError(str(e), path=Path(args.calibration), key="parameters") from None
    except BuildError as e:
        print(f"railcal: cannot build the FMU: {e}", file=sys.stderr)
        return EXIT_INTERNAL
    checked = ""
    if args.check:
        from fmu_src.checks import check_fmu

        record = check_fmu(built.path)
        write_result(args.check, record, "fmu-check")
        agree = record.get("fmpy_vs_libcosim")
        checked = (f"; checks {record['verdict']} (fmpy validate, fmutool"
                   + (f", fmpy vs libcosim {agree['worst']:.1e}" if agree and agree["worst"] is not None else "")
                   + f"), wrote {args.check}")
    print(f"FMI {built.fmi_version} co-simulation FMU with binaries for {', '.join(built.platforms)}"
          f"{' and a stand-alone track' if args.track else ''}: wrote {built.path}{checked}")
    return EXIT_OK


def cmd_infer_track(args) -> int:
    path = Path(args.calibration)
    campaign = campaign_of(args)
    out = Path(args.out)
    if out.suffix.lower() != ".csv":
        raise InputError(f"the profile is a CSV file: give --out with .csv, got {out.name!r}", key="--out")
    if not 0.05 <= args.step <= 1.0:
        raise InputError(f"--step must be within 0.05-1 m (D1 reaches 3 m wavelengths), got {args.step}",
                         key="--step")
    files = {"csv": out, "d2": out.with_name(out.stem + "_d2.csv"), "json": out.with_suffix(".json"),
             "png": out.with_suffix(".png")}
    check_outputs(list(files.values()), inputs=[args.campaign, path, args.compare, _truth_path(args.campaign)])
    calibration = read_calibration(path)
    model = _model_for(campaign, calibration, path)
    if model.infer_track is None:
        raise InputError(f"the {model.name} model's campaigns do not run over a track", path=path, key="model")
    with about_calibration(path):
        print(model.infer_track(campaign, calibration, args, files))
    return EXIT_OK


def cmd_crosscheck(args) -> int:
    calibration = read_calibration(args.calibration)
    model = model_of_calibration(calibration, args.calibration)
    png = Path(args.out).with_suffix(".png") if model.crosscheck_figure else None
    check_outputs([args.out, png], inputs=[args.calibration, args.track])
    if not (args.speed > 0 and args.duration > 0):
        raise InputError("--speed and --duration must be positive", key="--speed")
    distance, level = track_for_crosscheck(args)
    try:
        with about_calibration(args.calibration):
            report, summary = model.crosscheck(calibration, distance, level, args, png)
    except InputError:
        raise
    except ValueError as e:  # the track does not suit the run (too short for the vehicle and duration)
        raise InputError(str(e), path=Path(args.track) if args.track else None) from None
    write_result(args.out, report, "crosscheck")
    print(f"{summary}; verdict {report['verdict']} (wall time {report['wall_time_s']:.1f} s, not judged); wrote "
          f"{names(args.out, report.get('plot'))}")
    return EXIT_OK


# ------------------------------------------------------------------------------- run
def cmd_run(args) -> int:
    from railcal.run import run_campaign

    campaign = campaign_of(args)
    model = args.model or model_for_campaign(campaign).name
    say = (lambda msg: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    record = run_campaign(campaign, Path(args.out), model=model, pdf=not args.no_pdf, say=say,
                          criteria_path=args.criteria)
    done = [s["name"] for s in record["steps"] if s["status"] == "done"]
    failed = [f"{s['name']} ({s['reason']})" for s in record["steps"] if s["status"] == "failed"]
    skipped = {}
    for s in record["steps"]:
        if s["status"] == "skipped":
            skipped.setdefault(s["reason"], []).append(s["name"])
    skips = "".join(f"; skipped {','.join(names)}: {why}" for why, names in skipped.items())
    print(f"run of {campaign.root} with {model}: {len(done)} steps done"
          f"{'; not done: ' + '; '.join(failed) if failed else ''}{skips}; wrote {args.out}")
    return EXIT_INPUT if record["stopped_at"] else EXIT_OK


# ------------------------------------------------------------------------------- report
def cmd_report(args) -> int:
    from railcal.report.build import write_report

    html, pdf, steps = write_report(args.folder, pdf=args.pdf, criteria_path=args.criteria)
    print(f"report of {', '.join(steps)}: wrote {names(html, pdf)}")
    return EXIT_OK


# ------------------------------------------------------------------------------- demo
def cmd_demo(args) -> int:
    from railcal.demo import CAMPAIGNS, RESULTS, run_demo

    out = Path(args.out)
    if os.path.lexists(out) and not out.is_dir():
        raise InputError("exists and is not a folder; --out takes the folder to write the demo into", path=out,
                         key="--out")
    # the demo replaces its own campaigns there: refuse before any work if one is not railcal's
    for name in CAMPAIGNS.values():
        check_campaign_output(out / name, overwrite=True)
    summary = run_demo(Path(args.out), progress=progress_for(args), full=args.full)
    print(f"demo finished: {summary} (the answers against the truth); each campaign's results and sign-off "
          f"report in {', '.join(str(out / r) for r in RESULTS.values())}")
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
        _finish(s, func)
        return s

    s = synth_parser("in-service", "in-service journeys (bogie and axle-box sensors)", cmd_synth_in_service)
    s.add_argument("--journeys", type=int, default=10, help="number of journeys (run files)")
    s.add_argument("--length-km", type=float, default=40.0, help="length of the line [km]")
    s.add_argument("--carbody-sensors", action="store_true",
                   help="add floor accelerometers above both bogies and at the car centre")
    s.add_argument("--truth", choices=("railcal", "exudyn"), default="railcal",
                   help="the simulator: railcal's own 2D car (default) or the independent exudyn truth "
                        "(flexible carbody, nonlinear suspension, discretely supported track)")
    s.add_argument("--vehicle", default=None, help="vehicle of the exudyn truth's library (default intercity; "
                   "the library and its sources: docs/methods/truth-independent.md); --truth exudyn only")
    s.add_argument("--dip", action="append", default=None, metavar="CENTRE_M:DEPTH_MM:LENGTH_M",
                   help="a settled dip in the line's level: a raised cosine of that centre [m], depth [mm] and "
                        "length [m]; repeatable (default: none); --truth exudyn only")
    s.add_argument("--line-seed", type=_seed, default=None, help="the line's own seed, so that campaigns of other "
                   "seeds run over the same line (default: the campaign's seed draws it); --truth exudyn only")
    s = synth_parser("excitation", "stationary excitation test (exciter force and floor accelerometers)",
                     cmd_synth_excitation)
    s.add_argument("--duration", type=float, default=600.0, help="total recording [s], split over the runs")
    s.add_argument("--runs", type=int, default=2, help="number of test runs (run files)")
    s.add_argument("--truth", choices=("railcal", "exudyn"), default="railcal",
                   help="the simulator: railcal's box model (default) or the independent exudyn truth (a shell "
                        "finite element carbody with window openings, on two bogies)")

    s = sub.add_parser("identify", help="modal identification of a campaign")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--out", required=True, help="JSON result to write")
    s.add_argument("--plot", default=None, help="PNG of the identification; a second figure goes beside it "
                   "(default: --out with .png)")
    s.add_argument("--seed", type=_seed, default=0, help="seed of the random segment draw")
    _finish(s, cmd_identify, reads_campaign=True)

    s = sub.add_parser("modes", help="eigen-analysis of a model")
    s.add_argument("--model", choices=tuple(MODELS), default="car2d",
                   help="model to analyse: the 2D car or the box-type vehicle (Shinkansen-type carbody)")
    s.add_argument("--vehicle", choices=("intercity", "manchester"), default="intercity",
                   help="base parameter set: the seed's intercity trailer or the Manchester benchmark coach")
    s.add_argument("--param", action="append", metavar="NAME=VALUE",
                   help="set one parameter [SI units] (box: a stiffness factor, nominal 1), repeatable (default: "
                        "none, the --vehicle set as it is)")
    s.add_argument("--max-hz", type=float, default=25.0, help="box model: modes below this [Hz]")
    s.add_argument("--out", default=None, help="JSON result to write (default: none, the summary only)")
    _finish(s, cmd_modes)

    s = sub.add_parser("calibrate", help="parameters from target frequencies (global search + identifiability)")
    s.add_argument("campaign", nargs="?", default=None,
                   help="campaign folder to identify and calibrate to (or give --targets)")
    s.add_argument("--targets", default=None, help="TOML with [[targets]] label, frequency_hz (default: none; give this or a "
                   "CAMPAIGN)")
    s.add_argument("--priors", default=None,
                   help="with --targets: TOML with [NAME] nominal, low, high (default: with --model car2d --method "
                        "ce the in-service seed's Table 7 ranges of the intercity trailer car; --method pso needs "
                        "this file; with --model box each factor's own range); a campaign brings its own priors")
    s.add_argument("--identification", default=None, metavar="F",
                   help="with a CAMPAIGN: its identification made before (railcal identify --out F), calibrated "
                        "to as it is instead of identifying again; refused if made from other files (default: "
                        "none, identify the campaign first)")
    s.add_argument("--model", choices=tuple(MODELS), default="car2d", help="model to calibrate")
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
                   help="box model: the factor set searched, grouped, credible, windowed (credible and the "
                        "side walls' shear beyond their windows; a campaign's [vehicle] windowed_length) or "
                        "orthotropic (windowed, and the roof's, floor's and sides' rigidity across apart) (default: "
                        "credible with --targets, grouped with a campaign); a campaign's [priors] must name "
                        "factors of the set, and a factor without one is searched over the set's own range")
    s.add_argument("--panel-order-change", type=int, default=0, metavar="N",
                   help="box model with a campaign: add N to every panel's shape-function order (negative: a "
                        "coarser, faster model; the file records it, and every later step rebuilds the same "
                        "model) (default: 0, the full-order model)")
    s.add_argument("--seed", type=_seed, default=0, help="seed of the search")
    s.add_argument("--out", required=True, help="calibration JSON to write")
    _finish(s, cmd_calibrate, reads_campaign=True)

    s = sub.add_parser("validate", help="simulate the runs over the track recording and compare")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--calibration", required=True, help="JSON from railcal calibrate")
    s.add_argument("--out", required=True, help="JSON result to write (the plot goes beside it, .png)")
    _finish(s, cmd_validate, reads_campaign=True)

    s = sub.add_parser("infer-track", help="the track's longitudinal level under the leading bogie, inferred from "
                       "the vehicle's response")
    s.add_argument("campaign", help="in-service campaign folder")
    s.add_argument("--calibration", required=True, help="JSON from railcal calibrate (or diagnose's extended model)")
    s.add_argument("--out", required=True, help="profile CSV to write (D1; D2 as OUT_d2.csv where the data allows; "
                   "the summary as OUT.json and the figure as OUT.png beside it)")
    s.add_argument("--axle-boxes", action="store_true", help="use the leading bogie's axle boxes too (default: the "
                   "bogie's accelerometer and gyro only)")
    s.add_argument("--compare", default=None, help="an earlier profile CSV of the same line (infer-track's D1): "
                   "report the dips and rises between the two (default: none)")
    s.add_argument("--step", type=float, default=0.25, help="distance step of the profile [m] (default 0.25)")
    _finish(s, cmd_infer_track, reads_campaign=True)

    s = sub.add_parser("diagnose", help="find what the model gets wrong on a campaign, name the cause, "
                       "extend the model and measure the gain")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--calibration", help="JSON from railcal calibrate: the baseline the diagnosis starts from "
                   "(default: the campaign's priors; a campaign without priors needs it)")
    s.add_argument("--out", required=True, help="JSON to write (plots go beside it)")
    _finish(s, cmd_diagnose, reads_campaign=True)

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
    s.add_argument("--check", default=None, metavar="F.json",
                   help="also check the FMU built (fmpy's validation, fmutool's checks, the same run in fmpy and "
                        "libcosim) and write the record to F.json (default: none)")
    _finish(s, cmd_export_fmu, reads_campaign=True)

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
    _finish(s, cmd_crosscheck)

    s = sub.add_parser("run", help="the whole job on a campaign: identify, calibrate, validate, diagnose, FMUs, "
                       "cross-checks and the report; resumable")
    s.add_argument("campaign", help="campaign folder")
    s.add_argument("--out", required=True, help="folder to write every step's results, the FMUs and the report into")
    s.add_argument("--model", choices=tuple(MODELS), default=None,
                   help="model (default: car2d in service, box for an excitation test)")
    s.add_argument("--no-pdf", action="store_true", help="the HTML report only")
    s.add_argument("--criteria", default=None, metavar="C.toml",
                   help="acceptance criteria for the report (default: railcal's, listed in docs/cli.md)")
    _finish(s, cmd_run, reads_campaign=True)

    s = sub.add_parser("report", help="the engineering sign-off report of a results folder (HTML, and PDF)")
    s.add_argument("folder", help="folder holding the steps' JSON results (identification.json, calibration.json, "
                   "validation.json, diagnosis.json, crosscheck.json) and their figures")
    s.add_argument("--pdf", action="store_true", help="also write report.pdf")
    s.add_argument("--criteria", default=None, metavar="C.toml",
                   help="acceptance criteria ([[criterion]] tables; default: railcal's, listed in docs/cli.md)")
    _finish(s, cmd_report)

    s = sub.add_parser("demo", help="the whole job on the built-in example")
    s.add_argument("--out", default="demo_output", help="folder to write the demo's results into")
    s.add_argument("--full", action="store_true",
                   help="the published methods' sizes (10 journeys over 40 km, the seed's 1000 particles, the "
                        "full-order box model; much longer); default: off, the quick demo")
    _finish(s, cmd_demo)
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
