"""The 2D car (in-service seed) in the commands: what `identify`, `modes`, `calibrate`,
`validate`, `crosscheck`, `infer-track` and `export-fmu` do for it. Each function writes the command's
files and returns its one-line summary; the registry (:mod:`railcal.registry`) picks it."""
from __future__ import annotations

from pathlib import Path

from calibration.data.errors import InputError
from calibration.data.outputs import write_result
from calibration.models.car2d import (CarExtras, carbody_centre, extras_from_json, extras_to_json,
                                      sensor_model_from_json)
from calibration.models.parameters import CAR_PARAMETER_SPECS, CarParameters, ParameterError

from .common import campaign_of, names, progress_for, read_identification, write_calibration


def parameters(calibration: dict, path) -> CarParameters:
    """The car's parameters of a calibration file, or exit 2 naming the file."""
    try:
        return CarParameters.from_mapping(calibration["parameters"])
    except ParameterError as e:
        raise InputError(str(e), path=Path(path), key="parameters") from None


def extras(calibration: dict, path) -> CarExtras:
    """The additions to the seed's car a calibration file carries (``extras``: the extended
    model a diagnosis writes), or exit 2 naming the file."""
    try:
        return extras_from_json(calibration.get("extras") or {})
    except ValueError as e:
        raise InputError(str(e), path=Path(path), key="extras") from None


def sensor_model(calibration: dict, path) -> tuple[float, float]:
    """(bogie_dx [m], gyro_gain) of a calibration file's ``sensor_model``, or exit 2 naming
    the file."""
    try:
        return sensor_model_from_json(calibration.get("sensor_model"))
    except ValueError as e:
        raise InputError(str(e), path=Path(path), key="sensor_model") from None


def identify(campaign, args, png: Path, second: Path) -> str:
    from calibration.identification.fdd import FDDSettings
    from calibration.identification.in_service import IdentifySettings, identify_in_service

    settings = IdentifySettings(fdd=FDDSettings(seed=args.seed))
    result = identify_in_service(campaign, settings=settings, progress=progress_for(args))
    out = {**result.to_json(), "campaign_sha256": campaign.fingerprint()}
    png, spectra = result.plot(png, second)
    out["plot"] = str(png)
    out["plot_spectra"] = None if spectra is None else str(spectra)
    write_result(args.out, out, "identification")
    modes = ", ".join(f"{m.label} {m.frequency_hz:.3f} Hz" for m in result.modes)
    open_ = "".join(f"; {u.label} not determined" for u in result.undetermined)
    return (f"identified {len(result.modes)} modes ({modes}){open_}; {len(result.rejected_peaks)} peaks rejected; "
            f"{out['data']['gaps']} gaps in {len(result.runs)} runs reported; wrote {names(args.out, png, spectra)}")


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


def modes(args) -> dict:
    """The --vehicle car with ``--param NAME=VALUE`` changes: undamped modes with the damped
    ones' ratios and frequencies beside them."""
    from calibration.models.car2d import build_car, damped_modes, undamped_modes
    from calibration.models.vehicles import VEHICLES

    p = VEHICLES[args.vehicle].replace(**_parse_params(args.param))
    asm = build_car(p)
    damped = {m.name: m for m in damped_modes(asm)}
    rows = []
    for m in undamped_modes(asm):  # both analyses name a mode by its shape alike
        d = damped.get(m.name)
        rows.append({"label": m.name, "family": m.label, "frequency_hz": m.frequency_hz,
                     "damping_ratio": None if d is None else d.damping_ratio,
                     "damped_frequency_hz": None if d is None else d.damped_frequency_hz})
    return {"model": "car2d", "vehicle": args.vehicle, "parameters": p.as_dict(), "modes": rows}


