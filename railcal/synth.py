"""``railcal synth``: synthetic campaigns and their truth. With the demo, the only part of
the application that imports the truth simulators (calibration/truth)."""
from __future__ import annotations

import math

from calibration.data.errors import InputError
from calibration.data.outputs import check_campaign_output

from .common import EXIT_OK, progress_for


def cmd_synth_in_service(args) -> int:
    from calibration.truth.effects import parse_effect
    from calibration.truth.in_service import InServiceSettings, synth_in_service
    from calibration.truth.track import LineSpec

    if args.journeys < 1:
        raise InputError(f"--journeys must be >= 1, got {args.journeys}", key="--journeys")
    if not 5.0 <= args.length_km <= 500.0:
        raise InputError(f"--length-km must be within 5..500 km, got {args.length_km}", key="--length-km")
    if getattr(args, "truth", "railcal") == "exudyn":
        return _synth_in_service_exudyn(args)
    if args.vehicle is not None:
        raise InputError("--vehicle chooses a vehicle of the exudyn truth; give --truth exudyn", key="--vehicle")
    if args.dip:
        raise InputError("--dip settles a dip in the exudyn truth's line; give --truth exudyn", key="--dip")
    if args.line_seed is not None:
        raise InputError("--line-seed draws the exudyn truth's line; give --truth exudyn", key="--line-seed")
    effect = parse_effect(args.effect, "in_service")
    check_campaign_output(args.out, overwrite=args.force)
    settings = InServiceSettings(journeys=args.journeys, line=LineSpec(length=args.length_km * 1000.0),
                                 carbody_sensors=args.carbody_sensors)
    truth = synth_in_service(args.out, seed=args.seed, settings=settings, effect=effect, fmt=args.format,
                             overwrite=args.force, progress=progress_for(args))
    f = truth["frequencies_hz"]
    print(f"wrote {args.out} ({args.journeys} journeys x {args.length_km:g} km) and {args.out}.truth.json; "
          + ", ".join(f"{k} {v:.3f} Hz" for k, v in f.items()))
    return EXIT_OK


def _synth_in_service_exudyn(args) -> int:
    """``synth in-service --truth exudyn``: the independent exudyn truth."""
    from calibration.truth.independent import VEHICLES, IndependentSettings, parse_hidden, \
        synth_in_service_independent
    from calibration.truth.independent.irregularity import LineSpec

    name = args.vehicle or "intercity"
    if name not in VEHICLES:
        raise InputError(f"unknown vehicle {name!r}; the exudyn truth's library has {', '.join(VEHICLES)}",
                         key="--vehicle")
    effect = parse_hidden(args.effect)
    dips = _parse_dips(args.dip or (), args.length_km * 1000.0)
    check_campaign_output(args.out, overwrite=args.force)
    settings = IndependentSettings(journeys=args.journeys, line=LineSpec(length=args.length_km * 1000.0, dips=dips),
                                   carbody_sensors=args.carbody_sensors, line_seed=args.line_seed)
    truth = synth_in_service_independent(args.out, seed=args.seed, settings=settings, effect=effect, vehicle=name,
                                         fmt=args.format, overwrite=args.force, progress=progress_for(args))
    f = truth["frequencies_hz"]
    print(f"wrote {args.out} ({args.journeys} journeys x {args.length_km:g} km, exudyn truth, {name}) and "
          f"{args.out}.truth.json; " + ", ".join(f"{k} {v:.3f} Hz" for k, v in f.items())
          + f"; real-time factor {truth['performance']['real_time_factor']:.1f}")
    return EXIT_OK


def _parse_dips(texts, line_length: float) -> tuple[tuple[float, float, float], ...]:
    """``--dip CENTRE_M:DEPTH_MM:LENGTH_M`` values as (centre, depth, length) [m]: the depth is
    given in mm, as track engineers quote it, and becomes metres here once."""
    dips = []
    for text in texts:
        try:
            centre, depth_mm, length = (float(x) for x in text.split(":"))
        except ValueError:
            raise InputError(f"--dip takes CENTRE_M:DEPTH_MM:LENGTH_M (e.g. 2500:3:12), got {text!r}",
                             key="--dip") from None
        if not all(math.isfinite(x) for x in (centre, depth_mm, length)) or depth_mm < 0 or length <= 0:
            raise InputError(f"--dip {text!r}: give finite numbers, a depth >= 0 mm and a length > 0 m", key="--dip")
        if not 0.0 <= centre <= line_length:
            raise InputError(f"--dip {text!r}: its centre must be on the line, within 0..{line_length:g} m",
                             key="--dip")
        dips.append((centre, depth_mm * 1e-3, length))
    return tuple(dips)


def cmd_synth_excitation(args) -> int:
    from calibration.truth.effects import parse_effect
    from calibration.truth.excitation import ExcitationSettings, synth_excitation

    if args.runs < 1:
        raise InputError(f"--runs must be >= 1, got {args.runs}", key="--runs")
    if not 20.0 * args.runs <= args.duration <= 7200.0:
        raise InputError(f"--duration must be within {20 * args.runs:g}..7200 s (at least 20 s per run), "
                         f"got {args.duration:g}", key="--duration")
    if getattr(args, "truth", "railcal") == "exudyn":
        return _synth_excitation_exudyn(args)
    effect = parse_effect(args.effect, "stationary_excitation")
    check_campaign_output(args.out, overwrite=args.force)
    settings = ExcitationSettings(runs=args.runs, duration=args.duration)
    truth = synth_excitation(args.out, seed=args.seed, settings=settings, effect=effect, fmt=args.format,
                             overwrite=args.force, progress=progress_for(args))
    elastic = [f"{k} {f:.2f} Hz" for k, f in truth["frequencies_hz"].items() if truth["mode_kinds"][k] == "elastic"]
    print(f"wrote {args.out} ({args.runs} runs x {settings.run_duration:g} s, {len(truth['sensors'])} floor "
          f"accelerometers and the exciter force at {settings.fs:g} Hz) and {args.out}.truth.json; "
          f"{truth['modes_kept']['count']} modes kept; elastic modes in 3-25 Hz: {', '.join(elastic)}")
    return EXIT_OK


def _synth_excitation_exudyn(args) -> int:
    """``synth excitation --truth exudyn``: the independent truth's shell carbody."""
    from calibration.truth.independent import parse_hidden
    from calibration.truth.independent.hidden import STATIONARY_RANGES
    from calibration.truth.independent.stationary import StationarySettings, synth_excitation_independent

    effect = parse_hidden(args.effect, STATIONARY_RANGES)
    if len(effect) > 1:
        raise InputError("the stationary exudyn truth hides one effect at a time", key="--effect")
    check_campaign_output(args.out, overwrite=args.force)
    settings = StationarySettings(runs=args.runs, duration=args.duration)
    truth = synth_excitation_independent(args.out, seed=args.seed, settings=settings, effect=effect, fmt=args.format,
                                         overwrite=args.force, progress=progress_for(args))
    poles = ", ".join(f"{f:.2f}" for f in truth["frequencies_hz"].values())
    print(f"wrote {args.out} ({args.runs} runs x {args.duration / args.runs:g} s, {len(truth['sensors'])} floor "
          f"accelerometers and the exciter force, exudyn truth) and {args.out}.truth.json; poles in 3-25 Hz: "
          f"{poles} Hz; real-time factor {truth['performance']['real_time_factor']:.1f}")
    return EXIT_OK
