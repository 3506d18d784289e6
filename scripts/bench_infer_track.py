"""Benchmark: `railcal infer-track` on the independent exudyn truth, against the true line,
the campaign's own track recording and the seed's Cross-Entropy baseline; a settled dip
between two campaigns of the same line.

    OPENBLAS_NUM_THREADS=1 python scripts/bench_infer_track.py [--cases 3] [--jobs 2] [--keep DIR] [--no-ce]

Cases, seeds drawn once by this rule, never retired: case j = 0 .. cases - 1 is a line of
seed 33200 + j, 10 km long, the intercity car (the library's; its damping drawn around
the seed's Table 6), 3 journeys each, bogie sensors and axle boxes:

* "before": campaign seed 33100 + j, calibrated with `railcal calibrate` (its defaults);
* "after": campaign seed 33300 + j over the same line with a dip settled in it, 5 mm deep
  and 10 m long, centred at 1500 + 7000 u m, u ~ U(0, 1) from generator seed 33400 + j.

Each campaign's profile is inferred with bogie sensors only and with the axle boxes too,
with the "before" calibration (the car is the same); "after" is compared with "before".
Figures: D1 and D2 correlation and RMSE against the true line filtered alike, at the
position the profile gives (GPS-anchored, passes averaged) and after the best shift
within +-5 m (printed); the same against the campaign's track recording (its noise:
0.05 mm rms); the dip found (the change nearest the true centre, within 10 m), its place
and depth error, and any other change reported; wall time per 10 km of line. The seed's
baseline (:mod:`calibration.track_inference.cross_entropy`, bogie sensors, its default
settings) runs on the first ``--ce-length`` metres of journey 1 after 200 m, and the
Kalman estimate of the same pass (its default settings, not fitted) and the classic
inertial method (:mod:`calibration.track_inference.inertial`, axle boxes) are scored on
the same stretch.

``--wall`` times one whole 10 km pass of a kept case, the Kalman filter then CE. Measured
(71e2e85, case 0, journey 1 at 24.7 m/s, beside the test suite): the Kalman filter 13.7 s
(6.5 s of it the noise search), D1 correlation 0.991, RMSE 0.123 mm; CE 182.9 s, 0.803,
0.555 mm.

``--own-truth`` runs the cases on railcal's own truth instead (seed 33500 + j, same
length and journeys; no dip): the filter's own car made that data, so it checks the code.

Forecast, written before the first run (2026-11-29, from two development campaigns,
seeds 33000 and line 77, which are not bench seeds): bogie sensors only, D1 correlation
>= 0.98 and RMSE <= 0.15 mm after the shift on every case, >= 0.95 at the profile's own
position on most; D2 correlation >= 0.95; axle boxes about the same (their noise is 5x
the bogie's and they carry the track's own dynamics); the dip found on 3 of 3, within
2 m, its depth within 20 %, at most one other change reported per case; the Kalman filter
10-30 s per 10 km of line and pass; CE correlation 0.7-0.9 and RMSE 0.3-0.6 mm, 10-100x
slower per km.

Measured on the reviewed code (71e2e85: passes named apart, the position scaled to GPS only
where the scale stands out of its wander, each sample low-passed at its own speed, the
axle boxes' double integral under 8 m), two cases at a time beside other jobs. Bogie
sensors only, D1 at the profile's own position: correlation 0.9958 / 0.9971 / 0.9962 and
RMSE 0.086 / 0.075 / 0.083 mm (true D1 rms 0.91-0.93 mm); after the best shift (-0.13 to
+0.09 m) 0.9988 / 0.9974 / 0.9974 and 0.046 / 0.071 / 0.070 mm. D2: 0.9941 / 0.9950 /
0.9939, RMSE 0.172 / 0.157 / 0.178 mm (true rms 1.55-1.58 mm). Against the campaign's
recording: 0.9907 / 0.9962 / 0.9920. With the axle boxes: D1 0.9962 / 0.9950 / 0.9963,
RMSE 0.082 / 0.093 / 0.081 mm (better on two cases, worse on case 1, whose D2 is worse
too: 0.267 mm). The dip: found on 3 of 3 with both sensor sets, 0.11-0.37 m from its
centre, its depth 0.8-8.2 % short, its length 10 m; other changes reported: bogie 0 / 0 /
1, axle boxes 0 / 0 / 2, each 0.44-0.66 mm at a score of 6.0-7.7 (the threshold is 6): the
forecast's "at most one" missed once. Wall time 29-35 s per 10 km of line with 3 passes
(the noise search, filter and draws), 30-61 s with the axle boxes. CE on 1 km of journey
1: correlation 0.892 / 0.891 / 0.916, RMSE 0.452 / 0.414 / 0.364 mm, 16-39 s per km; the
Kalman filter on the same stretch of the same pass (default settings): 0.988 / 0.977 /
0.993 (0.995 after the shift on case 1), 0.6-1.3 s per km; the inertial method 0.997 /
0.982 / 0.998, after the shift 0.9987-0.9994. The forecast held but for the other changes.

Earlier runs on the same seeds: on 25708a4 the detector took the 10 m dip as a 4-8 m one
with its side lobes as 1-4 further changes per case (mended in 453b02a: the shape is the
one that explains most of the difference); on e66d49c, before the review's mends, D1 at
position 0.9976 / 0.9959 / 0.9967; on 2d4a3e5 the speed was scaled to every GPS fit and
D1 at position fell to 0.955-0.985 with 18-49 false changes (mended in 2882af4).

``--own-truth`` (code 71e2e85; no forecast was written for it): D1 at the profile's own
position 0.9859 / 0.9173 / 0.9880, RMSE 0.160 / 0.374 / 0.144 mm; after the best shift
(-0.14 / -0.69 / +0.19 m) 0.9889 / 0.9908 / 0.9938, 0.141 / 0.125 / 0.104 mm; D2 0.974 /
0.959 / 0.981, RMSE 0.308-0.441 mm; with the axle boxes D1 0.9907 / 0.9197 / 0.9892.
Case 1's passes sit 0.69 m off on average (the mean GPS error of its three journeys,
about twice what the same GPS model's 30 s wander leaves on average; the exudyn cases sat
within 0.13 m), which at position takes it past 0.3 mm; after the shift the error is
still about twice the exudyn truth's, not yet explained. (On 393ef3d, before the review's
mends: 0.9879 / 0.9260 / 0.9941.)
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

from calibration.data.campaign import open_campaign
from calibration.data.tracks import read_track_file
from calibration.models.parameters import CarParameters
from calibration.models.car2d import wheelset_positions
from calibration.track_inference.inertial import inertial_level
from calibration.track_inference.kalman import KalmanSettings, infer_pass
from calibration.track_inference.passes import read_passes
from calibration.track_inference.profile import band_filter, best_offset
from calibration.truth.independent import truth_line
from railcal.cli import main as railcal

LENGTH_KM, JOURNEYS, DIP_MM, DIP_M = 10.0, 3, 5.0, 10.0
STEP = 0.25


def _case_seeds(j: int) -> dict:
    u = float(np.random.default_rng(33400 + j).uniform())
    return {"line": 33200 + j, "before": 33100 + j, "after": 33300 + j, "dip_centre": 1500.0 + 7000.0 * u}


def _score(d: np.ndarray, est: np.ndarray, ref: np.ndarray) -> dict:
    ok = np.isfinite(est) & np.isfinite(ref)
    d, est, ref = d[ok], est[ok], ref[ok]
    off, _ = best_offset(d, ref, d, est, STEP, 5.0)
    shifted = np.interp(d - off, d, est)  # est's sample at x belongs at x + off
    inner = slice(int(10 / STEP), d.size - int(10 / STEP))

    def stats(x):
        return {"corr": float(np.corrcoef(x[inner], ref[inner])[0, 1]),
                "rmse_mm": 1e3 * float(np.sqrt(np.mean((x[inner] - ref[inner]) ** 2)))}

    return {"at_position": stats(est), "shifted": {**stats(shifted), "shift_m": off},
            "true_rms_mm": 1e3 * float(np.std(ref[inner]))}


def _read_profile(path: Path) -> tuple[np.ndarray, np.ndarray]:
    rec = read_track_file(path)
    return rec.distance, rec.level


def _against_truth(csv: Path, line, band: str) -> dict | None:
    if not csv.exists():
        return None
    d, z = _read_profile(csv)
    fine = np.arange(line.s[0], line.s[-1], STEP)
    truth = np.interp(d, fine, band_filter(line.level(fine), band, STEP))
    return _score(d, z, truth)


def _against_recording(csv: Path, campaign: Path) -> dict:
    d, z = _read_profile(csv)
    rec = [t for t in open_campaign(campaign).tracks() if t.band == "D1"][0]
    inside = (d >= rec.distance[0]) & (d <= rec.distance[-1])
    return _score(d[inside], z[inside], np.interp(d[inside], rec.distance, rec.level))


def _run(args_list) -> float:
    t0 = time.perf_counter()
    rc = railcal(args_list)
    if rc != 0:
        raise RuntimeError(f"railcal {' '.join(args_list)} exited {rc}")
    return time.perf_counter() - t0


def _ce(root: Path, calibration: Path, line, length: float) -> dict:
    from calibration.track_inference.cross_entropy import CESettings, infer_pass_ce

    p = CarParameters.from_mapping(json.loads(calibration.read_text())["parameters"])
    ps = read_passes(open_campaign(root), step=STEP)[0]
    keep = (ps.s >= ps.s[0] + 200.0) & (ps.s <= ps.s[0] + 200.0 + length)
    sub = type(ps)(ps.run_id, ps.s[keep], ps.t[keep], ps.v[keep], ps.a[keep],
                   tuple(type(c)(c.name, c.kind, c.values[keep], c.x, c.wheelset) for c in ps.channels))
    out = {}
    ax = read_passes(open_campaign(root), step=STEP, axle_boxes=True)[0]
    t0 = time.perf_counter()
    d_in, z_in = inertial_level(ax, wheelset_positions(p))
    out["inertial_wall_s_per_km"] = (time.perf_counter() - t0) / ((ax.s[-1] - ax.s[0]) / 1000.0)
    t0 = time.perf_counter()
    ce = infer_pass_ce(sub, p, CESettings())
    out["ce_wall_s_per_km"] = (time.perf_counter() - t0) / (length / 1000.0)
    t0 = time.perf_counter()
    kf = infer_pass(ps, p, KalmanSettings(), draws=0)
    out["kalman_wall_s_per_km"] = (time.perf_counter() - t0) / ((ps.s[-1] - ps.s[0]) / 1000.0)
    fine = np.arange(line.s[0], line.s[-1], STEP)
    lo, hi = ce.distance[0] + 100.0, ce.distance[-1] - 100.0
    for name, (dist, band) in (("ce", (ce.distance, band_filter(ce.level, "D1", STEP))),
                               ("kalman", (kf.distance, band_filter(kf.level, "D1", STEP))),
                               ("inertial", (d_in, z_in))):
        inside = (dist >= lo) & (dist <= hi)
        truth = np.interp(dist[inside], fine, band_filter(line.level(fine), "D1", STEP))
        out[name] = _score(dist[inside], band[inside], truth)
    return out


def case(j: int, keep: Path, ce: bool, ce_length: float, ce_only: bool = False) -> dict:
    seeds = _case_seeds(j)
    keep.mkdir(parents=True, exist_ok=True)
    before, after, cal = keep / "before", keep / "after", keep / "calibration.json"
    common = ["--truth", "exudyn", "--journeys", str(JOURNEYS), "--length-km", str(LENGTH_KM),
              "--line-seed", str(seeds["line"]), "--quiet"]
    if not before.exists():
        _run(["synth", "in-service", str(before), "--seed", str(seeds["before"]), *common])
    if not after.exists():
        dip = f"{seeds['dip_centre']:.3f}:{DIP_MM:g}:{DIP_M:g}"
        _run(["synth", "in-service", str(after), "--seed", str(seeds["after"]), "--dip", dip, *common])
    if not cal.exists():
        _run(["calibrate", str(before), "--out", str(cal), "--quiet"])
    line = truth_line(json.loads(Path(f"{before}.truth.json").read_text()))
    out = {"case": j, "seeds": seeds, "sets": {}}
    for tag, extra in () if ce_only else (("bogie", []), ("axle_boxes", ["--axle-boxes"])):
        res = {}
        b_csv, a_csv = keep / f"before_{tag}.csv", keep / f"after_{tag}.csv"
        for path in keep.glob(f"*_{tag}*"):
            path.unlink()
        res["wall_s_before"] = _run(["infer-track", str(before), "--calibration", str(cal), "--out", str(b_csv),
                                     "--quiet", *extra])
        _run(["infer-track", str(after), "--calibration", str(cal), "--out", str(a_csv), "--compare", str(b_csv),
              "--quiet", *extra])
        res["D1"] = _against_truth(b_csv, line, "D1")
        res["D2"] = _against_truth(keep / f"before_{tag}_d2.csv", line, "D2")
        res["recording"] = _against_recording(b_csv, before)
        summary = json.loads(b_csv.with_suffix(".json").read_text())
        res["std_median_mm"] = summary["bands"]["D1"]["std_median_mm"]
        changes = json.loads(a_csv.with_suffix(".json").read_text())["changes"]
        near = [c for c in changes if abs(c["centre_m"] - seeds["dip_centre"]) <= 10.0 and c["depth_mm"] > 0]
        dip = min(near, key=lambda c: abs(c["centre_m"] - seeds["dip_centre"])) if near else None
        res["dip"] = None if dip is None else {**dip, "place_error_m": dip["centre_m"] - seeds["dip_centre"],
                                               "depth_error_pct": 100 * (dip["depth_mm"] / DIP_MM - 1)}
        res["other_changes"] = [c for c in changes if c is not dip]
        out["sets"][tag] = res
    if ce:
        out["ce"] = _ce(before, cal, line, ce_length)
    return out


def wall_10km(root: Path) -> None:
    """One whole pass (journey 1 of case ``root``, 10 km) by the Kalman filter (its search for
    the noise, then filter and draws) and by CE, one after the other in this process."""
    from calibration.track_inference.cross_entropy import CESettings, infer_pass_ce
    from calibration.track_inference.kalman import fit_noise

    p = CarParameters.from_mapping(json.loads((root / "calibration.json").read_text())["parameters"])
    line = truth_line(json.loads((root / "before.truth.json").read_text()))
    ps = read_passes(open_campaign(root / "before"), step=STEP)[0]
    fine = np.arange(line.s[0], line.s[-1], STEP)
    truth = band_filter(line.level(fine), "D1", STEP)

    def score(pr):
        inner = slice(int(100 / STEP), pr.level.size - int(100 / STEP))
        z = band_filter(pr.level, "D1", STEP)[inner]
        ref = np.interp(pr.distance[inner], fine, truth)
        return f"corr {np.corrcoef(z, ref)[0, 1]:.4f} RMSE {1e3 * np.sqrt(np.mean((z - ref) ** 2)):.3f} mm"

    t0 = time.perf_counter()
    settings, _ = fit_noise(ps, p, KalmanSettings())
    t1 = time.perf_counter()
    kf = infer_pass(ps, p, settings)
    t2 = time.perf_counter()
    print(f"{ps.run_id}, {(ps.s[-1] - ps.s[0]) / 1e3:.2f} km at {ps.v.mean():.1f} m/s: Kalman {t2 - t0:.1f} s "
          f"(search {t1 - t0:.1f} s), {score(kf)}", flush=True)
    t0 = time.perf_counter()
    ce = infer_pass_ce(ps, p, CESettings())
    print(f"  CE {time.perf_counter() - t0:.1f} s, {score(ce)}", flush=True)


def own_case(j: int, keep: Path) -> dict:
    """Case j on railcal's own truth (seed 33500 + j, the same length and journeys; its car is
    the filter's own 2D car, so this checks the code, not the method)."""
    from calibration.truth.in_service import InServiceSettings, draw_truth_parameters, synth_in_service
    from calibration.truth.track import Line, LineSpec

    seed = 33500 + j
    settings = InServiceSettings(journeys=JOURNEYS, line=LineSpec(length=LENGTH_KM * 1000.0))
    keep.mkdir(parents=True, exist_ok=True)
    camp, cal = keep / "own", keep / "own_calibration.json"
    if not camp.exists():
        synth_in_service(camp, seed=seed, settings=settings)
    if not cal.exists():
        _run(["calibrate", str(camp), "--out", str(cal), "--quiet"])
    rng = np.random.default_rng(seed)  # the truth's line is drawn right after its car
    draw_truth_parameters(settings, rng)
    line = Line(settings.line, rng)
    fine = np.arange(0.0, settings.line.length, STEP)
    level = line.level(fine)[0]
    out = {"case": j, "seed": seed, "sets": {}}
    for tag, extra in (("bogie", []), ("axle_boxes", ["--axle-boxes"])):
        csv = keep / f"own_{tag}.csv"
        for path in keep.glob(f"own_{tag}*"):
            path.unlink()
        _run(["infer-track", str(camp), "--calibration", str(cal), "--out", str(csv), "--quiet", *extra])
        res = {}
        for band, path in (("D1", csv), ("D2", keep / f"own_{tag}_d2.csv")):
            if path.exists():
                d, z = _read_profile(path)
                res[band] = _score(d, z, np.interp(d, fine, band_filter(level, band, STEP)))
        out["sets"][tag] = res
    return out


