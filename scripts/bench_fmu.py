"""Benchmark (issue 5): the car FMU's own cost, and its cost inside fmpy and libcosim.

1. A small C master (fmu_src/tools/fmu_driver.c, compiled here with gcc) loads the FMI 2
   binary and runs the car stand-alone over a synthetic 95 km track: 2250 s (90 km at
   40 m/s) in 1 ms communication steps, reading all ten outputs after every step. It prints
   the real-time factor (target >= 1000). The same run with the master setting the eight
   rail inputs every step is printed beside it.
2. The same FMU in fmpy and in libcosimpy (FMI 2; libcosim 0.0.6 loads no FMI 3) for
   ``--importer-seconds`` simulated seconds at 1 ms: real-time factor, and the share of the
   wall time spent inside the FMU: the importer's own overhead is measured with the same
   loop on a one-state FMU with as many outputs, built by the same builder
   (fmu_src/trivial), so share = 1 - wall(trivial) / wall(car); the C driver's time for the
   same simulated span over wall(car) is printed beside it.

    python scripts/bench_fmu.py [--seconds 2250] [--importer-seconds 200]
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from calibration.models.vehicles import INTERCITY_TRAILER
from fmu_src.build import HERE, build_fmu
from fmu_src.reference import smooth_profile
from fmu_src.variables import car2d_spec, trivial_spec

SPEED = 40.0
STEP = 1e-3
START = 100.0


def driver(tmp: Path) -> Path:
    exe = tmp / "fmu_driver"
    subprocess.run(["gcc", "-O2", "-std=c11", "-D_POSIX_C_SOURCE=200809L", f"-I{HERE / 'include'}",
                    str(HERE / "tools" / "fmu_driver.c"), "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def run_driver(exe: Path, fmu: Path, unzip: Path, guid: str, steps: int, mode: str, spec) -> dict:
    vr = {v.name: spec.value_reference(v.name) for v in spec.variables}
    outs = [str(vr[v.name]) for v in spec.outputs]
    args = [str(exe), str(unzip / "binaries" / "linux64" / f"{spec.identifier}.so"), (unzip / "resources").as_uri(),
            guid, str(steps), str(STEP), mode, str(vr["speed"]), str(SPEED), str(vr["track_start"]), str(START),
            str(len(outs)), *outs]
    if mode == "inputs":
        rails = [f"z_rail_{j}" for j in range(1, 5)] + [f"dz_rail_{j}" for j in range(1, 5)]
        args += [str(len(rails)), *[str(vr[n]) for n in rails]]
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"fmu_driver failed ({r.returncode}): {r.stderr.strip()}")
    return json.loads(r.stdout)


def timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=2250.0, help="simulated time for the C driver [s]")
    ap.add_argument("--importer-seconds", type=float, default=200.0, help="simulated time in fmpy/libcosim [s]")
    args = ap.parse_args()
    import fmpy

    from fmu_src.importers import simulate_libcosim

    with tempfile.TemporaryDirectory(prefix="bench_fmu_") as tmp:
        tmp = Path(tmp)
        length = SPEED * args.seconds + START + 200.0
        s, z, _ = smooth_profile(length, seed=1)
        track = tmp / "track.csv"
        np.savetxt(track, np.column_stack([s, z]), delimiter=",", header="distance,level", comments="", fmt="%.10g")
        spec = car2d_spec(INTERCITY_TRAILER.as_dict(), track=track)
        built = build_fmu(spec, 2, tmp / "car.fmu", platforms=("linux64",))
        unzip = Path(fmpy.extract(str(built.path), str(tmp / "car")))
        exe = driver(tmp)
        steps = int(round(args.seconds / STEP))
        own = run_driver(exe, built.path, unzip, built.guid, steps, "standalone", spec)
        spec_in = car2d_spec(INTERCITY_TRAILER.as_dict())  # no track: the master gives the rail inputs
        built_in = build_fmu(spec_in, 2, tmp / "car_inputs.fmu", platforms=("linux64",))
        unzip_in = Path(fmpy.extract(str(built_in.path), str(tmp / "car_inputs")))
        own_inputs = run_driver(exe, built_in.path, unzip_in, built_in.guid, steps, "inputs", spec_in)
        print(json.dumps({"c_driver_standalone": own, "c_driver_master_inputs": own_inputs,
                          "track_km": round(length / 1000, 1)}))

        T = args.importer_seconds
        outs = [v.name for v in spec.outputs]
        trivial_spec_ = trivial_spec(len(outs))  # as many outputs to read and record as the car
        trivial = build_fmu(trivial_spec_, 2, tmp / "trivial.fmu", platforms=("linux64",))
        touts = [v.name for v in trivial_spec_.outputs]
        sv = {"speed": SPEED, "track_start": START}
        walls = {
            "fmpy_car": timed(lambda: fmpy.simulate_fmu(str(built.path), stop_time=T, output_interval=STEP,
                                                        step_size=STEP, start_values=sv, output=outs)),
            "fmpy_trivial": timed(lambda: fmpy.simulate_fmu(str(trivial.path), stop_time=T, output_interval=STEP,
                                                            step_size=STEP, output=touts)),
            "libcosim_car": timed(lambda: simulate_libcosim(built.path, step=STEP, stop=T, outputs=outs,
                                                            start_values=sv)),
            "libcosim_trivial": timed(lambda: simulate_libcosim(trivial.path, step=STEP, stop=T, outputs=touts)),
        }
        fmu_cost = own["wall_s"] / own["simulated_s"] * T  # the FMU's own time for T, from the C driver
        for imp in ("fmpy", "libcosim"):
            car, triv = walls[f"{imp}_car"], walls[f"{imp}_trivial"]
            print(json.dumps({"importer": imp, "simulated_s": T, "wall_s": round(car, 3),
                              "real_time_factor": round(T / car, 1), "trivial_fmu_wall_s": round(triv, 3),
                              "share_inside_fmu": round(1 - triv / car, 3),
                              "share_inside_fmu_from_c_driver": round(fmu_cost / car, 3)}))
    ok = own["real_time_factor"] >= 1000
    print("PASS" if ok else "FAIL", f": C driver real-time factor {own['real_time_factor']:.0f} for "
          f"{own['simulated_s']:.0f} s at {STEP * 1e3:g} ms steps (target >= 1000)")
    return 0 if ok else 1


if __name__ == "__main__":
    if shutil.which("gcc") is None:
        sys.exit("gcc not found")
    sys.exit(main())
