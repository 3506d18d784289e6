"""Benchmark (issue 3): Cross-Entropy with the seed's settings on its Table 4 targets and
Table 7 ranges, 10 runs; targets: every run within 0.01 Hz of every target (seed Table 8),
<= 5 s for the 10 runs; the run averages compared with seed Table 9; then the CasADi
refinement from the average (target: <= 1e-6 relative frequency error).

Prints each run, the wall time, PASS/FAIL per target, and the averages beside Table 9.
``--deviation-about elite`` and ``--smoothing A`` run the other readings of the seed's
update (see calibration/optimisers/cross_entropy.py).

    python scripts/bench_calibrate_car.py [--deviation-about sampling|elite] [--smoothing 1.0] [--runs 10]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from calibration.calibrate import SEED_TABLE4
from calibration.models.batch import LinearFamily
from calibration.models.vehicles import INTERCITY_TRAILER, SEED_TABLE9
from calibration.optimisers.base import bounds
from calibration.optimisers.cross_entropy import SEED_TABLE7, CESettings, cross_entropy
from calibration.optimisers.objectives import sum_squared_error
from calibration.optimisers.refine import refine


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--smoothing", type=float, default=1.0)
    ap.add_argument("--deviation-about", choices=("sampling", "elite"), default="sampling")
    args = ap.parse_args()
    names = tuple(p.name for p in SEED_TABLE7)
    family = LinearFamily.of_car(INTERCITY_TRAILER, names=names)

    def objective(X):
        return sum_squared_error(family.frequencies(X), SEED_TABLE4)

    settings = CESettings(smoothing=args.smoothing, deviation_about=args.deviation_about)
    print(f"CE settings: {settings}")
    t0 = time.perf_counter()
    means, worst = [], 0.0
    for k in range(args.runs):
        r = cross_entropy(objective, SEED_TABLE7, np.random.default_rng(k), settings=settings)
        F = family.frequencies(r.mean[None, :])
        err = {lbl: float(F[lbl][0] - f) for lbl, f in SEED_TABLE4.items()}
        worst = max(worst, max(abs(e) for e in err.values()))
        means.append(r.mean)
        print(f"run {k + 1:2d}: {r.generations:4d} generations, {r.restarts:2d} restarts, converged {r.converged}; "
              + ", ".join(f"{lbl} {F[lbl][0]:.3f}" for lbl in SEED_TABLE4))
    wall = time.perf_counter() - t0
    avg = np.mean(means, axis=0)
    print(f"\nwall time for {args.runs} runs: {wall:.2f} s (target <= 5 s): {'PASS' if wall <= 5 else 'FAIL'}")
    print(f"worst |model - target| over all runs: {worst:.4f} Hz (target <= 0.01 Hz): "
          f"{'PASS' if worst <= 0.01 else 'FAIL'}")
    print("\nparameter      average      seed Table 9 average   difference")
    for n, a, b in zip(names, avg, SEED_TABLE9.mean(axis=0)):
        print(f"{n:6s} {a:16.0f} {b:16.0f} {100 * (a / b - 1):+10.1f} %")
    low, high = bounds(SEED_TABLE7)
    # Why the averages differ: four frequencies leave two directions free (identifiability),
    # and the seed's m_b lies outside its own Table 7 range, so its runs sat elsewhere on them.
    m_b_high = high[names.index("m_b")]
    print(f"\nseed Table 9 m_b {SEED_TABLE9[:, names.index('m_b')].min():.0f}-"
          f"{SEED_TABLE9[:, names.index('m_b')].max():.0f} kg against the Table 7 upper limit {m_b_high:.0f} kg: "
          f"{'outside' if SEED_TABLE9[:, names.index('m_b')].min() > m_b_high else 'inside'} the range this search is truncated to")
    F9 = family.frequencies(SEED_TABLE9)
    err9 = np.array([F9[lbl] - f for lbl, f in SEED_TABLE4.items()])
    print("seed Table 9 runs through our model, worst |model - target| per run [Hz]: "
          + " ".join(f"{e:.4f}" for e in np.abs(err9).max(axis=0)))
    t1 = time.perf_counter()
    ref = refine(family, avg, SEED_TABLE4, low, high)
    print(f"\nCasADi refinement from the average: {ref.status}, objective {ref.objective_start:.3g} -> "
          f"{ref.objective_end:.3g}, max relative error {ref.max_relative_error:.2e} (target <= 1e-6): "
          f"{'PASS' if ref.max_relative_error <= 1e-6 else 'FAIL'}; {time.perf_counter() - t1:.2f} s")
    print("refined: " + ", ".join(f"{n} {v:.0f}" for n, v in zip(names, ref.parameters)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
