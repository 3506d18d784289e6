"""Benchmark: the excitation-test diagnosis on every seed of tests/test_diagnosis_excitation.py's
campaign table, including the series once set aside after a failure (a seed is never
retired for failing: it stays a case, and the rate counts it).

Series 5201-5208, 5301-5308 and 5311-5318, each: underfloor equipment at the low and high
end of its range (mass ratio 0.01, 0.05), local panel softening at both ends (divisor 3,
10), effect-free, a sensor on a resilient bracket (21 Hz; outside the catalogue, so the
right answer is `unexplained`), and the force sensor reading 0.96 and 1.10 times the
applied force (cases 7 and 8, added with the extension ``force_calibration``). The coarse box model and the lighter settings of the
test file (``FAST``), one BLAS thread per worker. Prints one line per campaign and the
right-answer rate with its 95 % interval (Wilson score), overall and per effect.

    python scripts/bench_diagnose_excitation_seeds.py [--series 5201 5301 5311] [--jobs 2] [--only NAME]
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from scipy.stats import binomtest  # noqa: E402

#: position in a series -> (case, effect, magnitude), as in the test file's table
LAYOUT = ((1, "equipment_low", "underfloor_equipment", 0.01), (2, "equipment_high", "underfloor_equipment", 0.05),
          (3, "softening_low", "local_panel_softening", 3.0), (4, "softening_high", "local_panel_softening", 10.0),
          (5, "effect_free", None, None), (6, "outside_catalogue", "sensor_bracket", 21.0),
          (7, "force_low", "force_calibration", 0.96), (8, "force_high", "force_calibration", 1.10))
COARSE_BOX_ORDERS = -4  # tests/conftest.py
_MODEL = {}


def _init() -> None:
    from calibration.models.box.shinkansen import shinkansen_model
    from calibration.truth.excitation import ExcitationSettings

    _MODEL["settings"] = ExcitationSettings(runs=2, duration=300.0, order_change=COARSE_BOX_ORDERS)
    _MODEL["model"] = shinkansen_model(_MODEL["settings"].order_change)


def _case(case: dict) -> dict:
    from calibration.data.campaign import open_campaign
    from calibration.diagnosis.excitation import ExcitationDiagnosisSettings, diagnose_excitation
    from calibration.truth.effects import UNCATALOGUED, EffectChoice, effect_spec
    from calibration.truth.excitation import synth_excitation

    # the test file's FAST
    fast = ExcitationDiagnosisSettings(basis_extra=32, derivative_modes=12, refine_iterations=30, starts=2)
    effect = None if case["effect"] is None else EffectChoice(effect_spec(case["effect"]), case["magnitude"])
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / f"shaker_{case['seed']}"
        truth = synth_excitation(root, seed=case["seed"], settings=_MODEL["settings"], effect=effect,
                                 model=_MODEL["model"])
        t0 = time.perf_counter()
        result = diagnose_excitation(open_campaign(root), model=_MODEL["model"], settings=fast)
        wall = time.perf_counter() - t0
    hidden = case["effect"] or "none"
    expected = "unexplained" if hidden in UNCATALOGUED else hidden
    eff = truth["effect"] or {}
    return {**case, "cause": result.cause, "expected": expected, "right": result.cause == expected,
            "gain": result.extension.gain if result.extension else None, "panel": eff.get("panel"),
            "found": dict(result.extension.parameters) if result.extension else None,
            "confidence": None if result.certainty is None else
            f"{result.certainty.word}, {result.certainty.interval_words().strip(' ()')}",
            "hypotheses": {h.name: round(h.gain, 3) for h in result.hypotheses},
            "baseline_heldout_error": result.evidence.heldout_error_mean, "wall_s": wall}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--series", type=int, nargs="+", default=[5201, 5301, 5311], help="first seed of each series")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--only", help="run only this case of each series (e.g. softening_low)")
    args = ap.parse_args()
    cases = [{"seed": s0 + k - 1, "case": name, "effect": eff, "magnitude": mag}
             for s0 in args.series for k, name, eff, mag in LAYOUT if args.only in (None, name)]
    print(f"{len(cases)} campaigns: seeds {', '.join(str(c['seed']) for c in cases)}", flush=True)
    rows = []
    with multiprocessing.get_context("spawn").Pool(args.jobs, initializer=_init) as pool:
        for r in pool.imap_unordered(_case, cases):
            rows.append(r)
            gain = "" if r["gain"] is None else \
                f", held-out error -{r['gain']:.0%} (confidence {r['confidence']}), found {r['found']}"
            print(f"seed {r['seed']} {r['case']}{'' if r['panel'] is None else ' (' + r['panel'] + ')'}: "
                  f"{r['cause']} ({'right' if r['right'] else 'WRONG, expected ' + r['expected']}{gain}; "
                  f"hypotheses {r['hypotheses']}; baseline error {r['baseline_heldout_error']:.2f}; "
                  f"{r['wall_s']:.0f} s)", flush=True)
    rows.sort(key=lambda r: r["seed"])
    k, n = sum(r["right"] for r in rows), len(rows)
    ci = binomtest(k, n).proportion_ci(method="wilson")
    print(f"\nright answer {k}/{n} = {k / n:.0%} (95 % interval {ci.low:.0%}-{ci.high:.0%})")
    for _, name, _, _ in LAYOUT:
        sel = [r for r in rows if r["case"] == name]
        if sel:
            kk = sum(r["right"] for r in sel)
            ci = binomtest(kk, len(sel)).proportion_ci(method="wilson")
            print(f"  {name}: {kk}/{len(sel)} (95 % interval {ci.low:.0%}-{ci.high:.0%}); wrong: "
                  f"{', '.join(str(r['seed']) + ' -> ' + r['cause'] for r in sel if not r['right']) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
