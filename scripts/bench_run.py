"""Benchmark: `railcal run` on a synthetic in-service campaign (railcal's own truth, floor
sensors), then the same run again (every step unchanged, kept): the two wall times and the
steps done.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_run.py [--journeys 4] [--length-km 8]
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from railcal.cli import main as railcal
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--journeys", type=int, default=4)
    ap.add_argument("--length-km", type=float, default=8.0)
    ap.add_argument("--seed", type=int, default=11)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root, out = Path(tmp) / "c", Path(tmp) / "results"
        synth_in_service(root, seed=args.seed, fmt="parquet", settings=InServiceSettings(
            journeys=args.journeys, line=LineSpec(length=args.length_km * 1000.0), carbody_sensors=True))
        for attempt in ("first run", "run again"):
            t0 = time.perf_counter()
            code = railcal(["run", str(root), "--out", str(out), "--quiet"])
            wall = time.perf_counter() - t0
            steps = json.loads((out / "run.json").read_text())["steps"]
            kept = sum(bool(s.get("reused")) for s in steps)
            done = sum(s["status"] == "done" for s in steps)
            print(f"{attempt}: exit {code}, {wall:.1f} s wall, {done}/{len(steps)} steps done, {kept} kept unchanged")


if __name__ == "__main__":
    main()
