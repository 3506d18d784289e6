"""Benchmark of ``railcal diagnose`` on synthetic in-service campaigns (issue 7).

For every in-service effect of the catalogue, ``--seeds`` campaigns with the effect hidden
at a magnitude drawn uniformly across its range; as many effect-free campaigns; and as
many with an effect outside the catalogue (``bogie_equipment``), which must come out
``unexplained``. Seeds start at ``--first-seed`` (1000: never used while developing).
Prints the confusion matrix, the right-cause rate per effect, the false-alarm rate on
effect-free data, the held-out error reduction where the cause is right, and the wall
time per diagnosis; writes every case to ``--out``.

    python scripts/bench_diagnose.py [--seeds 10] [--journeys 4] [--length-km 8] [--jobs 2]

With ``--table``: instead, the campaign table of ``tests/test_diagnosis.py`` (each effect
at both ends of its range, seeds 61-72, 3 journeys x 8 km, 4 for track flexibility), of
which the suite runs the low ends only.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from multiprocessing import Pool
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # one thread per worker
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calibration.data.campaign import open_campaign  # noqa: E402
from calibration.diagnosis.in_service import diagnose_in_service  # noqa: E402
from calibration.truth.effects import EFFECTS, EffectChoice, effect_spec  # noqa: E402
from calibration.truth.in_service import InServiceSettings, synth_in_service  # noqa: E402
from calibration.truth.track import LineSpec  # noqa: E402

IN_SERVICE = [n for n, s in EFFECTS.items() if "in_service" in s.kinds]
OUTSIDE = "bogie_equipment"


def run_case(case: dict) -> dict:
    root = Path(case["folder"]) / f"c{case['seed']}"
    effect = None if case["effect"] == "none" else EffectChoice(effect_spec(case["effect"]), case["magnitude"])
    settings = InServiceSettings(journeys=case["journeys"], line=LineSpec(length=case["length_km"] * 1000.0),
                                 carbody_sensors=True)
    t0 = time.perf_counter()
    truth = synth_in_service(root, seed=case["seed"], settings=settings, effect=effect, fmt="parquet")
    t1 = time.perf_counter()
    diag = diagnose_in_service(open_campaign(root))
    t2 = time.perf_counter()
    shutil.rmtree(root, ignore_errors=True)
    return {**case, "diagnosed": diag.cause, "gain": diag.to_json()["gain"],
            "extension": diag.best and diag.best.parameters,
            "truth_details": truth["effect"] and truth["effect"]["details"],
            "hypotheses": {h.name: h.gain for h in diag.hypotheses},
            "systematic_left": {h.name: h.systematic_left for h in diag.hypotheses if h.systematic_left is not None},
            "synth_s": t1 - t0, "diagnose_s": t2 - t1}


def _table(folder: str) -> list[dict]:
    """The hidden-effect cases of tests/test_diagnosis.py, both ends of each range."""
    import importlib.util

    path = Path(__file__).resolve().parents[1] / "tests" / "test_diagnosis.py"
    spec = importlib.util.spec_from_file_location("test_diagnosis_table", path)
    table = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(table)
    return [{"effect": name, "magnitude": float(EFFECTS[name].magnitude_range[end]), "seed": table.SEEDS[(name, end)],
             "journeys": 4 if name == "track_flexibility" else 3, "length_km": 8.0, "folder": folder}
            for name, end in table.CASES]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=1000)
    ap.add_argument("--journeys", type=int, default=4)
    ap.add_argument("--length-km", type=float, default=8.0)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out", default="bench_diagnose.json")
    ap.add_argument("--table", action="store_true", help="the test file's campaign table instead")
    args = ap.parse_args(argv)
    rng = np.random.default_rng(args.first_seed)
    folder = tempfile.mkdtemp(prefix="railcal_bench_diagnose_")
    cases, seed = [], args.first_seed
    if args.table:
        cases = _table(folder)
    for name in [] if args.table else IN_SERVICE + ["none", OUTSIDE]:
        spec = None if name == "none" else effect_spec(name)
        for _ in range(args.seeds):
            mag = None if spec is None else float(rng.uniform(*spec.magnitude_range))
            cases.append({"effect": name, "magnitude": mag, "seed": seed, "journeys": args.journeys,
                          "length_km": args.length_km, "folder": folder})
            seed += 1
    t0 = time.perf_counter()
    results = []
    with Pool(args.jobs) as pool:
        for r in pool.imap_unordered(run_case, cases):
            results.append(r)
            mag = "" if r["magnitude"] is None else f"={r['magnitude']:.4g}"
            gain = "" if r["gain"] is None else f", held-out error -{r['gain']['reduction']:.0%}"
            print(f"[{len(results)}/{len(cases)}] seed {r['seed']}: {r['effect']}{mag} -> {r['diagnosed']}{gain} "
                  f"({r['diagnose_s']:.1f} s)", flush=True)
    wall = time.perf_counter() - t0
    shutil.rmtree(folder, ignore_errors=True)
    Path(args.out).write_text(json.dumps(results, indent=1))

    truths = [t for t in IN_SERVICE + ["none", OUTSIDE] if any(r["effect"] == t for r in results)]
    answers = IN_SERVICE + ["none", "unexplained"]
    expected = {**{n: n for n in IN_SERVICE}, "none": "none", OUTSIDE: "unexplained"}
    sizes = ("the test table, 3-4 journeys x 8 km" if args.table
             else f"{args.seeds} campaigns per row, {args.journeys} journeys x {args.length_km:g} km")
    print(f"\nconfusion matrix ({sizes}, carbody sensors; rows: truth, columns: diagnosis)")
    print(" " * 22 + "".join(f"{a[:9]:>10s}" for a in answers))
    for t in truths:
        row = [sum(1 for r in results if r["effect"] == t and r["diagnosed"] == a) for a in answers]
        print(f"{t:22s}" + "".join(f"{n:>10d}" for n in row))
    print()
    ok_all = True
    for t in truths:
        rs = [r for r in results if r["effect"] == t]
        right = [r for r in rs if r["diagnosed"] == expected[t]]
        rate = len(right) / len(rs)
        line = f"{t:22s} right {len(right)}/{len(rs)} = {rate:.0%}"
        if t in IN_SERVICE:
            gains = [r["gain"]["reduction"] for r in right]
            below = sum(g < 0.3 for g in gains)
            line += (f"; held-out error reduction min {min(gains):.0%}, median {np.median(gains):.0%}, "
                     f"{below} below 30 %" if gains else "")
            ok_all &= rate >= 0.9 and below == 0
        elif t == "none":
            alarms = len(rs) - len(right)
            line += f"; false alarms {alarms}/{len(rs)} = {alarms / len(rs):.0%} (target <= 10 %)"
            ok_all &= alarms / len(rs) <= 0.1
        else:
            named = [r["diagnosed"] for r in rs if r["diagnosed"] not in ("unexplained",)]
            line += f"; named as a catalogue cause: {len(named)} ({', '.join(sorted(set(named))) or '-'})"
            ok_all &= rate >= 0.9
        print(line)
    times = [r["diagnose_s"] for r in results]
    print(f"\ndiagnosis wall time per campaign: median {np.median(times):.1f} s, max {max(times):.1f} s "
          f"({args.jobs} in parallel); whole bench {wall / 60:.1f} min")
    print("acceptance (>= 90 % right per effect, <= 10 % false alarms, >= 30 % gain when right): "
          + ("met" if ok_all else "NOT met"))
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