def calibrate(args) -> str:
    from calibration.calibrate import DEFAULT_SEARCH, calibrate_campaign, calibrate_car, read_priors, read_targets

    if args.method == "pso" and args.targets is not None and args.priors is None:
        raise InputError("--method pso searches within a range for every parameter and there is no default "
                         "for the 2D car (the seed's Table 7 gives no range for J_v and J_b): give the ranges "
                         "with --priors P.toml ([NAME] nominal, low, high)", key="--priors")
    if args.runs < 1:
        raise InputError(f"--runs must be >= 1, got {args.runs}", key="--runs")
    if args.panel_order_change:
        raise InputError("--panel-order-change is the box model's; the 2D car has no panels",
                         key="--panel-order-change")
    if (args.campaign is None) == (args.targets is None):
        raise InputError("give either a CAMPAIGN or --targets T.toml", key="CAMPAIGN / --targets")
    if args.campaign is not None:
        campaign = campaign_of(args)
        identified = None
        if args.identification is not None:
            from calibration.identification.in_service import identified_modes_from_json

            identified = read_identification(args.identification, campaign, identified_modes_from_json)
        result, modes = calibrate_campaign(campaign, method=args.method, objective=args.objective,
                                           runs=args.runs, seed=args.seed, refine_result=args.refine,
                                           identified=identified, progress=progress_for(args))
        out = result.to_json()
        out["identified_modes"] = [m.to_json() for m in modes]
        figures = write_calibration(out, args.out)
        n = len(result.targets)
        return (f"calibrated to {n} identified mode{'s' * (n != 1)} ({', '.join(result.targets)}): "
                f"max error {result.max_error_pct:.3g} %; "
                f"{result.identifiability['summary']}; wrote {names(args.out, *figures)}")
    targets = read_targets(args.targets)
    search = read_priors(args.priors) if args.priors else DEFAULT_SEARCH
    result = calibrate_car(targets, search, method=args.method, objective=args.objective, runs=args.runs,
                           seed=args.seed, refine_result=args.refine)
    figures = write_calibration(result.to_json(), args.out)
    refined = ""
    if result.refinement is not None:
        refined = (" after CasADi refinement" if result.refinement["improved"]
                   else " (refinement did not improve; global result kept)")
    within = "" if args.priors else " within the seed's Table 7 ranges (intercity trailer car)"
    return (f"{args.method} x {args.runs} runs{within}{refined}: max error {result.max_error_pct:.3g} %; "
            f"{result.identifiability['summary']}; wrote {names(args.out, *figures)}")


def validate(campaign, calibration: dict, args, figures) -> str:
    from calibration.validation.in_service import validate as validate_runs

    p = parameters(calibration, args.calibration)
    bogie_dx, gyro_gain = sensor_model(calibration, args.calibration)
    result = validate_runs(campaign, p, extras=extras(calibration, args.calibration), bogie_dx=bogie_dx,
                           gyro_gain=gyro_gain, progress=progress_for(args))
    png = result.plot(figures[0])
    runs_png = result.plot_runs(figures[1])
    out = result.to_json()
    out["plot"], out["plots"] = str(png), [runs_png.name]
    write_result(args.out, out, "validation")
    summary = "; ".join(f"{k}: NRMSE {v['nrmse']:.3f}, PSD {v['psd_log_error_db']:.2f} dB"
                        for k, v in out["channels"].items())
    comfort = ", ".join(f"{pos} {c['model']['n_mv_z']:.2f}" + ("" if c["measured"] is None else
                                                                  f" (measured {c['measured']['n_mv_z']:.2f})")
                        for pos, c in out["ride_comfort"].items())
    comfort = f"; ride comfort, the vertical part of N_MV over the recording: {comfort}" if comfort else ""
    return (f"validated over {result.track} ({len(result.runs)} runs, band {result.band_m[0]:g}-"
            f"{result.band_m[1]:g} m): {summary}{comfort}; wrote {names(args.out, png, runs_png)}")


