"""Benchmark: the independent exudyn truth writes a bench campaign of 4 journeys x 8 km at
20-45 m/s (issue 31 target: about a minute on one core).

It prints the simulated time, the wall time, the real-time factor (simulated over wall
time, whole campaign: model builds, static solutions, time integration, sensor chain and
file writing) and the time of the time integration alone.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_truth_independent.py [--journeys 4] [--length-km 8] [--vehicle intercity]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from calibration.truth.independent import IndependentSettings, synth_in_service_independent
from calibration.truth.independent.irregularity import LineSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--journeys", type=int, default=4)
    ap.add_argument("--length-km", type=float, default=8.0)
    ap.add_argument("--vehicle", default="intercity")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    settings = IndependentSettings(journeys=args.journeys, line=LineSpec(length=args.length_km * 1000.0))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        truth = synth_in_service_independent(Path(tmp) / "bench", seed=args.seed, settings=settings,
                                             vehicle=args.vehicle)
        wall = time.perf_counter() - t0
    perf = truth["performance"]
    steps = sum(j["steps"] for j in truth["journeys"])
    print(f"independent exudyn truth, {args.vehicle}: {args.journeys} journeys x {args.length_km:g} km")
    print(f"simulated {perf['simulated_s']:.0f} s of journeys ({steps} steps of {1e3 / settings.sim_rate:g} ms) "
          f"in {wall:.1f} s wall time (campaign written {perf['wall_s']:.1f} s)")
    print(f"real-time factor {perf['simulated_s'] / wall:.1f}")


if __name__ == "__main__":
    main()
