"""Benchmark of the excitation-test diagnosis on the independent stationary truth (issue 31,
deliverable 4, "and the stationary one"): campaigns of the shell finite element carbody
(``synth excitation --truth exudyn``, docs/methods/truth-independent-stationary.md), which
the box model did not generate, each calibrated as a user would (``railcal calibrate --model box --method pso --factors
FACTORS --refine --particles 300 --iterations 300``: the command's swarm on the identified
modes, refined) and diagnosed from that calibration (``railcal diagnose
--calibration``), against the full-order box model: the commands themselves, run in
process. ``--factors`` is ``orthotropic`` (the default since 2026-11-28) or ``windowed``
(the bench's first runs); each set's calibrations and diagnoses are kept apart.

Cases, in this order (index k):

    k  case                    hidden (independent truth's STATIONARY_RANGES)   seeds
    0  clean                   nothing                                          --seeds
    1  underfloor_equipment    mass ratio 0.01-0.05, tuned to a mode in 8-20 Hz --seeds
    2  local_panel_softening   a region's rigidities / 3-10                     --seeds
    3  force_calibration       the load cell reads 1 +- (0.03-0.10) x the force --seeds
    4  sensor_bracket          an accelerometer on a 10-28 Hz bracket           --few
    5  rigid_equipment         300-1000 kg bolted to the floor                  --few

Expected answers, written before the first run (any answer in neither column is a miss):

    case                   right                      counts as a wrong name
    clean                  none                       any catalogue name (a false alarm)
    catalogue effect E     E                          any other catalogue name
    bracket, rigid         unexplained, none          any catalogue name with confidence high
                                                      (the issue's rule for near-mimics)

What I expect to happen (2026-11-28, before any run): `unexplained` on most campaigns. On
development seed 5 (clean) the windowed baseline met the identified modes within 2.5e-6 %
yet left the held-out FRFs 1047x the noise, and the load-cell hypothesis found a level
offset of 0.924 (the box carbody is 2.7 % heavier than the shell's and its modal masses
differ) that gained 5.5 %. On development seed 7 the equipment was found (603 kg at
13.26 Hz against 681 kg at 13.07 Hz) and gained 38 % but made one channel 39 % worse.
So: clean `unexplained` (a miss, not a false alarm); equipment named on a few campaigns,
the heavier ones; softening and force `unexplained`, their detectability limits above the
hidden sizes; the near-mimics `unexplained`, no wrong name.

With ``--factors orthotropic`` (written 2026-11-28 on e8fd1fc, before its first bench
run): development seed 5 (clean) left 344x the noise with this set against 1047x with the
windowed one, still `unexplained`; development seed 7 (equipment, 3 %) found the equipment
(519 kg at 13.14 Hz against 681 kg at 13.07 Hz) with a gain of 35 % (23-45 %), just under
its bar, `unexplained`. So again: clean `unexplained` on most campaigns, no catalogue name
(false alarms 0 or 1 of 10); equipment named on some of the heavier ones (mass ratio above
about 0.03), the rest `unexplained`; softening and force `unexplained` with detectability
limits above the hidden sizes; the near-mimics `unexplained`, no wrong name.

After the near-mimic rule of 3a3b734 (a cause fitted to a limit of its own search is at most
`moderate`), written before the fresh rigid-equipment seeds 6753-6755 ran: `unexplained` on
most, any catalogue name `moderate` at most; the equipment-on-mounts fit, where it gains, with
its damping or frequency at a limit as on 6751 and 6752.

Seed rule (stated once, never retired): case k, repetition j (0-based, j < 50) -> seed
``6500 + 50 k + j`` (6500-6799, never used before). The magnitude is drawn uniformly in the
case's range by ``numpy.random.default_rng([6500, k, j])`` (for the force, then its sign), so
adding repetitions leaves earlier campaigns as they were. Development runs use seeds below
100.

One campaign costs about 2.5 min of synthesis, 3-19 min of calibration and 9 min of
diagnosis on one core: the whole bench (4 x 10 + 2 x 3 campaigns) is a day of two cores;
``--only CASE --seeds N --from-rep J`` runs part of it, ``--keep DIR`` keeps the campaigns,
calibrations and diagnoses (a kept step is read, not run again).

    OPENBLAS_NUM_THREADS=1 python scripts/bench_diagnose_excitation_independent.py [--seeds 10] [--few 3]
        [--only CASE] [--from-rep J] [--jobs 1] [--keep DIR] [--out F.json] [--list]
        [--factors orthotropic|windowed]
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import functools  # noqa: E402
import json  # noqa: E402
import multiprocessing  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from scipy.stats import binomtest  # noqa: E402

FIRST_SEED, STRIDE = 6500, 50
#: (case, hidden effect or None, many seeds (--seeds) or few (--few))
CASES = (("clean", None, True), ("underfloor_equipment", "underfloor_equipment", True),
         ("local_panel_softening", "local_panel_softening", True), ("force_calibration", "force_calibration", True),
         ("sensor_bracket", "sensor_bracket", False), ("rigid_equipment", "rigid_equipment", False))
CATALOGUE = ("underfloor_equipment", "local_panel_softening", "force_calibration")
FORCE_ERROR = (0.03, 0.10)


def campaigns(seeds: int, few: int, only: str | None, from_rep: int) -> list[dict]:
    """Every campaign of the bench by the seed rule of the module's docstring."""
    from calibration.truth.independent.hidden import STATIONARY_RANGES

    out = []
    for k, (case, effect, many) in enumerate(CASES):
        if only not in (None, case):
            continue
        for j in range(from_rep, seeds if many else few):
            rng = np.random.default_rng([FIRST_SEED, k, j])
            magnitude = None
            if effect == "force_calibration":
                magnitude = 1.0 + float(rng.choice([-1.0, 1.0])) * float(rng.uniform(*FORCE_ERROR))
            elif effect is not None:
                lo, hi = STATIONARY_RANGES[effect][:2]
                magnitude = float(rng.uniform(lo, hi))
            out.append({"case": case, "effect": effect, "magnitude": magnitude, "seed": FIRST_SEED + STRIDE * k + j})
    return out


