"""``make fmus``: the car and box-type vehicle FMUs, FMI 2.0 and 3.0, into ``build/fmus``.

The car from a calibration file (``--car-calibration``, default the seed's intercity
trailer), the box from a box calibration (``--box-calibration``, default the nominal
Shinkansen-type carbody with outputs at the reference floor grid); both carry a synthetic 5 km track for stand-alone running.
Binaries for every platform whose compiler is installed (linux64 with gcc, win64 with
Debian's gcc-mingw-w64-x86-64).

    python scripts/build_fmus.py [--out build/fmus] [--car-calibration F] [--box-calibration F]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from fmu_src.export import export_fmu
from fmu_src.reference import smooth_profile
from railcal.registry import MODELS


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="build/fmus")
    ap.add_argument("--car-calibration", default=None)
    ap.add_argument("--box-calibration", default=None)
    args = ap.parse_args()
    car = json.loads(Path(args.car_calibration).read_text()) if args.car_calibration else \
        MODELS["car2d"].example_calibration()
    box = json.loads(Path(args.box_calibration).read_text()) if args.box_calibration else \
        MODELS["box"].example_calibration()
    out = Path(args.out)
    with tempfile.TemporaryDirectory() as tmp:
        s, z, _ = smooth_profile(5000.0, seed=1)
        track = Path(tmp) / "track.csv"
        np.savetxt(track, np.column_stack([s, z]), delimiter=",", header="distance,level", comments="", fmt="%.10g")
        for name, cal in (("car", car), ("box", box)):
            for v in (2, 3):
                built = export_fmu(cal, v, out / f"railcal_{name}_fmi{v}.fmu", spec_for=MODELS[cal["model"]].fmu_spec,
                                   track=track)
                print(f"{built.path}: FMI {v}, binaries {', '.join(built.platforms)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