def _print(r: dict) -> None:
    print(f"case {r['case']} (line {r['seeds']['line']}, dip at {r['seeds']['dip_centre']:.1f} m)")
    for tag, s in r["sets"].items():
        for band in ("D1", "D2"):
            x = s[band]
            if x is None:
                print(f"  {tag:10s} {band}: not written")
                continue
            print(f"  {tag:10s} {band}: at position corr {x['at_position']['corr']:.4f} RMSE "
                  f"{x['at_position']['rmse_mm']:.3f} mm; shifted {x['shifted']['shift_m']:+.2f} m corr "
                  f"{x['shifted']['corr']:.4f} RMSE {x['shifted']['rmse_mm']:.3f} mm "
                  f"(true rms {x['true_rms_mm']:.3f})")
        rec = s["recording"]
        print(f"  {tag:10s} recording: corr {rec['at_position']['corr']:.4f} RMSE "
              f"{rec['at_position']['rmse_mm']:.3f} mm"
              f"; shifted corr {rec['shifted']['corr']:.4f}; std median {s['std_median_mm']:.3f} mm; "
              f"{s['wall_s_before'] * 10 / LENGTH_KM:.1f} s per 10 km ({JOURNEYS} passes)")
        d = s["dip"]
        found = "not found" if d is None else (f"{d['depth_mm']:.2f} mm over {d['length_m']:g} m, place "
                                               f"{d['place_error_m']:+.2f} m, depth {d['depth_error_pct']:+.1f} %, "
                                               f"score {d['score']:.1f}")
        others = "".join(f" [{c['centre_m']:.0f} m {c['depth_mm']:+.2f} mm {c['score']:.1f}]"
                         for c in s["other_changes"])
        print(f"  {tag:10s} dip: {found}; other changes {len(s['other_changes'])}{others}")
    if "ce" in r:
        c = r["ce"]
        for name in ("ce", "kalman", "inertial"):
            x = c[name]
            print(f"  {name:10s} D1 on the CE stretch: corr {x['at_position']['corr']:.4f} RMSE "
                  f"{x['at_position']['rmse_mm']:.3f} mm; shifted corr {x['shifted']['corr']:.4f} RMSE "
                  f"{x['shifted']['rmse_mm']:.3f} mm; {c[name + '_wall_s_per_km']:.1f} s per km")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=3)
    ap.add_argument("--from-case", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--keep", default=None, help="folder to keep the campaigns and results in (reused when present)")
    ap.add_argument("--no-ce", action="store_true", help="leave out the Cross-Entropy baseline")
    ap.add_argument("--ce-length", type=float, default=1000.0, help="[m] of journey 1 the CE baseline infers")
    ap.add_argument("--ce-only", action="store_true", help="the CE baseline alone (on kept campaigns)")
    ap.add_argument("--own-truth", action="store_true", help="the cases on railcal's own truth instead")
    ap.add_argument("--wall", action="store_true", help="time one whole 10 km pass of case --from-case (kept in "
                    "--keep), the Kalman filter against CE")
    args = ap.parse_args()
    if args.wall:
        wall_10km(Path(args.keep) / f"case{args.from_case}")
        return
    if args.own_truth:
        with tempfile.TemporaryDirectory() as tmp:
            root = Path(args.keep or tmp)
            js = list(range(args.from_case, args.from_case + args.cases))
            with ProcessPoolExecutor(max_workers=args.jobs) as pool:
                results = list(pool.map(own_case, js, [root / f"case{j}" for j in js]))
        for r in results:
            for tag, bands in r["sets"].items():
                for band, x in bands.items():
                    print(f"own truth seed {r['seed']} {tag:10s} {band}: at position corr "
                          f"{x['at_position']['corr']:.4f} RMSE {x['at_position']['rmse_mm']:.3f} mm; shifted "
                          f"{x['shifted']['shift_m']:+.2f} m corr "
                          f"{x['shifted']['corr']:.4f} RMSE {x['shifted']['rmse_mm']:.3f} mm (true rms "
                          f"{x['true_rms_mm']:.3f})")
        return
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep or tmp)
        js = range(args.from_case, args.from_case + args.cases)
        with ProcessPoolExecutor(max_workers=args.jobs) as pool:
            futures = [pool.submit(case, j, root / f"case{j}", not args.no_ce, args.ce_length, args.ce_only)
                       for j in js]
            results = [f.result() for f in futures]
    for r in results:
        _print(r)
    for tag in () if args.ce_only else ("bogie", "axle_boxes"):
        found = sum(r["sets"][tag]["dip"] is not None for r in results)
        ci = binomtest(found, len(results)).proportion_ci(method="wilson")
        print(f"dip found ({tag}) {found}/{len(results)} (95 % interval {ci.low:.2f}-{ci.high:.2f})")
    if args.keep:
        Path(args.keep, f"results_{args.from_case}_{args.cases}.json").write_text(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
