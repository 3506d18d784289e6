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
import tempfile
import time
from pathlib import Path

import numpy as np

from calibration.models.vehicles import INTERCITY_TRAILER, VEHICLES
from fmu_src.reference import car_reference, nrmse, smooth_profile
from fmu_src.variables import car2d_spec
from reference_models.car2d import (OUTPUTS, IntegratorSettings, RailInput, eigen_errors, exudyn_eigenvalues,
                                    railcal_eigenvalues, simulate_car_exudyn)

TOL_UNDAMPED, TOL_DAMPED, TOL_NRMSE, TOL_WALL = 1e-6, 1e-4, 1e-3, 30.0
SPEED, START, DURATION, OUTPUT_INTERVAL = 40.0, 100.0, 10.0, 1e-3  # [m/s], [m], [s], [s]


def eigen_tables() -> bool:
    ok = True
    for name, p in VEHICLES.items():
        ours, theirs = railcal_eigenvalues(p, damped=False), exudyn_eigenvalues(p, damped=False)
        err = eigen_errors(ours, theirs)
        print(f"\n{name}: undamped natural frequencies [Hz]")
        print(f"  {'railcal':>14} {'exudyn':>14} {'rel. error':>11}")
        for a, e in zip(ours, err):
            b = theirs[np.argmin(np.abs(theirs - a))]
            print(f"  {a:14.9f} {b:14.9f} {e:11.2e}")
        ok_u = err.max() <= TOL_UNDAMPED
        ours, theirs = railcal_eigenvalues(p, damped=True), exudyn_eigenvalues(p, damped=True)
        err_d = eigen_errors(ours, theirs)
        print(f"{name}: damped eigenvalues [rad/s] (one per conjugate pair)")
        print(f"  {'railcal':>28} {'exudyn':>28} {'rel. error':>11}")
        for a, e in zip(ours, err_d):
            b = theirs[np.argmin(np.abs(theirs - a))]
            print(f"  {a.real:12.7f}{a.imag:+14.7f}j {b.real:12.7f}{b.imag:+14.7f}j {e:11.2e}")
        ok_d = err_d.max() <= TOL_DAMPED
        print(f"  max rel. error: undamped {err.max():.2e} (tol {TOL_UNDAMPED:g}), damped {err_d.max():.2e} "
              f"(tol {TOL_DAMPED:g}) -> {'PASS' if ok_u and ok_d else 'FAIL'}")
        ok &= ok_u and ok_d
    return ok


def fmu_outputs(spec, track: Path, workdir: Path, t: np.ndarray) -> tuple[dict, float, float]:
    """The FMI 2 car FMU stand-alone over ``track``: outputs at ``t``, build and run time [s]."""
    import fmpy

    from fmu_src.build import build_fmu

    t0 = time.perf_counter()
    built = build_fmu(spec, 2, workdir / "car2.fmu")
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = fmpy.simulate_fmu(str(built.path), start_time=0.0, stop_time=float(t[-1]), output_interval=OUTPUT_INTERVAL,
                            step_size=OUTPUT_INTERVAL, output=list(OUTPUTS),
                            start_values={"speed": SPEED, "track_start": START})
    t_run = time.perf_counter() - t0
    if len(res["time"]) != len(t) or np.max(np.abs(res["time"] - t)) > 1e-9:
        raise RuntimeError("the FMU's output times differ from exudyn's")
    return {n: np.asarray(res[n]) for n in OUTPUTS}, t_build, t_run


def time_response(with_fmu: bool) -> bool:
    p = INTERCITY_TRAILER
    s, z, profile = smooth_profile(900.0, seed=3)
    rail = RailInput(s, z, SPEED, START)
    settings = IntegratorSettings()
    t_total = time.perf_counter()
    res = simulate_car_exudyn(p, rail, duration=DURATION, output_interval=OUTPUT_INTERVAL, settings=settings)
    with tempfile.TemporaryDirectory(prefix="railcal_xcheck_") as tmp:
        track = Path(tmp) / "track.csv"
        np.savetxt(track, np.column_stack([s, z]), delimiter=",", header="distance,level", comments="", fmt="%.17g")
        spec = car2d_spec(p.as_dict(), track=str(track))
        t0 = time.perf_counter()
        ref = car_reference(spec, p, profile, SPEED, res.t, start=START)
        t_ref = time.perf_counter() - t0
        fmu, t_fmu_build, t_fmu_run = fmu_outputs(spec, track, Path(tmp), res.t) if with_fmu else (None, 0.0, 0.0)
    wall = time.perf_counter() - t_total - t_fmu_build

    print(f"\nintercity trailer, {DURATION:g} s over smooth_profile(900 m, seed 3) from {START:g} m at {SPEED:g} m/s; "
          f"exudyn generalized-alpha, h = {settings.step_size:g} s, rho_inf = {settings.spectral_radius:g}")
    head = f"  {'output':<20} {'rms':>10} {'NRMSE vs railcal':>17}"
    print(head + (f" {'vs FMU':>10} {'FMU vs railcal':>15}" if fmu else ""))
    worst = 0.0
    for n in OUTPUTS:
        e = nrmse(res.outputs[n], ref[n])
        line = f"  {n:<20} {np.std(ref[n]):10.3e} {e:17.2e}"
        worst = max(worst, e)
        if fmu:
            e_fmu = nrmse(res.outputs[n], fmu[n])
            worst = max(worst, e_fmu)
            line += f" {e_fmu:10.2e} {nrmse(fmu[n], ref[n]):15.2e}"
        print(line)
    print(f"  wall time [s]: exudyn build {res.build_time:.2f} (symbolic rail functions), exudyn run "
          f"{res.wall_time:.2f}, railcal reference {t_ref:.2f}" + (f", FMU run {t_fmu_run:.2f}" if fmu else "") +
          f"; whole cross-check {wall:.2f}" + (f" (+ FMU compilation {t_fmu_build:.2f})" if fmu else ""))
    ok = worst <= TOL_NRMSE and wall <= TOL_WALL
    print(f"  worst NRMSE {worst:.2e} (tol {TOL_NRMSE:g}), wall {wall:.2f} s (tol {TOL_WALL:g} s) -> "
          f"{'PASS' if ok else 'FAIL'}")
    return ok


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
