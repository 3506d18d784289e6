"""Acceptance check (issue 6, box-type vehicle): the exudyn build (reference_models.box)
against railcal's reduced box vehicle and the full box model, at nominal stiffness.

* eigenfrequencies below 20 Hz of the vehicle on held wheelsets: exudyn's
  ComputeODE2Eigenvalues against (a) the ReducedVehicle (same carbody basis; tolerance 1e-4
  relative) and (b) the full assembled model (eigsh; reported, same tolerance);
* floor accelerations (27 sensors) to a 2 s band-random exciter force (5-50 Hz, 500 N rms,
  seed 7), zeta = 0.02: exudyn's generalized-alpha (step 1e-4 s) against the reduced
  vehicle's exact response (ModalSimulator, first-order hold at 1 kHz); tolerance NRMSE 1e-2.

    python scripts/crosscheck_box.py [--coarse] [--cutoff 60]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from calibration.models.box.reduction import reduce_vehicle
from calibration.models.simulate import ModalSimulator
from calibration.truth.excitation import (
    EXCITER,
    SENSOR_GRID,
    ExcitationSettings,
    band_random,
    build_model,
)
from fmu_src.reference import nrmse
from reference_models.box import (
    build_box_exudyn,
    eigen_errors,
    exudyn_frequencies,
    full_frequencies,
    reduced_frequencies,
    simulate_box_exudyn,
)

TOL_EIG, TOL_NRMSE = 1e-4, 1e-2
ZETA, BELOW_HZ, DURATION, FS, STEP = 0.02, 20.0, 2.0, 1000.0, 1e-4


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--coarse", action="store_true", help="order_change = -4 (969 DOF) instead of full order")
    ap.add_argument("--cutoff", type=float, default=60.0, help="carbody modes kept [Hz]")
    args = ap.parse_args()
    t0 = time.perf_counter()
    model = build_model(ExcitationSettings(order_change=-4 if args.coarse else 0))
    p = np.ones(len(model.names))
    reduced = reduce_vehicle(model, p, args.cutoff, SENSOR_GRID, EXCITER)
    print(f"box model: {model.n_dof} DOF; reduced vehicle {reduced.M.shape[0]} coordinates "
          f"({reduced.n_modes} carbody modes <= {args.cutoff:g} Hz); railcal side {time.perf_counter() - t0:.1f} s")

    t0 = time.perf_counter()
    mbs, _ = build_box_exudyn(model, p, cutoff_hz=args.cutoff, zeta=ZETA)
    build = time.perf_counter() - t0
    t0 = time.perf_counter()
    ex = exudyn_frequencies(mbs, BELOW_HZ)
    t_eig = time.perf_counter() - t0
    red, full = reduced_frequencies(reduced, BELOW_HZ), full_frequencies(model, p, BELOW_HZ)
    ok = len(ex) == len(red) == len(full)
    e_red, e_full = eigen_errors(red, ex), eigen_errors(full, ex)
    print(f"\nvehicle eigenfrequencies below {BELOW_HZ:g} Hz [Hz] (exudyn build {build:.1f} s, eigen {t_eig:.2f} s)")
    print(f"  {'full model':>12} {'reduced':>12} {'exudyn':>12} {'err vs red':>11} {'err vs full':>11}")
    for i, f in enumerate(red):
        g = ex[np.argmin(np.abs(ex - f))]
        gf = full[np.argmin(np.abs(full - g))]
        print(f"  {gf:12.6f} {f:12.6f} {g:12.6f} {e_red[i]:11.2e} {np.abs(g - gf) / gf:11.2e}")
    ok_eig = ok and e_red.max() <= TOL_EIG
    print(f"  counts: full {len(full)}, reduced {len(red)}, exudyn {len(ex)}; max rel. error vs reduced "
          f"{e_red.max():.2e}, vs full {e_full.max():.2e} (tol {TOL_EIG:g}) -> {'PASS' if ok_eig else 'FAIL'}")

    n = round(DURATION * FS) + 1
    t = np.arange(n) / FS
    force = band_random(n, FS, (5.0, 50.0), 500.0, np.random.default_rng(7))
    w = np.zeros((n, 9))
    w[:, 8] = force
    t0 = time.perf_counter()
    ref = ModalSimulator(reduced.state_space(ZETA), 1.0 / FS).step_chunk(w)
    t_ref = time.perf_counter() - t0
    res = simulate_box_exudyn(model, p, t, force, cutoff_hz=args.cutoff, zeta=ZETA, step_size=STEP)
    err = np.array([nrmse(res.acc[:, i], ref[:, i]) for i in range(len(SENSOR_GRID))])
    ok_t = err.max() <= TOL_NRMSE
    print(f"\nfloor accelerations, {DURATION:g} s band-random 5-50 Hz 500 N rms, zeta {ZETA:g}, step {STEP:g} s")
    print(f"  NRMSE over {len(err)} sensors: max {err.max():.2e} ({res.sensors[int(np.argmax(err))]}), median "
          f"{np.median(err):.2e} (tol {TOL_NRMSE:g}) -> {'PASS' if ok_t else 'FAIL'}")
    print(f"  wall: exudyn integration {res.wall_time:.1f} s (+ build {res.build_time:.1f} s); exact reference "
          f"{t_ref:.2f} s")
    return 0 if ok_eig and ok_t else 1


if __name__ == "__main__":
    sys.exit(main())