def verdict(case: str, cause: str, confidence: str | None) -> str:
    """right, wrong (a wrong name) or missed, by the table of the module's docstring."""
    if case == "clean":
        return "right" if cause == "none" else ("wrong" if cause in CATALOGUE else "missed")
    if case in CATALOGUE:
        return "right" if cause == case else ("wrong" if cause in CATALOGUE else "missed")
    if cause in ("unexplained", "none"):
        return "right"
    return "wrong" if confidence == "high" else "missed"


def _run(c: dict, keep: Path, factors: str) -> dict:
    """One campaign by the user's three commands, each step kept in ``keep`` and read back
    when there (the calibration and diagnosis per factor set; the windowed set's under the
    names of the bench's first runs)."""
    from railcal.cli import main as railcal

    tag = "" if factors == "windowed" else f"_{factors}"
    root, cal, diag = keep / f"shaker_{c['seed']}", keep / f"shaker_{c['seed']}{tag}_cal.json", \
        keep / f"shaker_{c['seed']}{tag}_diag.json"
    t0 = time.perf_counter()
    if not Path(f"{root}.truth.json").exists():
        effect = [] if c["effect"] is None else ["--effect", f"{c['effect']}={c['magnitude']!r}"]
        _ok(railcal(["synth", "excitation", str(root), "--truth", "exudyn", "--seed", str(c["seed"]), "--format",
                     "parquet", "--quiet", *effect]), "synth", c)
    t1 = time.perf_counter()
    if not cal.exists():
        _ok(railcal(["calibrate", str(root), "--model", "box", "--method", "pso", "--factors", factors,
                     "--refine", "--particles", "300", "--iterations", "300", "--out", str(cal), "--quiet"]),
            "calibrate", c)
    t2 = time.perf_counter()
    if not diag.exists():
        _ok(railcal(["diagnose", str(root), "--calibration", str(cal), "--out", str(diag), "--quiet"]), "diagnose", c)
    t3 = time.perf_counter()
    truth = json.loads(Path(f"{root}.truth.json").read_text())
    d = json.loads(diag.read_text())
    ext = d["extension"]
    return {**c, "factors": factors, "cause": d["cause"], "confidence": d.get("confidence"),
            "verdict": verdict(c["case"], d["cause"], d.get("confidence")),
            "gain": None if d["gain"] is None else d["gain"]["reduction"],
            "found": None if ext is None else ext["parameters"], "hidden": truth["effect"],
            "hypotheses": {h["name"]: round(h["gain"], 4) for h in d["hypotheses"]},
            "detectability": d.get("detectability"),
            "calibration_max_error_pct": json.loads(cal.read_text())["max_error_pct"],
            "baseline_heldout_error": d["evidence"]["heldout_error_mean"],
            "synth_s": t1 - t0, "calibrate_s": t2 - t1, "diagnose_s": t3 - t2}


