"""Track profile inference (calibration/track_inference, ``railcal infer-track``).

The filter's own-model tests run the calibrated car's equations over a known profile:
they test the inverse's code, not its evidence, which is the exudyn-truth bench
(``scripts/bench_infer_track.py``)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from calibration.data.tracks import read_track_file
from calibration.models.track_irregularity import german_vertical_psd, synthesise_profile
from calibration.track_inference.kalman import KalmanSettings, PassProfile, infer_pass
from calibration.track_inference.profile import band_filter, changes, combine
from railcal.cli import main

from track_passes import FS, NOISE, STEP, own_pass



@pytest.fixture(scope="module")
def own():
    p, ps, (sx, zx) = own_pass(1200.0)
    # the noise on the grid: the white noise's rms through the 30 Hz low-pass
    noise = {k: v * np.sqrt(30.0 / (FS / 2)) for k, v in NOISE.items()}
    pr = infer_pass(ps, p, KalmanSettings(noise=noise), draws=16)
    inner = slice(int(60 / STEP), pr.level.size - int(60 / STEP))
    est = band_filter(pr.level, "D1", STEP)[inner]
    true = band_filter(np.interp(pr.distance, sx, zx), "D1", STEP)[inner]
    formal = np.sqrt(np.mean(band_filter(pr.error_draws, "D1", STEP)[inner] ** 2))
    return est, true, formal


def test_the_filter_recovers_the_profile_its_own_car_ran_over(own):
    est, true, _ = own
    assert np.corrcoef(est, true)[0, 1] > 0.99
    assert np.sqrt(np.mean((est - true) ** 2)) < 0.1e-3  # [m] against a D1 rms of about 1 mm


def test_the_error_draws_give_the_error_size_on_the_models_own_data(own):
    est, true, formal = own
    actual = np.sqrt(np.mean((est - true) ** 2))
    assert 0.5 < actual / formal < 2.0


def test_an_extended_model_is_filtered_with_its_additions():
    """A diagnosis's extended car (here a flexible carbody) is the filter's car as it stands."""
    from calibration.models.car2d import CarExtras

    p, ps, _ = own_pass(200.0)
    plain = infer_pass(ps, p, KalmanSettings(), draws=0)
    bent = infer_pass(ps, p, KalmanSettings(), extras=CarExtras(bending_hz=9.0), draws=0)
    assert np.all(np.isfinite(bent.level)) and bent.log_likelihood != plain.log_likelihood


def _profile(run_id, distance, level, std=1e-4):
    return PassProfile(run_id, distance, level, np.full(level.size, std), 0.0, {},
                       np.random.default_rng(len(run_id)).normal(0, std, (level.size, 4)))


def test_combine_aligns_passes_on_their_mean_position_and_averages_them():
    rng = np.random.default_rng(3)
    d, truth = synthesise_profile(german_vertical_psd, 3000.0, STEP, rng, min_wavelength=1.0, max_wavelength=200.0)
    shifts = {"a": 0.8, "b": -0.3, "c": -0.5}  # a pass's distance axis is this far ahead of the truth
    passes = [_profile(k, d + s, truth + rng.normal(0, 5e-5, d.size)) for k, s in shifts.items()]
    sec = combine(passes, STEP)
    for k, s in shifts.items():  # the mean shift is zero, so each pass is moved back by its own
        assert sec.offsets[k] == pytest.approx(-s, abs=0.03)
    ok = sec.passes["D1"] == 3
    err = sec.level["D1"][ok] - np.interp(sec.distance[ok], d, band_filter(truth, "D1", STEP))
    # the noise in D1 (0.15 of a white band's power), averaged over three passes: 1.1e-5 m
    assert np.sqrt(np.mean(err ** 2)) < 2.5e-5


def test_changes_find_a_settled_dip_where_it_is_and_nothing_else():
    rng = np.random.default_rng(4)
    d = np.arange(0.0, 4000.0, STEP)
    before = band_filter(rng.normal(0, 1e-3, d.size), "D1", STEP) * 3
    dip = np.where(np.abs(d - 2100.0) < 5.0, 5e-3 * 0.5 * (1 + np.cos(2 * np.pi * (d - 2100.0) / 10.0)), 0.0)
    after = before - band_filter(dip, "D1", STEP) + rng.normal(0, 1e-4, d.size)
    found, _ = changes(d, before, after, STEP)
    assert len(found) == 1
    assert found[0].centre == pytest.approx(2100.0, abs=1.0)
    assert found[0].depth == pytest.approx(5e-3, rel=0.1)
    assert changes(d, before, before + rng.normal(0, 1e-4, d.size), STEP)[0] == []


def test_a_profile_is_compared_only_with_one_it_overlaps():
    from calibration.track_inference.infer import TrackResult, compare
    from calibration.track_inference.profile import SectionProfile

    d = np.arange(0.0, 2000.0, STEP)
    level = {"D1": np.zeros(d.size), "D2": np.full(d.size, np.nan)}
    sec = SectionProfile(d, level, dict(level), {"D1": np.ones(d.size, int), "D2": np.zeros(d.size, int)}, {}, {})
    result = TrackResult(sec, (), (), KalmanSettings(), False, (), 0.0)
    with pytest.raises(ValueError, match="overlaps"):
        compare(result, np.array([5000.0, 6000.0]), np.zeros(2))


def test_settings_are_checked():
    with pytest.raises(ValueError, match="step"):
        KalmanSettings(step=0.0)
    with pytest.raises(ValueError, match="spectrum"):
        KalmanSettings(spectrum="smooth")


# ------------------------------------------------------------------- the command
@pytest.fixture(scope="module")
def small_campaign(tmp_path_factory):
    from calibration.truth.independent import IndependentSettings, synth_in_service_independent
    from calibration.truth.independent.irregularity import LineSpec
    from railcal.registry import MODELS

    root = tmp_path_factory.mktemp("track") / "c"
    synth_in_service_independent(root, seed=3, settings=IndependentSettings(journeys=1, line=LineSpec(length=1500.0)))
    cal = root.parent / "cal.json"
    cal.write_text(json.dumps({"format": "railcal-calibration/1", **MODELS["car2d"].example_calibration()}))
    return root, cal


@pytest.mark.slow(seconds=25)
def test_infer_track_writes_a_d1_profile_a_summary_and_a_figure(small_campaign, capsys):
    root, cal = small_campaign
    out = root.parent / "profile.csv"
    assert main(["infer-track", str(root), "--calibration", str(cal), "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    rec = read_track_file(out)  # a profile is a track file: a campaign can validate over it
    assert rec.band == "D1" and np.all(np.diff(rec.distance) > 0)
    summary = json.loads(out.with_suffix(".json").read_text())
    assert summary["format"] == "railcal-track-profile/1"
    assert summary["sensors"] == ["bogie1_acc_z", "bogie1_gyro_pitch"]
    assert 0.2 < summary["bands"]["D1"]["level_rms_mm"] < 5.0
    assert summary["bands"]["D1"]["std_median_mm"] < summary["bands"]["D1"]["level_rms_mm"]
    assert out.with_suffix(".png").exists() and "inferred the D1 level" in printed
    assert (summary["profile_d2"] is None) == (not out.with_name("profile_d2.csv").exists())
    # an earlier profile with a 4 mm dip at its middle and a 60 m hole elsewhere: the dip shows as
    # a rise since, the hole as nothing
    mid = rec.distance[rec.distance.size // 2]
    dip = np.where(np.abs(rec.distance - mid) < 5.0, 4e-3 * 0.5 * (1 + np.cos(2 * np.pi * (rec.distance - mid) / 10)),
                   0.0)
    keep = np.abs(rec.distance - (rec.distance[0] + 300.0)) > 30.0
    earlier = root.parent / "earlier.csv"
    level = rec.level - band_filter(dip, "D1", STEP)
    earlier.write_text('# band = "D1"\ndistance,level\n' + "".join(
        f"{float(d)!r},{float(z)!r}\n" for d, z in zip(rec.distance[keep], level[keep])))
    again = root.parent / "again.csv"
    assert main(["infer-track", str(root), "--calibration", str(cal), "--out", str(again), "--compare", str(earlier),
                 "--quiet"]) == 0
    found = json.loads(again.with_suffix(".json").read_text())["changes"]
    assert len(found) == 1 and abs(found[0]["centre_m"] - mid) < 1.0
    assert found[0]["depth_mm"] == pytest.approx(-4.0, rel=0.1)


@pytest.mark.parametrize("change, message", [
    ({"out": "profile.txt"}, "--out"),
    ({"step": "0"}, "--step"),
    ({"step": "1e-4"}, "--step"),
    ({"compare": "d2.csv"}, "D1 profile"),
    ({"calibration": "box.json"}, "box"),
])
def test_infer_track_refuses_bad_input_with_exit_2(small_campaign, tmp_path, capsys, example_calibration, change,
                                                   message):
    root, cal = small_campaign
    (tmp_path / "d2.csv").write_text('# band = "D2"\ndistance,level\n0,0\n1,0\n')
    (tmp_path / "box.json").write_text(json.dumps({"format": "railcal-calibration/1", **example_calibration("box")}))
    args = {"out": "p.csv", "step": "0.25", "compare": None, "calibration": str(cal), **change}
    calibration = str(tmp_path / args["calibration"]) if change.get("calibration") else args["calibration"]
    argv = ["infer-track", str(root), "--calibration", calibration, "--out", str(tmp_path / args["out"]), "--step",
            args["step"], "--quiet"]
    if args["compare"]:
        argv += ["--compare", str(tmp_path / args["compare"])]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "p.csv").exists()


# ------------------------------------------------------------------- reading passes
def _copy_campaign(src, dst, edit):
    """A copy of campaign ``src`` whose run file's columns are edited by ``edit(columns)``."""
    import shutil

    from calibration.data.outputs import write_csv
    from calibration.data.tables import read_csv

    shutil.copytree(src, dst)
    path = next((dst / "runs").glob("*.csv"))
    cols = dict(read_csv(path).columns)
    edit(cols)
    with open(path, "wb") as f:
        write_csv(f, cols)
    return dst


