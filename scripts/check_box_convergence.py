"""Acceptance check (issue 4): convergence of the box-type model over polynomial order.

Solves the Shinkansen-type model at its default panel orders and with every order raised
by 1, 2 and 3, for the free carbody (first 12 elastic modes = modes 7-18) and for the
vehicle on its suspension (modes 7-18), and prints the change of each frequency against
the finest model. Target: the default's first 12 elastic frequencies within 0.1 %.

    python scripts/check_box_convergence.py [--increases 1 2 3]
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import scipy.linalg

from calibration.models.box import assemble, free_carbody, shinkansen_vehicle


def frequencies(vehicle, n=18):
    model = assemble(vehicle)
    K = model.stiffness(np.ones(len(model.names))).toarray()
    w2 = scipy.linalg.eigh(K, model.M.toarray(), eigvals_only=True, subset_by_index=[0, n - 1])
    return model.n_dof, np.sqrt(np.clip(w2, 0, None)) / (2 * np.pi)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--increases", type=int, nargs="+", default=[1, 2, 3])
    args = ap.parse_args()
    ok = True
    for label, build in (("free carbody", lambda inc: free_carbody(shinkansen_vehicle(order_increase=inc))),
                         ("vehicle on its suspension", lambda inc: shinkansen_vehicle(order_increase=inc))):
        rows = []
        for inc in [0] + args.increases:
            t0 = time.perf_counter()
            n, f = frequencies(build(inc))
            rows.append((inc, n, f[6:18], time.perf_counter() - t0))
        finest = rows[-1][2]
        print(f"\n{label}: modes 7-18 [Hz]")
        for inc, n, f, dt in rows:
            change = 100 * (f / finest - 1)
            print(f"  orders +{inc}: {n:5d} DOF ({dt:4.1f} s)  " + " ".join(f"{x:7.3f}" for x in f)
                  + f"   max change vs +{rows[-1][0]}: {np.abs(change).max():.3f} %")
        worst = float(np.abs(100 * (rows[0][2] / finest - 1)).max())
        passed = worst <= 0.1
        ok &= passed
        print(f"  default orders ({rows[0][1]} DOF): worst of the first 12 elastic frequencies {worst:.3f} % "
              f"from the +{rows[-1][0]} model (target <= 0.1 %): {'PASS' if passed else 'FAIL'}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
