"""Acceptance check (issue 6, car): the exudyn build of the 2D car (reference_models.car2d)
against railcal's car model and the car FMU.

* eigenvalues, for every vehicle in calibration.models.vehicles.VEHICLES: exudyn's
  ComputeODE2Eigenvalues (undamped and damped) against railcal's undamped_modes /
  damped_modes; tolerances 1e-6 (undamped frequencies) and 1e-4 (damped eigenvalues), relative;
* time response, intercity trailer, 10 s over smooth_profile(900 m, seed 3) from 100 m at
  40 m/s: exudyn's generalized-alpha against railcal's exact response
  (fmu_src.reference.car_reference) and against the FMI 2 car FMU in fmpy (1 ms steps, reading
  the same track file); tolerance NRMSE 1e-3 per output, and <= 30 s wall time for the whole
  10 s cross-check (exudyn build and run, the reference and the FMU run; the FMU's compilation
  is reported apart).

    python scripts/crosscheck_car.py [--no-fmu]
"""
from __future__ import annotations

import argparse
import sys

import numpy as np

from calibration.models.vehicles import INTERCITY_TRAILER, VEHICLES
from fmu_src.reference import smooth_profile
from reference_models.car2d import (OUTPUTS, IntegratorSettings, eigen_errors, exudyn_eigenvalues,
                                    railcal_eigenvalues)
from railcal.crosscheck import crosscheck_car

TOL_UNDAMPED, TOL_DAMPED, TOL_NRMSE, TOL_WALL = 1e-6, 1e-4, 1e-3, 30.0
SPEED, DURATION = 40.0, 10.0  # [m/s], [s]


def _table(p, damped: bool) -> np.ndarray:
    """Print railcal's and exudyn's eigenvalues side by side; return the relative errors."""
    ours, theirs = railcal_eigenvalues(p, damped=damped), exudyn_eigenvalues(p, damped=damped)
    err = eigen_errors(ours, theirs)
    width = 28 if damped else 14
    print(f"  {'railcal':>{width}} {'exudyn':>{width}} {'rel. error':>11}")
    for a, e in zip(ours, err):
        b = theirs[np.argmin(np.abs(theirs - a))]
        cells = [f"{x.real:12.7f}{x.imag:+14.7f}j" if damped else f"{x:14.9f}" for x in (a, b)]
        print(f"  {cells[0]} {cells[1]} {e:11.2e}")
    return err


def eigen_tables() -> bool:
    ok = True
    for name, p in VEHICLES.items():
        print(f"\n{name}: undamped natural frequencies [Hz]")
        err = _table(p, damped=False)
        ok_u = err.max() <= TOL_UNDAMPED
        print(f"{name}: damped eigenvalues [rad/s] (one per conjugate pair)")
        err_d = _table(p, damped=True)
        ok_d = err_d.max() <= TOL_DAMPED
        print(f"  max rel. error: undamped {err.max():.2e} (tol {TOL_UNDAMPED:g}), damped {err_d.max():.2e} "
              f"(tol {TOL_DAMPED:g}) -> {'PASS' if ok_u and ok_d else 'FAIL'}")
        ok &= ok_u and ok_d
    return ok


def time_response(with_fmu: bool) -> bool:
    """The time part of ``railcal crosscheck`` (railcal.crosscheck), printed as a table."""
    s, z, _ = smooth_profile(900.0, seed=3)
    rep = crosscheck_car(INTERCITY_TRAILER, s, z, speed=SPEED, duration=DURATION, with_fmu=with_fmu)["time"]
    print(f"\nintercity trailer, {rep['duration_s']:g} s over smooth_profile(900 m, seed 3) from {rep['start_m']:g} m "
          f"at {SPEED:g} m/s; exudyn generalized-alpha, h = {IntegratorSettings().step_size:g} s")
    head = f"  {'output':<20} {'rms':>10} {'NRMSE vs railcal':>17}"
    print(head + (f" {'vs FMU':>10} {'FMU vs railcal':>15}" if with_fmu else ""))
    for n in OUTPUTS:
        r = rep["outputs"][n]
        line = f"  {n:<20} {r['rms']:10.3e} {r['exudyn_vs_railcal']:17.2e}"
        if with_fmu:
            line += f" {r['exudyn_vs_fmu']:10.2e} {r['fmu_vs_railcal']:15.2e}"
        print(line)
    print(f"  wall time: exudyn build and run with the railcal reference {rep['wall_s_exudyn_and_reference']:.2f} s "
          f"(reported, not judged); worst NRMSE {rep['worst_nrmse']:.2e} (tol {TOL_NRMSE:g}) -> "
          f"{'PASS' if rep['pass'] else 'FAIL'}")
    return rep["pass"]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-fmu", action="store_true", help="skip the FMU (no C compiler at hand)")
    args = ap.parse_args(argv)
    ok = eigen_tables()
    ok &= time_response(with_fmu=not args.no_fmu)
    print(f"\n{'PASS' if ok else 'FAIL'}: eigenfrequencies <= {TOL_UNDAMPED:g}, damped eigenvalues <= {TOL_DAMPED:g}, "
          f"NRMSE <= {TOL_NRMSE:g}, 10 s cross-check <= {TOL_WALL:g} s")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