def _ok(code: int, step: str, c: dict) -> None:
    if code != 0:
        raise RuntimeError(f"seed {c['seed']}: railcal {step} exited {code}")


def _report(rows: list[dict]) -> None:
    answers = list(CATALOGUE) + ["none", "unexplained"]
    print("\nconfusion matrix (independent stationary truth; rows: hidden case, columns: diagnosed cause)")
    print(f"{'':>24}" + "".join(f"{a[:12]:>14}" for a in answers))
    for case, _, _ in CASES:
        sel = [r for r in rows if r["case"] == case]
        if sel:
            print(f"{case:>24}" + "".join(f"{sum(r['cause'] == a for r in sel):>14}" for a in answers))
    for case, _, _ in CASES:
        sel = [r for r in rows if r["case"] == case]
        if not sel:
            continue
        k = sum(r["verdict"] == "right" for r in sel)
        ci = binomtest(k, len(sel)).proportion_ci(method="wilson")
        wrong = [f"{r['seed']} {r['cause']} ({r['confidence']})" for r in sel if r["verdict"] == "wrong"]
        gains = [r["gain"] for r in sel if r["verdict"] == "right" and r["gain"] is not None]
        print(f"  {case}: right {k}/{len(sel)} (95 % interval {ci.low:.0%}-{ci.high:.0%}); wrong names: "
              f"{', '.join(wrong) or 'none'}" + (f"; held-out gain when right: min {min(gains):.0%}, median "
                                                 f"{np.median(gains):.0%}" if gains else ""))
        if case == "clean":  # a false alarm is a catalogue name; `unexplained` is a miss, not an alarm
            ci = binomtest(len(wrong), len(sel)).proportion_ci(method="wilson")
            print(f"  clean: false alarms {len(wrong)}/{len(sel)} (95 % interval {ci.low:.0%}-{ci.high:.0%})")
    for key in ("synth_s", "calibrate_s", "diagnose_s"):
        v = [r[key] for r in rows]
        print(f"{key}: median {np.median(v):.0f} s, max {max(v):.0f} s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10, help="campaigns per catalogue case and clean (default 10)")
    ap.add_argument("--few", type=int, default=3, help="campaigns per near-mimic (default 3)")
    ap.add_argument("--only", choices=[c for c, _, _ in CASES])
    ap.add_argument("--from-rep", type=int, default=0, help="repetitions j from this one on")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--keep", type=Path, help="keep campaigns, calibrations and diagnoses here (and reuse them)")
    ap.add_argument("--out", type=Path, help="write every campaign's result to this JSON file")
    ap.add_argument("--list", action="store_true", help="print the campaigns and stop")
    ap.add_argument("--factors", choices=("orthotropic", "windowed"), default="orthotropic",
                    help="the box factor set the campaigns are calibrated with (default orthotropic)")
    args = ap.parse_args()
    todo = campaigns(args.seeds, args.few, args.only, args.from_rep)
    if args.list:
        for c in todo:
            print(json.dumps(c))
        return 0
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        keep = args.keep or Path(tmp)
        keep.mkdir(parents=True, exist_ok=True)
        with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
            for r in pool.imap_unordered(functools.partial(_run, keep=keep, factors=args.factors), todo):
                rows.append(r)
                mag = "" if r["magnitude"] is None else f"={r['magnitude']:.4g}"
                print(f"seed {r['seed']} {r['case']}{mag} -> {r['cause']} ({r['confidence']}) [{r['verdict']}]; "
                      f"gain {r['gain']}; found {r['found']}; hypotheses {r['hypotheses']}; calibration "
                      f"{r['calibration_max_error_pct']:.3g} %, baseline {r['baseline_heldout_error']:.1f} x noise; "
                      f"{r['synth_s'] + r['calibrate_s'] + r['diagnose_s']:.0f} s", flush=True)
    rows.sort(key=lambda r: r["seed"])
    _report(rows)
    if args.out:
        args.out.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
