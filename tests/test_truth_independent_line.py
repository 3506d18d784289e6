"""The independent truth's line (calibration/truth/independent/irregularity.py): settled dips
change the level under them and nothing else, and a campaign's line is rebuilt from its truth."""
from __future__ import annotations

import json

import numpy as np
import pytest

from calibration.data.campaign import open_campaign
from calibration.truth.independent import IndependentSettings, synth_in_service_independent, truth_line
from calibration.truth.independent.irregularity import Line, LineSpec, dip_shape

DIP = (300.0, 2e-3, 12.0)  # centre, depth, length [m]


def test_a_dip_changes_the_level_under_it_by_its_shape_and_nothing_else():
    plain = Line(LineSpec(length=600.0), np.random.default_rng(5))
    dipped = Line(LineSpec(length=600.0, dips=(DIP,)), np.random.default_rng(5))
    centre, depth, length = DIP
    diff = plain.z - dipped.z
    inside = np.abs(plain.s - centre) < 0.5 * length
    # the same draws: outside its span the level is the same to the bit, and the cross level everywhere
    assert np.array_equal(plain.s, dipped.s) and np.array_equal(plain.cross, dipped.cross)
    assert np.all(diff[~inside] == 0.0) and np.all(diff[inside] > 0.0)
    np.testing.assert_allclose(diff[inside], dip_shape(plain.s[inside] - centre, depth, length), rtol=0, atol=1e-15)
    # its deepest point is at the centre and as deep as asked; half-way down at a quarter length from it
    assert plain.s[np.argmax(diff)] == pytest.approx(centre, abs=plain.spec.dx / 2)
    assert diff.max() == pytest.approx(depth, rel=1e-9)
    assert plain.level(centre + length / 4) - dipped.level(centre + length / 4) == pytest.approx(depth / 2, rel=1e-3)


def test_two_dips_add_and_a_dip_of_no_depth_changes_nothing():
    plain = Line(LineSpec(length=600.0), np.random.default_rng(5))
    two = Line(LineSpec(length=600.0, dips=(DIP, (305.0, 1e-3, 20.0))), np.random.default_rng(5))
    expected = dip_shape(plain.s - 300.0, 2e-3, 12.0) + dip_shape(plain.s - 305.0, 1e-3, 20.0)
    np.testing.assert_allclose(plain.z - two.z, expected, rtol=0, atol=1e-15)
    none = Line(LineSpec(length=600.0, dips=((300.0, 0.0, 12.0),)), np.random.default_rng(5))
    assert np.array_equal(plain.z, none.z)


@pytest.mark.parametrize("dips", [((300.0, -1e-3, 12.0),), ((300.0, 1e-3, 0.0),), ((np.nan, 1e-3, 12.0),),
                                  ((300.0, 1e-3),), (300.0, 1e-3, 12.0), (("a", 1e-3, 12.0),)])
def test_a_bad_dip_is_refused_naming_the_field(dips):
    with pytest.raises(ValueError, match="LineSpec.dips"):
        LineSpec(dips=dips)


@pytest.mark.slow(seconds=1)
def test_truth_line_is_the_line_the_campaign_ran_over_and_recorded(tmp_path):
    """The line drawn again from the truth file is the campaign's: the same as a line of its seed
    and spec, and its D1 record of the recorded stretch (the dip inside it) is the campaign's
    track recording within the recording's noise."""
    settings = IndependentSettings(journeys=1, line=LineSpec(length=600.0, dips=(DIP,)), speed_range=(40.0, 45.0))
    synth_in_service_independent(tmp_path / "c", seed=6, settings=settings)
    truth = json.loads((tmp_path / "c.truth.json").read_text())
    assert truth["line"]["dips"] == [{"centre_m": 300.0, "depth_m": 2e-3, "length_m": 12.0}]
    line = truth_line(truth)
    assert line.spec == settings.line
    assert np.array_equal(line.z, Line(settings.line, np.random.default_rng(6)).z)

    rec = open_campaign(tmp_path / "c").tracks()[0]
    where = truth["line"]["track_recording"]
    assert where["start_m"] < DIP[0] < where["start_m"] + where["length_m"]
    d, clean = line.recording(where["start_m"], where["length_m"], noise=0.0, rng=np.random.default_rng(0))
    assert np.allclose(d, rec.distance, atol=1e-6)
    residual = rec.level - clean
    noise = settings.recording_noise
    assert 0.8 * noise < np.sqrt(np.mean(residual ** 2)) < 1.2 * noise
    # without its dip the line misses the recording by far more than the noise
    plain = Line(LineSpec(length=600.0), np.random.default_rng(6))
    _, undipped = plain.recording(where["start_m"], where["length_m"], noise=0.0, rng=np.random.default_rng(0))
    assert np.max(np.abs(rec.level - undipped)) > 10 * noise


def test_truth_line_refuses_a_truth_without_the_whole_line_spec():
    truth = {"simulator": "independent exudyn truth", "kind": "in_service", "seed": 0,
             "line": {"length_m": 600.0, "spectrum": "german_low"}}
    with pytest.raises(ValueError, match="sleeper_spacing, panel_length, weld_depth, dx, dips"):
        truth_line(truth)
    with pytest.raises(ValueError, match="independent exudyn truth"):
        truth_line({**truth, "simulator": "railcal"})


# ------------------------------------------------------------ railcal synth in-service --dip
def _synth(args, capsys) -> tuple[int, str]:
    from railcal.cli import main

    code = main([str(a) for a in ["synth", "in-service", *args, "--journeys", "1", "--length-km", "5", "--quiet"]])
    return code, capsys.readouterr().err


def test_cli_dips_reach_the_line_in_metres(tmp_path, monkeypatch, capsys):
    import calibration.truth.independent as independent

    seen = {}

    def fake(out, *, settings, **kw):  # the simulation itself is tested above; here only what reaches it
        seen["settings"] = settings
        return {"frequencies_hz": {}, "performance": {"real_time_factor": 1.0}}

    monkeypatch.setattr(independent, "synth_in_service_independent", fake)
    code, err = _synth([tmp_path / "c", "--truth", "exudyn", "--dip", "2500:3:12", "--dip", "4000:1.5:20"], capsys)
    assert code == 0, err
    assert seen["settings"].line.dips == ((2500.0, 3e-3, 12.0), (4000.0, 1.5e-3, 20.0))


@pytest.mark.parametrize("dip, truth, says", [
    ("2500:3:12", "railcal", "give --truth exudyn"),
    ("2500:3", "exudyn", "CENTRE_M:DEPTH_MM:LENGTH_M"),
    ("a:3:12", "exudyn", "CENTRE_M:DEPTH_MM:LENGTH_M"),
    ("2500:-3:12", "exudyn", "depth >= 0 mm"),
    ("2500:3:0", "exudyn", "length > 0 m"),
    ("2500:nan:12", "exudyn", "finite"),
    ("9000:3:12", "exudyn", "within 0..5000 m"),
])
def test_cli_refuses_a_bad_dip_naming_it_before_any_work(tmp_path, capsys, dip, truth, says):
    code, err = _synth([tmp_path / "c", "--truth", truth, f"--dip={dip}"], capsys)
    assert code == 2 and "--dip" in err and says in err and "Traceback" not in err, err
    assert not (tmp_path / "c").exists() and not (tmp_path / "c.truth.json").exists()
