"""Identification and calibration of stationary excitation tests made by the independent
truth (issue 31): a shell finite element carbody the box model did not generate
(``synth excitation --truth exudyn``, docs/methods/truth-independent-stationary.md).

For each seed: a clean campaign (2 runs of 300 s), ``identify`` (FRF and EMA), each
identified mode against the truth's nearest pole, then the box model's particle swarm on
the identified modes (the command's defaults, the campaign's grouped factors).

Seeds: 6100 + k, k = 0, 1, 2, drawn once, never retired (never used before).

Expected before the first run (written with it): every identified mode within 0.5 % of a
truth pole (the truth's own integration shifts a 23 Hz pole by about 0.2 %), none without a
pole within 1 %; the box model does not reach the shell car: its best fit more than 3 % off
and several factors on their bounds, as on development seed 5 (6.3 %, 11 of 12 on bounds).

``--factors credible``: the swarm over the credible set instead (18 factors in ranges stated
before any fit; 300 particles x 300 iterations in 4 swarms, in the factors' logarithms, each
refined and polished as ``railcal calibrate --factors credible --refine`` does). Expected
before its first run on these seeds: within 2.5 % on each (development seed 5: 2.38 %, every
mode's error near that bound, the signature of a minimax fit the model form limits), short of
the seed's 0.86 % on its real car: the shell's side walls have windows between x = -7 and 7 m
only, and a uniform side plate cannot be soft there and stiff beyond.

``--factors windowed``: the credible set and the side walls' in-plane shear over their end
strips beyond the windowed middle (the campaign's [vehicle] windowed_length, 14 m), the same
swarm. Expected before its first run on these seeds (written after development seed 5 gave
0.14 % with a zone of 5.25 m, and seed 6100's credible fit 2.80 %, six factors on bounds):
within 0.5 % on each seed, every MAC at least 0.95.

    OPENBLAS_NUM_THREADS=1 python scripts/check_excitation_independent.py [--seeds 3] [--keep DIR]
        [--factors grouped|credible|windowed|orthotropic]
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from calibration.calibrate_box import RefineSettings, SwarmSettings, calibrate_box_campaign, campaign_factor_set
from calibration.data.campaign import open_campaign
from calibration.identification.excitation import identify_excitation
from calibration.optimisers.pso import PSOSettings
from calibration.swarm_defaults import CAMPAIGN_DONE_PCT, CAMPAIGN_SWARMS, TYPED_POLISH_STEPS
from calibration.truth.independent.stationary import synth_excitation_independent

FIRST_SEED = 6100
WITHIN_PCT, STRAY_PCT = 0.5, 1.0


def _calibrate(campaign, ident, fs):
    if fs.name == "grouped":  # the command's defaults
        return calibrate_box_campaign(campaign, identified=ident)[0]
    swarm = SwarmSettings(pso=PSOSettings(particles=300, iterations=300), swarms=CAMPAIGN_SWARMS,
                          done_pct=CAMPAIGN_DONE_PCT, log_factors=True)
    return calibrate_box_campaign(campaign, identified=ident, factors=fs, swarm=swarm,
                                  refinement=RefineSettings(polish_steps=TYPED_POLISH_STEPS))[0]


def check(seed: int, workdir: Path, factors: str) -> dict:
    out = workdir / f"shaker_{seed}"
    t0 = time.perf_counter()
    kept = Path(f"{out}.truth.json")
    truth = json.loads(kept.read_text()) if kept.exists() else synth_excitation_independent(out, seed=seed,
                                                                                            fmt="parquet")
    t1 = time.perf_counter()
    campaign = open_campaign(out)
    ident = identify_excitation(campaign)
    t2 = time.perf_counter()
    poles = truth["frequencies_hz"]
    modes = []
    for m in ident.modes:
        label, f_true = min(poles.items(), key=lambda kv: abs(kv[1] - m.frequency_hz))
        err = 100 * (m.frequency_hz / f_true - 1)
        modes.append({"identified_hz": round(m.frequency_hz, 4), "pole": label, "truth_hz": round(f_true, 4),
                      "error_pct": round(err, 3),
                      "verdict": "within" if abs(err) <= WITHIN_PCT else ("off" if abs(err) <= STRAY_PCT else
                                                                           "STRAY")})
    fs = campaign_factor_set(factors, campaign)
    cal = _calibrate(campaign, ident, fs)
    t3 = time.perf_counter()
    ranges = dict(zip(fs.names, fs.ranges))
    bounds = [n for n, v in cal.parameters.items() if min(abs(v / ranges[n][0] - 1), abs(v / ranges[n][1] - 1)) < 1e-4]
    return {"seed": seed, "factor_set": factors, "modes": modes,
            "calibration_max_error_pct": float(f"{cal.max_error_pct:.3g}"),  # a fit within 1e-6 % shows as one
            "factors_on_bounds": bounds, "factors": {k: round(v, 3) for k, v in cal.parameters.items()},
            "synth_s": round(t1 - t0, 1), "identify_s": round(t2 - t1, 1), "calibrate_s": round(t3 - t2, 1),
            "real_time_factor": round(truth["performance"]["real_time_factor"], 1)}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--keep", type=Path, help="keep the campaigns in this folder (and reuse those there)")
    ap.add_argument("--factors", choices=("grouped", "credible", "windowed", "orthotropic"), default="grouped")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp) if args.keep is None else args.keep
        workdir.mkdir(parents=True, exist_ok=True)
        for k in range(args.seeds):
            row = check(FIRST_SEED + k, workdir, args.factors)
            rows.append(row)
            print(json.dumps(row), flush=True)
    modes = [m for r in rows for m in r["modes"]]
    worst = max((abs(m["error_pct"]) for m in modes), default=float("nan"))
    print(f"identified {len(modes)} modes over {len(rows)} campaigns: {sum(m['verdict'] == 'within' for m in modes)} "
          f"within {WITHIN_PCT} % of a truth pole, {sum(m['verdict'] == 'STRAY' for m in modes)} without one within "
          f"{STRAY_PCT} %; worst {worst:.2f} %")
    print(f"box model's best fit over the {args.factors} factors (max error over the identified modes): "
          + ", ".join(f"seed {r['seed']} {r['calibration_max_error_pct']:.3g} % ({len(r['factors_on_bounds'])} of "
                      f"{len(r['factors'])} factors on bounds)" for r in rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
