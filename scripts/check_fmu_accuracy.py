"""Acceptance check (issue 5): each FMU in fmpy and in libcosimpy over a synthetic track at
40 m/s, against the project's own continuous-time reference, at 1 ms and 10 ms steps.

* car: the 2D car FMU (intercity trailer) against calibration.models.car2d driven exactly
  (fmu_src.reference.car_reference);
* box: the box-type vehicle FMU (nominal Shinkansen-type carbody, full panel orders, modes
  below 100 Hz plus static correction) against the same reduced vehicle's exact response
  (fmu_src.reference.box_reference), and that reduction against the full box model's
  direct-solve FRF (printed as frf_error).

Both run stand-alone over the track (the FMU reads resources/track.csv and takes the speed).
NRMSE is the worst output's; importers agree when their outputs differ by <= 1e-9 of the
output's rms. libcosim 0.0.6 loads FMI 1 and 2 only, so FMI 3 runs in fmpy alone.

    python scripts/check_fmu_accuracy.py
"""
from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

import fmpy
import numpy as np

from calibration.models.box import assemble, shinkansen_vehicle
from calibration.models.box.vehicle_reduction import frf_full, frf_reduced, reduce_vehicle
from calibration.models.vehicles import INTERCITY_TRAILER as CAR
from calibration.models.box.rig import EXCITER, SENSOR_GRID
from fmu_src.box import box_spec
from fmu_src.build import build_fmu
from fmu_src.importers import simulate_libcosim
from fmu_src.reference import box_reference, car_reference, nrmse, smooth_profile
from fmu_src.variables import car2d_spec

SPEED, START, T = 40.0, 100.0, 10.0
TOL = {1e-3: 1e-3, 1e-2: 1e-2}


def main() -> int:
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        s, z, profile = smooth_profile(1200.0, seed=5)
        track = tmp / "track.csv"
        np.savetxt(track, np.column_stack([s, z]), delimiter=",", header="distance,level", comments="", fmt="%.17g")
        model = assemble(shinkansen_vehicle())
        reduced = reduce_vehicle(model, {n: 1.0 for n in model.names}, 100.0, SENSOR_GRID, EXCITER)
        f = np.array([6.0, 9.0, 12.0, 15.0, 20.0, 30.0, 45.0])
        full = frf_full(model, {n: 1.0 for n in model.names}, f, SENSOR_GRID, EXCITER)
        frf_err = np.linalg.norm(frf_reduced(reduced, f) - full, axis=1) / np.linalg.norm(full, axis=1)
        print(json.dumps({"box_reduction": {"modes": reduced.n_modes, "pseudo_modes": reduced.M.shape[0] - 12 -
                                            reduced.n_modes, "frf_error_at_hz": dict(zip(f.tolist(),
                                                                                         np.round(frf_err, 5).tolist()))}}))
        specs = {"car": car2d_spec(CAR.as_dict(), track=track),
                 "box": box_spec({"model": "box", "parameters": {}},
                                 points=(SENSOR_GRID, EXCITER), reduced=reduced, track=track)}
        for name, spec in specs.items():
            outs = [v.name for v in spec.outputs]
            sv = {"speed": SPEED, "track_start": START}
            for version in (2, 3):
                built = build_fmu(spec, version, tmp / f"{name}{version}.fmu")
                for h in (1e-3, 1e-2):
                    a = fmpy.simulate_fmu(str(built.path), stop_time=T, output_interval=h, step_size=h,
                                          start_values=sv, output=outs)
                    t = a["time"]
                    sub = max(1, int(round(h / 5e-5)))
                    if name == "car":
                        ref = car_reference(spec, CAR, profile, SPEED, t, start=START, substeps=sub)
                    else:
                        y = box_reference(reduced, float(spec.variables[spec.value_reference("zeta_carbody")].start),
                                          profile, SPEED, t, np.zeros(t.size), start=START, substeps=sub)
                        ref = {n: y[:, k] for k, n in enumerate(outs)}
                    row = {"fmu": name, "fmi": version, "step_s": h,
                           "fmpy_nrmse": float(f"{max(nrmse(a[n], ref[n]) for n in outs):.3g}")}
                    good = row["fmpy_nrmse"] <= TOL[h]
                    if version == 2:
                        b = simulate_libcosim(built.path, step=h, stop=T, outputs=outs, start_values=sv)
                        row["libcosim_nrmse"] = float(f"{max(nrmse(b[n], ref[n]) for n in outs):.3g}")
                        row["importers_max_difference_rel"] = float(f"{max(np.max(np.abs(a[n] - b[n])) / np.std(a[n]) for n in outs):.3g}")
                        good &= row["libcosim_nrmse"] <= TOL[h] and row["importers_max_difference_rel"] <= 1e-9
                    else:
                        row["libcosim"] = "FMI 3 not loadable by libcosim 0.0.6"
                    row["pass"] = bool(good)
                    ok &= good
                    print(json.dumps(row))
    print("PASS" if ok else "FAIL", ": NRMSE <= 1e-3 at 1 ms, <= 1e-2 at 10 ms; importers within 1e-9")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
