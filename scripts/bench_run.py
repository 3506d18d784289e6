"""Benchmark: `railcal run` on a synthetic campaign, then the same run again (every step
unchanged, kept): the two wall times and the steps done, kept and skipped.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_run.py [--journeys 4] [--length-km 8] [--effect NAME[=SIZE]]
    OPENBLAS_NUM_THREADS=1 python scripts/bench_run.py --shaker [--seed 3] [--effect NAME[=SIZE]] [--quick]

In service: railcal's own truth, floor sensors. ``--shaker``: a stationary excitation test
(2 x 300 s, 27 floor accelerometers) of the full-order box carbody, calibrated with
`railcal calibrate`'s defaults (the seed's 1000 particles); with ``--quick``, the quick demo's
coarse box model (every panel order - 4) and its 2 swarms of 100 particles. ``--effect`` hides one effect of
the catalogue (`railcal synth --effect`), so that the diagnosis has an extended model and the
run makes, checks and cross-checks both FMUs.

Forecast, written before the first runs with ``--effect`` (2026-11-29): in service with
``cog_offset`` (seed 11), 10/10 steps done and the cause named; ``--shaker --effect
underfloor_equipment`` (seed 3), 10/10 steps done, the cause named, the extended model's FRAC
above the calibrated one's; first runs 1.2-1.5 times the runs without an effect (the extended
model's validation, FMU and cross-check), second runs under 3 s.

Measured (code 65bd83b, the `.ci/run` clone's environment): in service with ``cog_offset``,
10/10, named `high`, 52.4 s against 39.1 s clean (1.34x), again 3.1 s; ``--shaker --quick
--seed 11 --effect underfloor_equipment=0.03``, 10/10, named `high`, 243.1 s, again 3.3 s;
``--shaker --effect underfloor_equipment`` (full order, seed 3): 7/10, **`unexplained`**, the
forecast missed, 1381.5 s (calibrate 940 s, 10.3 % off the modes; the diagnosis from that
calibration gained 17 % with the right equipment; docs/performance.md), again 2.3 s.

Forecast for the mend (every hypothesis fitted again once the baseline's re-fit is kept),
written before its runs (2026-11-29): the seed-3 campaign's diagnosis from its calibration
names the equipment (measured: `high`, 1.47 x noise, 12 min); on fresh seeds 4 and 5 (the
two after the one that missed, drawn before any run) ``--shaker --effect
underfloor_equipment``, full order: 10/10 steps and the equipment named on each, the
extended model's FRAC median above the calibrated one's; first runs 20-35 min.

Measured (code 710e939, the two seeds side by side): seed 4, 10/10, `high`, 698.98 kg for
699.6, mount within 1 mm, 13.394 Hz for 13.397; FRAC median 0.170 calibrated, 0.991
extended; 1579.1 s (calibrate 1137 s, 11.4 % off its modes; diagnose 348 s), again 3.3 s.
Seed 5, 10/10, `high`, 695.9 kg, mount within 4 mm, 15.651 Hz for 15.651; FRAC 0.378 and
0.997; 1564.2 s (calibrate 1136 s, 7.7 % off; diagnose 339 s), again 2.8 s. Neither
needed the second pass (no baseline re-fit kept): forecast met on both.

Forecast for the final code of the session (the box cross-check driving the exciter),
written before its run: fresh seed 6 (the next), the same answers as seeds 4 and 5 (10/10,
named, extended FRAC above calibrated), both cross-checks `pass` with the exciter driven.
Measured (code 96ae7d6, beside one other job): 10/10, `high`, 700.5 kg for 699.6, mount within
1 mm, 13.436 Hz for 13.437; FRAC median 0.399 calibrated, 0.997 extended; both cross-checks
`pass` (worst NRMSE 2.5e-3 and 2.3e-3 with the exciter driven; frequencies 2.6e-8 and 3.3e-6
against the full model); 1216.4 s (calibrate 817 s, 11.7 % off; diagnose 294 s), again 2.6 s;
the report's 752 cells equal the JSON. Forecast met.
"""
from __future__ import annotations

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

from railcal.cli import main as railcal
from railcal.demo import QUICK
from railcal.run import run_campaign
from calibration.data.campaign import open_campaign
from calibration.truth.effects import parse_effect
from calibration.truth.excitation import synth_excitation
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--journeys", type=int, default=4)
    ap.add_argument("--length-km", type=float, default=8.0)
    ap.add_argument("--shaker", action="store_true", help="an excitation test of the box carbody instead")
    ap.add_argument("--seed", type=int, default=None, help="default: 11 in service, 3 for --shaker")
    ap.add_argument("--effect", default=None, help="hide this effect of the catalogue, NAME[=SIZE]")
    ap.add_argument("--keep", type=Path, default=None, help="copy the campaign and the results folder here")
    ap.add_argument("--quick", action="store_true",
                    help="with --shaker: the quick demo's coarse box model (panel orders - 4) and its swarm")
    args = ap.parse_args()
    if args.quick and not args.shaker:
        ap.error("--quick goes with --shaker")
    effect = parse_effect(args.effect, "stationary_excitation" if args.shaker else "in_service")
    with tempfile.TemporaryDirectory() as tmp:
        root, out = Path(tmp) / "c", Path(tmp) / "results"
        if args.shaker:
            synth_excitation(root, seed=3 if args.seed is None else args.seed, effect=effect,
                             **({"settings": QUICK.excitation} if args.quick else {}))
        else:
            synth_in_service(root, seed=11 if args.seed is None else args.seed, fmt="parquet", effect=effect,
                             settings=InServiceSettings(journeys=args.journeys,
                                                        line=LineSpec(length=args.length_km * 1000.0),
                                                        carbody_sensors=True))
        for attempt in ("first run", "run again"):
            t0 = time.perf_counter()
            if args.quick:  # the run's step options, as the demo gives them
                run_campaign(open_campaign(root), out, model="box", options=QUICK.run_options(), say=lambda m: None)
                code = 0
            else:
                code = railcal(["run", str(root), "--out", str(out), "--quiet"])
            wall = time.perf_counter() - t0
            steps = json.loads((out / "run.json").read_text())["steps"]
            kept = sum(bool(s.get("reused")) for s in steps)
            done = sum(s["status"] == "done" for s in steps)
            skipped = [s["name"] for s in steps if s["status"] == "skipped"]
            print(f"{attempt}: exit {code}, {wall:.1f} s wall, {done}/{len(steps)} steps done, {kept} kept unchanged"
                  + (f", skipped {', '.join(skipped)}" if skipped else "")
                  + f"; report.pdf {'written' if (out / 'report.pdf').is_file() else 'absent'}")
        diagnosis = json.loads((out / "diagnosis.json").read_text()) if (out / "diagnosis.json").is_file() else {}
        print(f"cause {diagnosis.get('cause')} (confidence {diagnosis.get('confidence')}); FMUs "
              + ", ".join(p.name for p in sorted((out / "fmu").glob("*.fmu"))))
        for name in ("validation", "validation_extended"):
            v = json.loads((out / f"{name}.json").read_text()) if (out / f"{name}.json").is_file() else {}
            if "frac_median" in v:
                print(f"{name}: FRAC median {v['frac_median']:.3f}, least {v['frac_min']:.3f}")
        if args.keep is not None:
            shutil.copytree(tmp, args.keep, dirs_exist_ok=True)


if __name__ == "__main__":
    main()
