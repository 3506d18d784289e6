"""Benchmark: the noise floors `railcal identify` reports against the sensor noise the truth
simulator added, channel by channel, as the ratio of the amplitude spectral densities.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_noise_floor.py [--seeds 5] [--force-noise N]

Campaigns, seeds drawn once by this rule: in service seeds 7300 + k (3 journeys x 6 km,
carbody sensors; the truth's noise is white up to fs / 2), excitation tests seeds 7310 + k
(the quick demo's 2 x 120 s at fs 200 Hz; the truth's is white up to fs_sim / 2, then the
logger's anti-alias filter), k = 0 .. seeds - 1. The truth's density: rms / sqrt(white band).

Forecast, written before the first run (2026-11-29, code 6ad52b3): in service the bogie,
carbody and gyro floors within 2-6 % above the truth's (the percentile's chi-square
correction, since the degrees-of-freedom mend), the axle boxes 2-4x above it (they carry
the rail's short waves over the whole band: an upper bound); in the excitation tests the
floor accelerometers' non-coherent floors within 10 % of the truth's.

Measured (code 6ad52b3, beside two other jobs): in service bogie 1.017 [1.013, 1.022],
carbody 1.001 [0.994, 1.004], gyro 1.006 [1.006, 1.008]: closer than forecast (the forecast
missed on the safe side); axle boxes 3.13 [2.04, 3.63] (forecast met). Excitation tests:
force 1.028 [1.024, 1.030]; floor accelerometers 1.155 [1.051, 3.172] over 135 channels,
**forecast missed** (median 15 % above, one channel 3.2x): upper bounds, not the noise.
Not the load cell's noise carried through the FRF: seed 7310 without force noise gives
the same (median 1.139 against 1.140, largest 2.30 against 2.30; ``--seeds 1 --force-noise 0``
against ``--seeds 1``). Not yet found what it is.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

from railcal.cli import main as railcal
from railcal.demo import QUICK
from calibration.truth.excitation import synth_excitation
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


def _group(channel: str) -> str:
    for key in ("axle", "carbody", "gyro", "bogie", "force"):  # the in-service names, and the exciter
        if key in channel:
            return key
    return "floor" if channel.startswith("acc_") else channel


def _in_service_truth(truth: dict, channel: str) -> float:
    """[SI / sqrt(Hz)] the simulated noise density of ``channel``."""
    noise = truth["noise_rms_si"]
    rms = {"axle": noise["axle_boxes"], "carbody": noise["carbody"], "gyro": noise["bogie1_gyro_pitch"],
           "bogie": noise["bogie1_acc_z"]}[_group(channel)]
    return rms / np.sqrt(noise["white_up_to_hz"])


def _excitation_truth(truth: dict, channel: str, force: str) -> float:
    s = truth["settings"]
    rms = s["force_noise"] if channel == force else s["acc_noise"]
    return rms / np.sqrt(s["fs_sim"] / 2)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--force-noise", type=float, default=None,
                    help="[N] rms of the excitation tests' load-cell noise (default: the truth simulator's)")
    args = ap.parse_args()
    ratios: dict[str, list[float]] = defaultdict(list)
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.seeds):
            for kind, seed in (("in service", 7300 + k), ("excitation", 7310 + k)):
                root, out = Path(tmp) / f"c{seed}", Path(tmp) / f"i{seed}.json"
                if kind == "in service":
                    synth_in_service(root, seed=seed, fmt="parquet", settings=InServiceSettings(
                        journeys=3, line=LineSpec(length=6000.0), carbody_sensors=True))
                else:
                    settings = QUICK.excitation if args.force_noise is None else \
                        dataclasses.replace(QUICK.excitation, force_noise=args.force_noise)
                    synth_excitation(root, seed=seed, settings=settings)
                assert railcal(["identify", str(root), "--out", str(out), "--quiet"]) == 0
                truth = json.loads(Path(f"{root}.truth.json").read_text())
                floors = json.loads(out.read_text())["data"]["noise_floors"]
                force = truth.get("exciter", {}).get("sensor")
                for fl in floors:
                    expected = (_in_service_truth(truth, fl["channel"]) if kind == "in service"
                                else _excitation_truth(truth, fl["channel"], force))
                    group = f"{kind}: {_group(fl['channel'])} ({fl['method']})"
                    ratios[group].append(fl["asd_si_per_sqrt_hz"] / expected)
                print(f"seed {seed} ({kind}): {len(floors)} floors", flush=True)
    print("\nfloor / truth's noise density, per channel group: median [least, largest] (channels)")
    for group, r in sorted(ratios.items()):
        print(f"  {group}: {np.median(r):.3f} [{min(r):.3f}, {max(r):.3f}] ({len(r)})")


if __name__ == "__main__":
    main()
