"""Acceptance check (issue 3): calibration of synthetic in-service campaigns against their truth.

For each seed: synthesise, identify, calibrate (Cross-Entropy, then CasADi refinement).
Targets: calibrated frequencies within 1 % of the identified ones; the true parameters
inside the reported 95 % intervals along every determined direction; at least two
undetermined directions reported when six parameters meet four frequencies. Printed beside
them, not judged: each targeted mode's undamped frequency in the calibrated car against the
truth car's (the identification estimates poles, |lambda| / 2 pi, which damping moves off the
undamped frequencies).

Expected before the pole-matching calibration's run (written with the run on 3c8439d going):
on 3c8439d, which fits the model's undamped frequencies to the identified poles, each mode's
calibrated undamped frequency sits above the truth's by about the truth car's pole shift
(carbody pitch +0.45 %, carbody bounce +0.10 %, bogie bounce -0.12 %, bogie pitch 0.00 %)
plus the identification's own error; matching the model's poles instead takes those shifts
out, leaving the identification's error alone, and every other figure holds.

Measured (seeds 1-5): the forecast failed. On 3c8439d the calibrated carbody pitch sat
-0.15, +0.28, -0.08, +0.38, +0.15 % off the truth's undamped frequency (mean +0.11 %): the
identification lies nearer the undamped frequency than the pole on this truth, and against
the pole its carbody pitch is -0.53, -0.06, -0.46, +0.03, -0.17 % (mean -0.24 %), its bogie
bounce +0.03 to +0.25 % (mean +0.13 %, against +0.06 % from the undamped). Calibrated to the
poles (d3829e7 and 309b2b2; fit within 4e-6 %) the pitch came out -0.57, -0.14, -0.53, -0.09,
-0.32 % (mean -0.33 %) and seed 4 lost the truth from one determined 95 % interval (19 of 20
inside). Pole matching was therefore taken back out; calibration matches the undamped
frequencies, the usual convention of model updating. (The truth cars' own pitch shifts were
0.32-0.38 %, not the nominal car's 0.45 %: their parameters, dampings included, are drawn
about the nominal.)

    python scripts/check_calibrate_in_service.py [--seeds 1 2 3 4 5] [--runs 10]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

from calibration.calibrate import calibrate_campaign
from calibration.data.campaign import open_campaign
from calibration.models.car2d import build_car, frequencies_by_label, pole_shifts, undamped_modes
from calibration.models.parameters import CarParameters
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    ap.add_argument("--runs", type=int, default=10)
    args = ap.parse_args()
    ok_all = True
    with tempfile.TemporaryDirectory() as tmp:
        for seed in args.seeds:
            root = Path(tmp) / f"c{seed}"
            truth = synth_in_service(root, seed=seed, fmt="parquet",
                                     settings=InServiceSettings(journeys=10, line=LineSpec(length=40_000.0)))
            res, modes = calibrate_campaign(open_campaign(root), runs=args.runs, seed=seed, refine_result=True)
            ident = res.identifiability
            names = ident["parameters"]
            x = np.log(np.array([truth["parameters"][n] for n in names]) /
                       np.array([getattr(res.parameters, n) for n in names]))
            inside = [bool(lo <= np.array(d["vector"]) @ x <= hi)
                      for d in ident["determined_directions"] for lo, hi in [d["interval_95_log"]]]
            true_f = frequencies_by_label(undamped_modes(build_car(CarParameters(**truth["parameters"]))))
            true_shift = pole_shifts(CarParameters(**truth["parameters"]), res.targets)
            true_pole = {k: true_f[k] * true_shift[k] for k in res.targets}
            cal_f = frequencies_by_label(undamped_modes(build_car(res.parameters)))
            row = {"seed": seed, "max_fit_error_pct": round(res.max_error_pct, 6),
                   "undamped_error_pct": {k: round(100 * (cal_f[k] / true_f[k] - 1), 3) for k in res.targets},
                   "identified_vs_truth_pole_pct": {m.label: round(100 * (m.frequency_hz / true_pole[m.label] - 1), 3)
                                                    for m in modes if m.label in true_pole},
                   "true_inside_95": inside, "undetermined": len(ident["undetermined_directions"]),
                   "parameter_error_pct": {n: round(100 * (getattr(res.parameters, n) / truth["parameters"][n] - 1), 1)
                                           for n in names}}
            ok = res.max_error_pct <= 1.0 and all(inside) and row["undetermined"] >= 2
            row["pass"] = ok
            ok_all &= ok
            print(json.dumps(row), flush=True)
    print(("PASS" if ok_all else "FAIL") + ": fit <= 1 %, truth inside every determined 95 % interval, >= 2 "
          "undetermined directions")
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
