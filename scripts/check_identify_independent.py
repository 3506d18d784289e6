"""Identification on the independent exudyn truth (issue 31, item 5): for every vehicle of its
library, a campaign simulated at its source's damping (the seed's Table 6 for the intercity
car), identified by railcal, each rigid-body mode compared with the truth's linearised one.

Targets: carbody modes within 3 %, bogie modes within 2 %; a mode railcal cannot identify
must be reported undetermined with its reason, never as a wrong number (an undetermined mode
counts as honest, a number outside the target as wrong).

Expected before the first run: the bogie pitch of every vehicle within 2 % (lightly damped,
seen by the gyro); the bogie bounce of the intercity car (damping ratio about 0.38 at Table
6's 29.4 kN s/m) undetermined or outside 2 %; the carbody modes, with bogie sensors only and
a flexible carbody, within 3 % or undetermined.

Seeds: vehicle k of the library (in its order) uses seed 9100 + k, drawn once, never retired.
The rule that a carbody mode whose partner the fit did not resolve is undetermined
(``unpaired_carbody``) was found on these seeds; its evidence is a second series, 9300 + k,
drawn once after it (``--first-seed 9300``), expected before its first run: no carbody mode
given as a number when its partner was not resolved, and the other wrong numbers of the first
series (carbody pitch +3.3 %, Manchester; bogie bounce +7.5 % and +10.8 %, Eurostar power car
and Pioneer R), biases this rule does not address, may recur.

Second series, measured: 10 within, 6 undetermined, 4 wrong. The pair rule held three
carbody poles back (two would have been 16-18 % off, one was within 2.3 %); the wrong numbers
were Manchester's carbody bounce +4.3 % and pitch +6.0 %, and the bogie bounce of Pioneer R
(+28.5 %, a pole damped 0.027 for a mode damped 0.9) and of the Eurostar power car (+33.8 %,
jackknife standard error 8.7 %). A pole damped outside what the priors allow (by a factor
2, ``prior_range.damping_outside``) is now refused too. Its evidence is a third series,
9500 + k, expected before its first run: no bogie mode given from a pole damped ten times
less than its priors allow; Manchester's carbody bias and the heavily damped Eurostar bogie
bounce, which no rule here addresses, may recur as wrong numbers.

Third series, measured: 12 within, 5 undetermined, 3 wrong, all a heavily damped bogie bounce
(+2.05 % intercity, +34.5 % Pioneer R, +7.4 % Eurostar power car). A fourth series, 9700 + k, ran
with a rule that refused a mode whose 95 % jackknife interval was wider than 3 % / 2 %; the rule
was reverted (a delete-one-journey jackknife over three journeys refused modes identified
right), so that series is read without it.

The heavily damped bogie bounces' bias was then traced on the fourth series (intercity +5.0 %,
Eurostar power car +6.0 %) by ablating the truth: not its bi-linear dampers, reservoirs,
equipment mounts or axle-box noise, but the sensors' gain errors (a gain-free intercity
campaign read +1.5 %), which mix the bogie's pitch into its centre acceleration, and a fit
with too few poles when a carbody bending shares the band (+9.7 % on the Eurostar's exact
linearised FRF with two poles, +2.5 % with three). The bounce FRF now takes the rail pitch
as a second input, each bogie mode is fitted over its prior frequency /x 2.5 at the lowest
order its pole is stable at, and a pole damped above 1/sqrt(2) is refused (no resonance
peak). Fourth series re-read with these: bogie modes within 2 % but the Eurostar bounce
(+2.09 %), Pioneer R's undetermined. Its evidence is a fifth series, 9900 + k, expected
before its first run: every bogie bounce within 2 % or undetermined, the Eurostar power
car's possibly just over (the wheelset-clamped system's poles, which axle-box inputs
observe, lie 1.3-3.1 % above its flexible-track frequency); Pioneer R's bogie modes
undetermined; bogie pitch within 2 %; the carbody modes as before (this change does not
touch them), Manchester's carbody bias possibly recurring.

Fifth series, measured: 11 within, 6 undetermined, 3 wrong: the Eurostar power car's bogie
bounce +2.48 % (+9.30 % with the previous code on the same campaign) and Pioneer M's carbody
bounce +4.06 % and pitch +3.35 % (the same with the previous code). Every other bogie mode
within 2 % (largest +1.06 %), Pioneer R's undetermined.

Sixth series, 10100 + k (the rule that a mode whose delete-one-journey standard error exceeds
3 % carbody / 2 % bogie is undetermined, found on the fifth: Pioneer M's carbody pitch, +3.35 %
with a standard error of 16 %; the error against the truth's own pole reported beside the
error against its undamped frequency). Expected before its first run: 10-12 within, 5-8
undetermined, 1-3 wrong; Pioneer M's carbody bounce may again be 3-4 % high with a small
standard error (a bias no spread shows: with its segments drawn by four other seeds it read
+2.2 to +4.1 %, with 800 segments +2.7 to +3.6 %); the Eurostar power car's bogie bounce may be
just over 2 % against its undamped frequency and within against its pole; the intercity car's
carbody modes undetermined where its journeys' speeds are too alike; no right mode refused
by the new rule (on the fifth series the largest standard error of a mode within was 2.2 %,
Manchester's carbody bounce). The fifth series re-read with the rule (before the sixth's run):
11 within, 8 undetermined, 1 wrong: Pioneer M's carbody pitch refused for its spread and its
bounce with it (the pair rule); the Eurostar's bogie bounce +2.48 % (+2.08 % against its pole).

Sixth series, measured (code 6ec3103): 9 within, 8 undetermined, 3 wrong (forecast missed on
the within count). Wrong: the intercity car's bogie bounce +2.03 % (standard error 1.06 %,
damping ratio 0.44; +2.54 % against its pole), Manchester's carbody pitch +3.88 % (+2.70 %
against its pole, within) and the Eurostar's bogie bounce +2.21 % (+1.28 % against its pole,
within). The spread rule refused two: Pioneer M's carbody bounce (a pole at 0.921 Hz for a
0.629 Hz mode, standard error 214 %: rightly) and Pioneer R's carbody pitch (0.654 Hz, +1.2 %
off, standard error 3.0 %: a right mode refused). Against the truth's own poles the carbody
errors shrink (the Eurostar's pitch +1.18 % -> +0.13 %): a fitted pole is |lambda|, and the
car calibration still matches it to the model's undamped frequency.

Against the seed's 2D model's modes of the truth car (``rigid_frequencies_hz``: stiff carbody,
wheelsets on a rigid rail; the system an axle-box input observes, since the wheelsets are its
input, and the one the car calibration's model represents), the check prints a third error.
Read after the sixth series: every bogie mode of both series within 2 % (largest +1.08 %, the
intercity car's bounce, which is +2.03 % against the truth on its flexible track); the one
wrong number left of the two series is Manchester's carbody pitch on the sixth (+3.73 %).

    python scripts/check_identify_independent.py [--journeys 6] [--length-km 10] [--vehicles NAME ...]
        [--first-seed 9100] [--keep DIR]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from calibration.data.campaign import open_campaign
from calibration.identification.in_service import RIGID_LABELS, identify_in_service
from calibration.truth.independent import VEHICLES, IndependentSettings, synth_in_service_independent
from calibration.truth.independent.irregularity import LineSpec

LIMITS = {"carbody_bounce": 3.0, "carbody_pitch": 3.0, "bogie_bounce": 2.0, "bogie_pitch": 2.0}
FIRST_SEED = 9100


def check(k: int, name: str, journeys: int, length_km: float, workdir: Path, first_seed: int = FIRST_SEED) -> dict:
    out = workdir / f"{name}_{first_seed + k}"
    settings = IndependentSettings(journeys=journeys, line=LineSpec(length=length_km * 1000.0))
    t0 = time.perf_counter()
    kept = Path(f"{out}.truth.json")
    if kept.exists():  # a campaign kept by an earlier run (--keep)
        truth = json.loads(kept.read_text())
    else:
        truth = synth_in_service_independent(out, seed=first_seed + k, settings=settings, vehicle=name, fmt="parquet")
    t1 = time.perf_counter()
    result = identify_in_service(open_campaign(out))
    row = {"vehicle": name, "seed": first_seed + k, "synth_s": round(t1 - t0, 1),
           "identify_s": round(time.perf_counter() - t1, 1), "modes": {}}
    undetermined = {u.label: u.reason for u in result.undetermined} if result.undetermined else {}
    for lbl in RIGID_LABELS:
        f_true = truth["frequencies_hz"].get(lbl)
        zeta = truth.get("damping_ratios", {}).get(lbl)
        f_damped = truth.get("damped_frequencies_hz", {}).get(lbl)
        # the truth's own pole |lambda| / 2 pi, what a fitted pole estimates: with damping that
        # is not proportional to stiffness it lies up to 1.3 % from the undamped frequency
        f_pole = None if f_damped is None or zeta is None else f_damped / (1 - zeta ** 2) ** 0.5
        # the seed's 2D model's mode of the truth car (stiff carbody, wheelsets on a rigid rail):
        # the system an axle-box-input FRF observes and the car calibration's model represents
        f_rigid = truth.get("rigid_frequencies_hz", {}).get(lbl)
        entry = {"truth_hz": None if f_true is None else round(f_true, 4),
                 "truth_damping_ratio": None if zeta is None else round(zeta, 3),
                 "truth_pole_hz": None if f_pole is None else round(f_pole, 4),
                 "truth_rigid_track_hz": None if f_rigid is None else round(f_rigid, 4)}
        try:
            m = result.mode(lbl)
        except KeyError:
            entry.update(verdict="undetermined", reason=undetermined.get(lbl, "not reported"))
        else:
            err = 100 * (m.frequency_hz / f_true - 1)
            pole_err = None if f_pole is None else round(100 * (m.frequency_hz / f_pole - 1), 2)
            rigid_err = None if f_rigid is None else round(100 * (m.frequency_hz / f_rigid - 1), 2)
            entry.update(identified_hz=round(m.frequency_hz, 4), error_pct=round(err, 2), error_vs_pole_pct=pole_err,
                         within_vs_pole=None if pole_err is None else abs(pole_err) <= LIMITS[lbl],
                         error_vs_rigid_track_pct=rigid_err,
                         within_vs_rigid_track=None if rigid_err is None else abs(rigid_err) <= LIMITS[lbl],
                         std_pct=None if m.frequency_std_hz is None else round(100 * m.frequency_std_hz
                                                                               / m.frequency_hz, 2),
                         method=m.method, damping_ratio=None if m.damping_ratio is None else round(m.damping_ratio, 3),
                         verdict="within" if abs(err) <= LIMITS[lbl] else "WRONG")
        row["modes"][lbl] = entry
    return row


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--journeys", type=int, default=6)
    ap.add_argument("--length-km", type=float, default=10.0)
    ap.add_argument("--vehicles", nargs="+", default=list(VEHICLES))
    ap.add_argument("--first-seed", type=int, default=FIRST_SEED,
                    help="the series: 9100, 9300, 9500, 9700, 9900 or 10100")
    ap.add_argument("--keep", type=Path, help="keep the campaigns in this folder, and read those already there "
                    "instead of simulating them again")
    args = ap.parse_args()
    counts = {"within": 0, "undetermined": 0, "WRONG": 0}
    # the same tally against the truth's pole and against the seed model's mode on a rigid rail
    other = {ref: {"within": 0, "undetermined": 0, "WRONG": 0, "no reference": 0} for ref in ("pole", "rigid_track")}
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp) if args.keep is None else args.keep
        workdir.mkdir(parents=True, exist_ok=True)
        for k, name in enumerate(VEHICLES):
            if name not in args.vehicles:
                continue
            row = check(k, name, args.journeys, args.length_km, workdir, args.first_seed)
            for e in row["modes"].values():
                counts[e["verdict"]] += 1
                for ref, tally in other.items():
                    ok = e.get(f"within_vs_{ref}")
                    tally["undetermined" if e["verdict"] == "undetermined" else
                          "no reference" if ok is None else "within" if ok else "WRONG"] += 1
            print(json.dumps(row), flush=True)
    print(f"{counts['within']} modes within {LIMITS} %, {counts['undetermined']} reported undetermined, "
          f"{counts['WRONG']} wrong numbers")
    for ref, words in (("pole", "the truth's own poles"), ("rigid_track", "the seed model's modes on a rigid rail")):
        t = other[ref]
        print(f"against {words}: {t['within']} within, {t['undetermined']} undetermined, {t['WRONG']} wrong"
              + (f", {t['no reference']} without one (an overdamped mode)" if t["no reference"] else ""))
    return 0 if counts["WRONG"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
