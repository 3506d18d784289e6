"""Benchmark: the in-service diagnosis of a fleet-sized campaign, 10 journeys x 40 km
(issue 31 target: at most 2 min on the 2-core machine).

It writes the campaign once (railcal's own truth by default, or the independent exudyn
truth), then times ``diagnose_in_service`` on it, from opening the campaign to the
answer, and prints the wall time, the data it read and the answer.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_diagnose_scale.py [--truth railcal|exudyn] [--journeys 10] [--length-km 40]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from calibration.data.campaign import open_campaign
from calibration.diagnosis.in_service import diagnose_in_service
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.independent import IndependentSettings, synth_in_service_independent
from calibration.truth.independent.irregularity import LineSpec as IndependentLine
from calibration.truth.track import LineSpec


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truth", choices=("railcal", "exudyn"), default="railcal")
    ap.add_argument("--journeys", type=int, default=10)
    ap.add_argument("--length-km", type=float, default=40.0)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    length = args.length_km * 1000.0
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / "fleet"
        t0 = time.perf_counter()
        if args.truth == "railcal":
            synth_in_service(root, seed=args.seed, fmt="parquet", settings=InServiceSettings(
                journeys=args.journeys, line=LineSpec(length=length), carbody_sensors=True))
        else:
            synth_in_service_independent(root, seed=args.seed, fmt="parquet", settings=IndependentSettings(
                journeys=args.journeys, line=IndependentLine(length=length), carbody_sensors=True))
        t1 = time.perf_counter()
        diag = diagnose_in_service(open_campaign(root))
        t2 = time.perf_counter()
    seconds = sum(diag.statistics.seconds.values())
    print(f"{args.truth} truth, {args.journeys} journeys x {args.length_km:g} km, carbody sensors; "
          f"written in {t1 - t0:.0f} s")
    print(f"diagnosis: {t2 - t1:.1f} s wall time for {seconds / 3600:.2f} h of gap-free records; "
          f"cause {diag.cause}")


if __name__ == "__main__":
    main()
