"""The box-type vehicle (carbody seed) in the commands: what `identify`, `modes`, `calibrate`,
`validate` and `crosscheck` do for it. Each function writes the command's files and returns
its one-line summary; the registry (:mod:`railcal.registry`) picks it."""
from __future__ import annotations

from pathlib import Path

from calibration.data.errors import InputError
from calibration.data.outputs import write_result
from calibration.swarm_defaults import (CAMPAIGN_DONE_PCT, CAMPAIGN_SWARMS, TYPED_MIN_MAC, TYPED_POLISH_STEPS,
                                        TYPED_REFINE_ROUNDS, TYPED_SWARMS)

from .common import campaign_of, names, progress_for, read_identification, write_calibration


def identify(campaign, args, png: Path, second: Path) -> str:
    from calibration.identification.excitation import identify_excitation

    result = identify_excitation(campaign)
    png, mac_png = result.plot(png, second)
    write_result(args.out, {**result.to_json(), "campaign_sha256": campaign.fingerprint(), "plot": str(png),
                            "plot_mac": str(mac_png)}, "identification")
    modes = ", ".join(f"{m.label} {m.frequency_hz:.3f} Hz ({100 * m.damping_ratio:.1f} %)" for m in result.modes)
    local = "".join(f"; a resonance at {r.channel} alone, {r.frequency_hz:.2f} Hz (its mounting, not the carbody)"
                    for r in result.local)
    return (f"identified {len(result.modes)} modes ({modes}){local}; {len(result.rejected)} peaks rejected; "
            f"{result.frf.n_averages} Welch segments over {result.records} records; wrote "
            f"{names(args.out, png, mac_png)}")


def modes(args) -> dict:
    """The box-type vehicle (default factor set) with ``--param NAME=FACTOR`` stiffness
    factors: its modes below --max-hz."""
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
    found = box_modes(model, p, max_hz=args.max_hz)
    return {"model": "box", "parameters": p, "max_hz": args.max_hz,
            "modes": [{"label": m.label, "family": m.family, "frequency_hz": m.frequency_hz,
                       "damping_ratio": m.damping_ratio, "kind": m.kind} for m in found]}


def calibrate(args) -> str:
    from calibration.calibrate_box import (RefineSettings, SwarmSettings, box_search, calibrate_box_campaign,
                                           campaign_factor_set, wide_search)
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
    if args.campaign is None and args.panel_order_change:
        raise InputError("--panel-order-change goes with a CAMPAIGN (typed targets are matched on the "
                         "full-order model)", key="--panel-order-change")
    if args.campaign is not None:
        from calibration.models.box.shinkansen import LOWEST_ORDER_CHANGE

        campaign = campaign_of(args)
        try:
            factors = campaign_factor_set(args.factors, campaign)
        except ValueError as e:
            raise InputError(str(e), key="--factors") from None
        try:
            wide = wide_search(box_search(campaign.meta.priors, factors=factors))
        except InputError as e:
            raise e.located(campaign.root / "campaign.toml") from None
        swarm = SwarmSettings(pso=settings, seed=args.seed, swarms=swarms, done_pct=CAMPAIGN_DONE_PCT,
                              log_factors=wide)
        identified = None
        if args.identification is not None:
            from calibration.identification.excitation import IdentifiedShapes

            identified = read_identification(args.identification, campaign, IdentifiedShapes.from_json)
        # a set's polish-only factors join in the polish, which follows the refinement
        polish = TYPED_POLISH_STEPS if args.refine and factors.polish_only else 0
        if args.panel_order_change < LOWEST_ORDER_CHANGE:
            raise InputError(f"{args.panel_order_change} would leave a panel order below 1 (lowest: "
                             f"{LOWEST_ORDER_CHANGE})", key="--panel-order-change")
        result, ident = calibrate_box_campaign(campaign, swarm=swarm, factors=factors, identified=identified,
                                               refinement=RefineSettings(enabled=args.refine, polish_steps=polish),
                                               order_change=args.panel_order_change, progress=progress_for(args))
        out = result.to_json(ident)
    else:
        result = _calibrate_typed_targets(args, settings, swarms)
        out = result.to_json()
    figures = write_calibration(out, args.out)
    pso = result.pso
    runs = pso.get("swarms", ())
    ends = ", ".join(f"{r['end_max_error_pct']:.3g} %" for r in runs)
    split = f" in {len(runs)} swarms (each refined: {ends}; the best kept)" if runs else ""
    return (f"pso {pso['particles']} x {pso['iterations']} iterations{split} over {len(pso['factors'])} of the "
            f"{len(result.parameters)} {result.factor_set} factors ({pso['evaluations_per_s']:.0f} evaluations/s): "
            f"{pso['best_full_pct']:.3g} %{' -> refined' if result.refinement else ''} to "
            f"{result.max_error_pct:.3g} % over {len(result.fit)} modes, MAC >= "
            f"{min(r['mac'] for r in result.fit):.3f}{unsound_note(result.fit)}; "
            f"{result.identifiability['summary']}; wrote {names(args.out, *figures)}")


