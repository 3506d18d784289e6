"""Benchmark (issue 7): the diagnosis of excitation tests over many synthetic
campaigns with a hidden effect, magnitudes drawn across each range, and effect-free ones.

For each case: ``synth excitation`` (the truth simulator, default settings: 2 runs of
300 s) with ``underfloor_equipment`` (mass ratio drawn uniformly in 0.01-0.05),
``local_panel_softening`` (divisor drawn uniformly in 3-10), no effect, or an effect
outside the catalogue, ``sensor_bracket`` (one accelerometer on a resilient bracket,
natural frequency drawn uniformly in 10-28 Hz; it must come out ``unexplained``), or
``force_calibration`` (the force sensor off by 3-10 %, either way: drawn after the others,
so that adding it left their seeds and magnitudes as they were), then
:func:`calibration.diagnosis.excitation.diagnose_excitation` against the effect-free box
model. Seeds run from ``--start`` (2000) upwards, one per campaign; magnitudes come from
``numpy.random.default_rng(start)``. Prints one line per campaign, then the confusion
matrix (rows: hidden effect, columns: diagnosed cause), the right-cause rate per effect,
the false-alarm rate on effect-free campaigns, the share of the uncatalogued campaigns
answered ``unexplained``, the held-out error reduction where the cause is right, and the
wall time per diagnosis.

Targets (issue 7): right cause >= 90 % for every effect, false alarms <= 10 %, held-out
error reduced >= 30 % whenever the cause is right; an effect outside the catalogue never
under a wrong name (``unexplained``).

    python scripts/bench_diagnose_excitation.py [--seeds 10] [--start 2000] [--jobs 2] [--coarse] [--only NAME]

Each worker process runs its linear algebra on one thread (``OMP_NUM_THREADS=1`` and
friends are set before numpy is imported): with ``--jobs 2`` on two cores that is
several times faster than two processes fighting over threaded BLAS.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import binomtest  # noqa: E402

EFFECT_NAMES = ("underfloor_equipment", "local_panel_softening", "force_calibration")
OUTSIDE = "sensor_bracket"  # outside the catalogue: must be `unexplained`
CAUSES = EFFECT_NAMES + ("none", "unexplained")
#: the force sensor's error drawn in these bounds (relative), either sign
FORCE_ERROR = (0.03, 0.10)

_MODEL = {}  # per worker process: the assembled box model, built once by _init


def _init(order_change: int) -> None:
    from calibration.models.box.shinkansen import shinkansen_model
    from calibration.truth.excitation import ExcitationSettings

    _MODEL["settings"] = ExcitationSettings(order_change=order_change)
    _MODEL["model"] = shinkansen_model(_MODEL["settings"].order_change)


def _case(case: dict) -> dict:
    from calibration.data.campaign import open_campaign
    from calibration.diagnosis.excitation import diagnose_excitation
    from calibration.truth.effects import EffectChoice, effect_spec
    from calibration.truth.excitation import synth_excitation

    settings, model = _MODEL["settings"], _MODEL["model"]
    effect = None if case["effect"] is None else EffectChoice(effect_spec(case["effect"]), case["magnitude"])
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp) / f"shaker_{case['seed']}"
        t0 = time.perf_counter()
        truth = synth_excitation(root, seed=case["seed"], settings=settings, effect=effect, model=model)
        t1 = time.perf_counter()
        result = diagnose_excitation(open_campaign(root), model=model)
        t2 = time.perf_counter()
    eff = truth["effect"] or {}
    hidden = {k: eff[k] for k in ("panel", "position_m", "mounting_frequency_hz", "equipment_mass_kg", "sensor",
                                  "force_gain", "frequency_hz") if k in eff}
    ext = result.extension
    return {**case, "cause": result.cause, "hidden": hidden,
            "found": dict(ext.parameters) if ext else None,
            "gain": ext.gain if ext else None,
            "confidence": None if result.certainty is None else result.certainty.to_json(),
            "hypotheses": {h.name: round(h.gain, 4) for h in result.hypotheses},
            "baseline_heldout_error": result.evidence.heldout_error_mean,
            "unpaired_modes": [{"hz": round(r.identified_hz, 3), "mac": round(r.mac, 3),
                                "heldout_error_near": r.heldout_error_near}
                               for r in result.evidence.unpaired],
            "summary": list(result.summary),
            "synth_s": t1 - t0, "diagnose_s": t2 - t1}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="campaigns per effect and effect-free (default 10)")
    ap.add_argument("--start", type=int, default=2000, help="first seed (default 2000)")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--coarse", action="store_true", help="coarse box model (every panel order - 4), as the tests")
    ap.add_argument("--out", type=Path, help="write every case's result to this JSON file")
    ap.add_argument("--only", choices=EFFECT_NAMES + ("none", OUTSIDE),
                    help="run only this effect's campaigns (same seeds and magnitudes as in the whole bench)")
    args = ap.parse_args()

    from calibration.truth.effects import EFFECTS, UNCATALOGUED

    rng = np.random.default_rng(args.start)
    cases, seed = [], args.start
    for name in EFFECT_NAMES[:2]:
        lo, hi = EFFECTS[name].magnitude_range
        for mag in rng.uniform(lo, hi, args.seeds):
            cases.append({"effect": name, "magnitude": float(mag), "seed": seed})
            seed += 1
    for _ in range(args.seeds):
        cases.append({"effect": None, "magnitude": None, "seed": seed})
        seed += 1
    for mag in rng.uniform(*UNCATALOGUED[OUTSIDE].magnitude_range, args.seeds):  # drawn last: earlier seeds unchanged
        cases.append({"effect": OUTSIDE, "magnitude": float(mag), "seed": seed})
        seed += 1
    for err, sign in zip(rng.uniform(*FORCE_ERROR, args.seeds), rng.choice([-1.0, 1.0], args.seeds)):
        cases.append({"effect": "force_calibration", "magnitude": float(1 + sign * err), "seed": seed})
        seed += 1
    if args.only:
        cases = [c for c in cases if (c["effect"] or "none") == args.only]
    order_change = -4 if args.coarse else 0
    print(f"{len(cases)} campaigns, seeds {cases[0]['seed']}-{cases[-1]['seed']}, "
          f"{'coarse' if args.coarse else 'full-order'} box model, {args.jobs} job(s)", flush=True)
    t0 = time.perf_counter()
    rows = []
    with multiprocessing.get_context("spawn").Pool(args.jobs, initializer=_init, initargs=(order_change,)) as pool:
        for r in pool.imap_unordered(_case, cases):
            rows.append(r)
            mag = "" if r["magnitude"] is None else f"={r['magnitude']:.3g}"
            gain = "" if r["gain"] is None else f", held-out error -{r['gain']:.0%}"
            if r["confidence"] is not None:
                lo, hi = r["confidence"]["interval_95"] or (float("nan"),) * 2
                gain += f" ({lo:.0%} to {hi:.0%}, {r['confidence']['confidence']})"
            print(f"seed {r['seed']}: {r['effect'] or 'effect-free'}{mag} -> {r['cause']}{gain} "
                  f"(hypotheses {r['hypotheses']}; baseline error {r['baseline_heldout_error']:.2f}; "
                  f"hidden {r['hidden']}; found {r['found']}; diagnosis {r['diagnose_s']:.0f} s)", flush=True)
    wall = time.perf_counter() - t0
    rows.sort(key=lambda r: r["seed"])
    print("\nconfusion matrix (rows: hidden effect; columns: diagnosed cause)")
    print(f"{'':>24}" + "".join(f"{c:>24}" for c in CAUSES))
    for hidden in EFFECT_NAMES + (None, OUTSIDE):
        sel = [r for r in rows if r["effect"] == hidden]
        if not sel:
            continue
        print(f"{hidden or 'effect-free':>24}" + "".join(f"{sum(r['cause'] == c for r in sel):>24}" for c in CAUSES))
    ok = True
    for name in EFFECT_NAMES:
        sel = [r for r in rows if r["effect"] == name]
        if not sel:
            continue
        right = [r for r in sel if r["cause"] == name]
        rate = len(right) / len(sel)
        gains = [r["gain"] for r in right]
        ok &= rate >= 0.9 and all(g >= 0.3 for g in gains)
        ci = binomtest(len(right), len(sel)).proportion_ci(method="wilson")
        words = [r["confidence"]["confidence"] for r in right if r.get("confidence")]
        print(f"{name}: right cause {len(right)}/{len(sel)} = {rate:.0%} (95 % interval {ci.low:.0%}-{ci.high:.0%}; "
              f"target >= 90 %); confidence when right: {', '.join(f'{w} {words.count(w)}' for w in sorted(set(words)))}"
              f"; held-out error "
              f"reduction when right: min {min(gains, default=float('nan')):.1%}, median "
              f"{np.median(gains) if gains else float('nan'):.1%} (target >= 30 %)")
    free = [r for r in rows if r["effect"] is None]
    alarms = [r for r in free if r["cause"] != "none"]
    ok &= len(alarms) <= 0.1 * len(free)
    if free:
        ci = binomtest(len(alarms), len(free)).proportion_ci(method="wilson")
        print(f"effect-free: false alarms {len(alarms)}/{len(free)} = {len(alarms) / len(free):.0%} (95 % interval "
              f"{ci.low:.0%}-{ci.high:.0%}; target <= 10 %)")
    outside = [r for r in rows if r["effect"] == OUTSIDE]
    if outside:
        named = [r for r in outside if r["cause"] != "unexplained"]
        ok &= not named
        print(f"{OUTSIDE} (outside the catalogue): unexplained {len(outside) - len(named)}/{len(outside)}, under a "
              f"wrong name {len(named)} (target 0)")
    d = np.array([r["diagnose_s"] for r in rows])
    print(f"wall time per diagnosis: median {np.median(d):.0f} s, max {d.max():.0f} s; synthesis median "
          f"{np.median([r['synth_s'] for r in rows]):.0f} s; whole bench {wall:.0f} s with {args.jobs} job(s)")
    print(("PASS" if ok else "FAIL") + (f" (only {args.only}: not the whole bench)" if args.only else ""))
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