def test_a_run_split_at_an_invalid_sample_gives_passes_of_their_own_names(small_campaign, tmp_path):
    from calibration.data.campaign import open_campaign
    from calibration.track_inference.passes import read_passes

    def nan_in_the_middle(cols):
        cols["bogie1_acc_z"] = cols["bogie1_acc_z"].copy()
        cols["bogie1_acc_z"][cols["bogie1_acc_z"].size // 2] = np.nan

    root = _copy_campaign(small_campaign[0], tmp_path / "c", nan_in_the_middle)
    passes = read_passes(open_campaign(root), step=STEP)
    assert [p.run_id for p in passes] == ["journey_001:1", "journey_001:2"]
    assert passes[0].s[-1] < passes[1].s[0]


@pytest.mark.parametrize("drop, warning", [("distance", "no distance column"), ("speed", "no speed column")])
def test_a_run_with_one_position_column_is_read_with_a_warning(small_campaign, tmp_path, drop, warning):
    from calibration.data.campaign import open_campaign
    from calibration.track_inference.passes import read_passes

    root = _copy_campaign(small_campaign[0], tmp_path / "c", lambda cols: cols.pop(drop))
    with pytest.warns(UserWarning, match=warning):
        passes = read_passes(open_campaign(root), step=STEP)
    assert len(passes) == 1 and passes[0].s[-1] - passes[0].s[0] > 1000.0


def test_a_biased_speed_is_scaled_to_the_gps_distance():
    """0.5 % too high a speed would drift 50 m over 10 km; fitted to the GPS it stays put."""
    from types import SimpleNamespace
    from pathlib import Path

    from calibration.track_inference.passes import line_position

    t = np.arange(0.0, 300.0, 0.01)
    true = 33.0 * t
    gps = true + 1.5 * np.sin(2 * np.pi * t / 60.0)  # a wandering fix
    run = SimpleNamespace(time=t, speed=np.full(t.size, 33.0 * 1.005), distance=gps, path=Path("r.csv"))
    assert np.max(np.abs(line_position(run, Path("runs")) - true)) < 1.0
    # a right speed is not scaled to the wander: a slow 1.5 m drift of the fixes leaves it be
    drift = true + 1.5 * np.sin(np.pi * t / 300.0)
    run = SimpleNamespace(time=t, speed=np.full(t.size, 33.0), distance=drift, path=Path("r.csv"))
    d = line_position(run, Path("runs"))
    assert np.ptp(d - true) < 1e-6 and abs(np.mean(d - true)) < 1.5


def test_the_inertial_method_integrates_the_rail_acceleration_twice():
    from calibration.track_inference.inertial import inertial_level
    from calibration.track_inference.passes import Channel, Pass

    p, ps, (sx, zx) = own_pass(600.0)
    from calibration.models.car2d import wheelset_positions

    xw = wheelset_positions(p)
    slope, curv = np.gradient(zx, sx), np.gradient(np.gradient(zx, sx), sx)
    axles = tuple(Channel(f"axle{j + 1}", "axle", ps.v ** 2 * np.interp(ps.s + xw[j], sx, curv)
                          + ps.a * np.interp(ps.s + xw[j], sx, slope) + 9.81, wheelset=j + 1) for j in (0, 1))
    d, z = inertial_level(Pass(ps.run_id, ps.s, ps.t, ps.v, ps.a, axles), xw)
    inner = slice(int(60 / STEP), d.size - int(60 / STEP))
    true = band_filter(np.interp(d, sx, zx), "D1", STEP)
    assert np.corrcoef(z[inner], true[inner])[0, 1] > 0.99
    # blended into a level that knows nothing under 8 m, the short waves are the axle boxes'
    from dataclasses import replace

    from calibration.track_inference.inertial import blend

    long_only = band_filter(np.interp(d, sx, zx), "D2", STEP)  # a stand-in for the filter's level
    pp = _profile("own", d, long_only)
    mixed = blend(pp, replace(ps, channels=axles), xw, 8.0)
    from calibration.track_inference.inertial import _lowpass_distance

    level = np.interp(d, sx, zx)
    expected = _lowpass_distance(long_only, 8.0, STEP) + level - _lowpass_distance(level, 8.0, STEP)
    got, want = band_filter(mixed.level, "D1", STEP)[inner], band_filter(expected, "D1", STEP)[inner]
    assert np.corrcoef(got, want)[0, 1] > 0.99


def test_the_noise_search_follows_the_data():
    """The filter's default noise is several times the pass's: the search brings it down."""
    from calibration.track_inference.kalman import fit_noise

    p, ps, _ = own_pass(400.0)
    start = KalmanSettings(noise={"bogie_acc": 0.1, "gyro": 0.01})
    fitted, ll = fit_noise(ps, p, start, length=400.0)
    assert fitted.noise["bogie_acc"] < 0.05 and fitted.noise["gyro"] < 0.005
    assert ll > infer_pass(ps, p, start, draws=0).log_likelihood
