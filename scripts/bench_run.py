"""Benchmark: `railcal run` on a synthetic campaign, then the same run again (every step
unchanged, kept): the two wall times and the steps done, kept and skipped.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_run.py [--journeys 4] [--length-km 8]
    OPENBLAS_NUM_THREADS=1 python scripts/bench_run.py --shaker [--seed 3]

In service: railcal's own truth, floor sensors. ``--shaker``: a stationary excitation test
(2 x 300 s, 27 floor accelerometers) of the full-order box carbody, calibrated with
`railcal calibrate`'s defaults (the seed's 1000 particles).
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from railcal.cli import main as railcal
from calibration.truth.excitation import synth_excitation
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--journeys", type=int, default=4)
    ap.add_argument("--length-km", type=float, default=8.0)
    ap.add_argument("--shaker", action="store_true", help="an excitation test of the box carbody instead")
    ap.add_argument("--seed", type=int, default=None, help="default: 11 in service, 3 for --shaker")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root, out = Path(tmp) / "c", Path(tmp) / "results"
        if args.shaker:
            synth_excitation(root, seed=3 if args.seed is None else args.seed)
        else:
            synth_in_service(root, seed=11 if args.seed is None else args.seed, fmt="parquet",
                             settings=InServiceSettings(journeys=args.journeys,
                                                        line=LineSpec(length=args.length_km * 1000.0),
                                                        carbody_sensors=True))
        for attempt in ("first run", "run again"):
            t0 = time.perf_counter()
            code = railcal(["run", str(root), "--out", str(out), "--quiet"])
            wall = time.perf_counter() - t0
            steps = json.loads((out / "run.json").read_text())["steps"]
            kept = sum(bool(s.get("reused")) for s in steps)
            done = sum(s["status"] == "done" for s in steps)
            skipped = [s["name"] for s in steps if s["status"] == "skipped"]
            print(f"{attempt}: exit {code}, {wall:.1f} s wall, {done}/{len(steps)} steps done, {kept} kept unchanged"
                  + (f", skipped {', '.join(skipped)}" if skipped else "")
                  + f"; report.pdf {'written' if (out / 'report.pdf').is_file() else 'absent'}")


if __name__ == "__main__":
    main()