def unsound_note(fit) -> str:
    """The summary's note of pairings that do not count as they are (under the MAC floor or
    sharing a partner; :meth:`BoxFit.sound`), with the MAC to six places: a MAC of 0.799999
    prints as 0.800 but is under a floor of 0.8."""
    bad = [r for r in fit if not r["sound"]]
    return "".join(f", {r['label']} unsound (MAC {r['mac']:.6f})" for r in bad)


def _calibrate_typed_targets(args, settings, swarms: int):
    """Targets given by mode type and frequency: each paired by MAC with the type's floor
    pattern at the reference floor grid of the excitation test."""
    from calibration.calibrate import read_priors, read_targets
    from calibration.calibrate_box import PairingSettings, RefineSettings, SwarmSettings, box_search, calibrate_box
    from calibration.data.campaign import Prior
    from calibration.models.box import factor_set
    from calibration.models.box.mode_types import MODE_TYPES, typed_targets
    from calibration.models.box.rig import EXCITER, GEOMETRY, SENSOR_GRID

    try:
        factors = factor_set(args.factors or "credible")
    except ValueError as e:
        raise InputError(str(e), key="--factors") from None
    targets = read_targets(args.targets, labels=tuple(MODE_TYPES), model="the box model (mode types)")
    given = read_priors(args.priors, searchable=factors.names) if args.priors else ()
    search = box_search({q.name: Prior(q.mean, q.low, q.high) for q in given}, factors=factors)
    typed = typed_targets(targets, SENSOR_GRID, GEOMETRY.length, GEOMETRY.width)
    return calibrate_box(typed, SENSOR_GRID, search, factors=factors, exciter=EXCITER, progress=progress_for(args),
                         swarm=SwarmSettings(pso=settings, seed=args.seed, swarms=swarms, log_factors=True),
                         refinement=RefineSettings(enabled=args.refine, rounds=TYPED_REFINE_ROUNDS,
                                                   polish_steps=TYPED_POLISH_STEPS if args.refine else 0),
                         pairing=PairingSettings(min_mac=TYPED_MIN_MAC))


def validate(campaign, calibration: dict, args, figures) -> str:
    from calibration.validation.excitation import compare_frf

    result = compare_frf(campaign, calibration)
    png = result.plot(figures[0])
    phase_png = result.plot_phase(figures[1])
    out = result.to_json()
    out["plot"], out["plots"] = str(png), [phase_png.name]
    write_result(args.out, out, "validation")
    return (f"FRF from the exciter to {len(result.sensors)} accelerometers over {result.band[0]:g}-"
            f"{result.band[1]:g} Hz: FRAC median {out['frac_median']:.3f}, min {out['frac_min']:.3f}; "
            f"log-magnitude error up to {result.log_error_db.max():.2f} dB rms; "
            f"wrote {names(args.out, png, phase_png)}")


def crosscheck(calibration: dict, distance, level, args, png: Path | None) -> tuple[dict, str]:
    """The exudyn cross-check over (distance, level) [m]: the report and its summary (the box
    draws no figure: ``png`` is None)."""
    from .crosscheck import crosscheck_box

    report = crosscheck_box(calibration, distance, level, speed=args.speed, duration=args.duration,
                            with_fmu=not args.no_fmu)
    e, t = report["eigen"], report["time"]
    return report, (f"exudyn vs railcal (box): frequencies below 20 Hz {e['max_relative_error_vs_reduced']:.1e} "
                    f"(reduced), {e['max_relative_error_vs_full']:.1e} (full model); {t['duration_s']:g} s at "
                    f"{t['speed_m_s']:g} m/s worst floor NRMSE {t['worst_nrmse']:.1e}")
