"""Benchmark: segmental FDD over 30 journeys x 90 km at 500 Hz (issue 2 target: <= 60 s, <= 2 GB).

The campaign is synthesised once (Parquet, about 1.5 GB, several minutes) into
``--data`` and reused. The benchmark then runs, in a fresh child process so that its
peak memory is its own:

* ``fdd``: the segmental FDD of seed Table 3 plus the input-output analysis (the part
  the target names), streaming one run at a time;
* ``identify``: the whole ``railcal identify`` (FDD, input-output fits, spectral-line
  classification, labelling), for reference.

It prints wall time and peak resident memory (ru_maxrss of the child) of each.

    python scripts/bench_fdd.py [--data bench_data/in_service_30x90] [--journeys 30] [--length-km 90]
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def ensure_campaign(path: Path, journeys: int, length_km: float) -> None:
    if (path / "campaign.toml").is_file():
        return
    from calibration.truth.in_service import InServiceSettings, synth_in_service
    from calibration.truth.track import LineSpec

    print(f"synthesising {journeys} journeys x {length_km:g} km into {path} (once)", flush=True)
    t0 = time.perf_counter()
    synth_in_service(path, seed=2024, fmt="parquet",
                     settings=InServiceSettings(journeys=journeys, line=LineSpec(length=length_km * 1000.0)),
                     progress=lambda m: print("  " + m, flush=True))
    print(f"synthesised in {time.perf_counter() - t0:.0f} s", flush=True)


def child(what: str, path: str) -> None:
    from calibration.data.campaign import open_campaign
    from calibration.identification.fdd import Analysis, segmental_fdd
    from calibration.identification.in_service import IO_ANALYSIS, IdentifySettings, identify_in_service
    from calibration.identification.fdd import plan_analyses

    campaign = open_campaign(path)
    t0 = time.perf_counter()
    if what == "fdd":
        settings = IdentifySettings()
        analyses = plan_analyses(campaign.meta) + (
            Analysis(IO_ANALYSIS, ("rail_bounce_bogie1", "rail_bounce_bogie2_from_bogie1", "bogie1_centre_acc_z",
                                   "rail_pitch_bogie1", "bogie1_gyro_pitch"), settings.io_segments, "input_output"),)
        result = segmental_fdd(campaign, analyses, settings=settings.fdd)
        summary = {name: r.n_used for name, r in result.results.items()}
    else:
        result = identify_in_service(campaign)
        summary = {m.label: round(m.frequency_hz, 4) for m in result.modes}
    wall = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({"what": what, "wall_s": round(wall, 2), "peak_rss_mb": round(peak_mb, 1), "result": summary}))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", default=str(ROOT / "bench_data" / "in_service_30x90"))
    ap.add_argument("--journeys", type=int, default=30)
    ap.add_argument("--length-km", type=float, default=90.0)
    ap.add_argument("--child", choices=("fdd", "identify"))
    args = ap.parse_args()
    if args.child:
        child(args.child, args.data)
        return 0
    data = Path(args.data)
    ensure_campaign(data, args.journeys, args.length_km)
    n_rows = 0
    import pyarrow.parquet as pq

    for p in sorted((data / "runs").glob("*.parquet")):
        n_rows += pq.read_metadata(p).num_rows
    print(f"campaign: {len(list((data / 'runs').glob('*.parquet')))} runs, {n_rows / 1e6:.1f} M samples per channel")
    ok = True
    for what in ("fdd", "identify"):
        out = subprocess.run([sys.executable, __file__, "--data", str(data), "--child", what], capture_output=True,
                             text=True, cwd=ROOT)
        if out.returncode != 0:
            print(out.stderr)
            return 1
        r = json.loads(out.stdout.strip().splitlines()[-1])
        print(f"{what:9s} wall {r['wall_s']:7.2f} s   peak memory {r['peak_rss_mb']:7.1f} MB   {r['result']}")
        if what == "fdd":
            ok = r["wall_s"] <= 60.0 and r["peak_rss_mb"] <= 2048.0
    print(("PASS" if ok else "FAIL") + ": segmental FDD target <= 60 s and <= 2048 MB")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