def infer_track(campaign, calibration: dict, args, files: dict) -> str:
    """``railcal infer-track``: the level under the leading bogie, D1 at ``files['csv']``, D2
    beside it where the data allows, the JSON summary and the figure."""
    from calibration.data.tracks import read_track_file
    from calibration.track_inference.infer import InferSettings, compare, infer_track as infer
    from calibration.track_inference.kalman import KalmanSettings
    from calibration.track_inference.plots import plot_profile

    p = parameters(calibration, args.calibration)
    bogie_dx, gyro_gain = sensor_model(calibration, args.calibration)
    earlier = read_track_file(Path(args.compare)) if args.compare else None
    if earlier is not None and earlier.band != "D1":
        raise InputError(f"--compare needs a D1 profile (infer-track's own CSV), got band {earlier.band!r}",
                         path=Path(args.compare), key="band")
    settings = InferSettings(kalman=KalmanSettings(step=args.step), axle_boxes=args.axle_boxes)
    result = infer(campaign, p, extras=extras(calibration, args.calibration), bogie_dx=bogie_dx,
                   gyro_gain=gyro_gain, settings=settings, progress=progress_for(args))
    if earlier is not None:
        try:
            result = compare(result, earlier.distance, earlier.level)
        except ValueError as e:
            raise InputError(str(e), path=Path(args.compare)) from None
    s = result.section
    out = result.to_json()
    out["campaign_sha256"] = campaign.fingerprint()
    out["plot"] = str(plot_profile(result, files["png"]))
    written = [write_profile(files["csv"], s.distance, s.level["D1"], s.std["D1"], s.passes["D1"], "D1")]
    usable = result.d2_usable()[0]
    if usable:
        written.append(write_profile(files["d2"], s.distance, s.level["D2"], s.std["D2"], s.passes["D2"], "D2"))
    else:  # an earlier run's D2 beside this summary would be taken for this run's
        Path(files["d2"]).unlink(missing_ok=True)
    out["profile"], out["profile_d2"] = str(files["csv"]), str(files["d2"]) if usable else None
    write_result(files["json"], out, "track-profile")  # last: a summary means every file it names is there
    d1 = out["bands"]["D1"]
    found = ""
    if result.changes is not None:
        found = "; changes against " + str(args.compare) + ": " + (", ".join(
            f"{'dip' if c.depth > 0 else 'rise'} of {abs(1e3 * c.depth):.2g} mm over {c.length:g} m at {c.centre:.1f} m"
            for c in result.changes) or "none")
    return (f"inferred the D1 level over {d1['from_m']:.0f}-{d1['to_m']:.0f} m from {len(result.passes)} pass"
            f"{'es' * (len(result.passes) != 1)} ({', '.join(result.sensors)}): rms {d1['level_rms_mm']:.3g} mm, "
            f"standard deviation {d1['std_median_mm']:.2g} mm (median); D2 {'written' if usable else 'not written'}"
            f"{found}; wrote {names(*written, files['json'], out['plot'])}")


def write_profile(path, distance, level, std, passes, band: str) -> Path:
    """A profile CSV in the campaign format's track-file form (``# band``, ``distance``,
    ``level``) with ``level_std`` and ``passes``: only where a pass covers it."""
    from calibration.data.outputs import write_atomic, write_csv

    ok = passes > 0
    cols = {"distance": distance[ok], "level": level[ok], "level_std": std[ok], "passes": passes[ok]}

    def write(f):
        f.write(f'# band = "{band}"\n'.encode())
        write_csv(f, cols)

    return write_atomic(path, write)


def crosscheck(calibration: dict, distance, level, args, png: Path | None) -> tuple[dict, str]:
    """The exudyn cross-check over (distance, level) [m]: the report and its summary."""
    from .crosscheck import crosscheck_car

    p, added = parameters(calibration, args.calibration), extras(calibration, args.calibration)
    sensor_model(calibration, args.calibration)  # unused here, but a malformed file is refused whole
    try:
        carbody_centre(p, added)
    except ValueError as e:
        raise InputError(str(e), path=Path(args.calibration), key="extras") from None
    report = crosscheck_car(p, distance, level, speed=args.speed, duration=args.duration, with_fmu=not args.no_fmu,
                            plot=png, extras=added)
    e, t = report["eigen"], report["time"]
    shown = sorted(extras_to_json(added))
    extended = f" (extended model: {', '.join(shown)})" if shown else ""
    return report, (f"exudyn vs railcal{extended}: eigenfrequencies {e['undamped']['max_relative_error']:.1e}, damped "
                    f"eigenvalues {e['damped']['max_relative_error']:.1e}; {t['duration_s']:g} s at "
                    f"{t['speed_m_s']:g} m/s worst NRMSE {t['worst_nrmse']:.1e} (exudyn, railcal"
                    f"{'' if args.no_fmu else ', FMU'})")
