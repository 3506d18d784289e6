"""The stationary excitation truth simulator: the campaign is what the truth says it is.

A coarse box model (every panel order - 4) keeps the file fast; the physics checked is the
same at full order."""
import json
from dataclasses import replace

import numpy as np
import pytest
from conftest import COARSE_BOX_ORDERS
import scipy.signal
import scipy.sparse.linalg

from railcal.cli import main
from calibration.data.campaign import open_campaign
from calibration.models.box.modal import vertical_operators
from calibration.models.box.rig import EXCITER, SENSOR_GRID
from calibration.models.box.shinkansen import floor_panel
from calibration.truth.excitation import (ExcitationSettings, anti_alias_sos, draw_truth_parameters,
                                          synth_excitation, truth_modes)

SETTINGS = ExcitationSettings(runs=1, duration=60.0, order_change=COARSE_BOX_ORDERS)


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory, model):
    root = tmp_path_factory.mktemp("exc_a") / "test"
    truth = synth_excitation(root, seed=3, settings=SETTINGS, model=model)
    return root, truth


def test_the_sensor_grid_is_27_floor_accelerometers_and_an_off_centre_exciter():
    assert len(SENSOR_GRID) == 27 and len({s.name for s in SENSOR_GRID}) == 27
    x = sorted({s.position[0] for s in SENSOR_GRID})
    assert np.allclose(np.diff(x), 2.8) and x[0] == pytest.approx(-11.2) and x[-1] == pytest.approx(11.2)
    assert sorted({s.position[1] for s in SENSOR_GRID}) == [-1.2, 0.0, 1.2]
    assert {s.position[2] for s in SENSOR_GRID} == {1.10}
    assert SENSOR_GRID[0].name == "acc_f01_l" and SENSOR_GRID[0].position[:2] == (11.2, 1.2)
    assert [floor_panel(x) for x in (11.2, 5.6, 2.8, -5.6)] == ["floor_front", "floor_front", "floor_middle",
                                                                 "floor_rear"]
    assert EXCITER.position[0] != 0 and EXCITER.position[1] != 0  # off both symmetry planes


def test_campaign_is_a_stationary_excitation_test_sampled_at_200_hz(synthetic):
    root, truth = synthetic
    assert not any(p.name.endswith("truth.json") for p in root.rglob("*"))
    assert json.loads((root.parent / "test.truth.json").read_text()) == json.loads(json.dumps(truth))
    campaign = open_campaign(root)
    meta = campaign.meta
    assert meta.kind == "stationary_excitation" and meta.sampling_rate == 200.0
    assert meta.excitation.sensor == "exciter_force" and meta.excitation.position == EXCITER.position
    assert meta.sensor("exciter_force").quantity == "force" and meta.sensor("exciter_force").unit == "N"
    assert [s.name for s in meta.sensors[1:]] == truth["sensors"] == [s.name for s in SENSOR_GRID]
    assert all(s.unit == "m/s^2" and s.body == "floor" and s.direction == "z" for s in meta.sensors[1:])
    run = campaign.read_run("run_001")
    assert run.time.size == 60 * 200 and np.allclose(np.diff(run.time), 0.005) and not run.gaps
    assert np.std(run.channels["exciter_force"]) == pytest.approx(500.0, rel=0.02)


def test_truth_lists_the_modes_in_3_to_25_hz_with_shapes_at_the_sensors(synthetic):
    _, truth = synthetic
    for key in ("parameters", "frequencies_hz", "damping_ratios", "mode_shapes", "sensors", "exciter", "effect",
                "settings"):
        assert key in truth
    assert truth["effect"] is None and truth["exciter"]["position"] == list(EXCITER.position)
    assert all(0.6 <= v <= 1.6 for v in truth["parameters"].values()) and len(truth["parameters"]) == 12
    f = np.array(list(truth["frequencies_hz"].values()))
    assert np.all((f >= 3) & (f <= 25)) and np.all(np.diff(f) >= 0)
    shapes = np.array(truth["mode_shapes"])
    assert shapes.shape == (f.size, 27)
    np.testing.assert_allclose(shapes.max(axis=1), 1.0)  # largest-magnitude entry is +1
    kinds, zeta = truth["mode_kinds"], truth["damping_ratios"]
    assert any(k == "elastic" for k in kinds.values()) and any(k == "bogie" for k in kinds.values())
    assert all(0.01 <= zeta[m] <= 0.03 for m, k in kinds.items() if k == "elastic")
    assert all(0.02 <= zeta[m] <= 0.3 for m, k in kinds.items() if k != "elastic")


def test_modal_truth_with_its_residual_mode_is_the_full_model_in_the_force_band(model):
    modal = truth_modes({"floor_bending": 1.3, "side_shear": 0.7}, settings=SETTINGS, model=model)
    undamped = replace(modal, damping_ratio=np.zeros_like(modal.damping_ratio))
    kept = replace(undamped, frequency_hz=undamped.frequency_hz[:-1], sensor_shapes=undamped.sensor_shapes[:, :-1],
                   exciter_shape=undamped.exciter_shape[:-1], damping_ratio=undamped.damping_ratio[:-1])
    p = [modal.parameters[n] for n in model.names]
    K, M = model.stiffness(p).tocsc(), model.M.tocsc()
    S, e = vertical_operators(model, SENSOR_GRID, EXCITER)
    for f in (6.3, 17.7, 33.1, 47.9):
        w = 2 * np.pi * f
        exact = -w**2 * (S @ scipy.sparse.linalg.spsolve((K - w**2 * M).tocsc(), e))
        error = np.linalg.norm(undamped.frf([f])[0] - exact) / np.linalg.norm(exact)
        truncated = np.linalg.norm(kept.frf([f])[0] - exact) / np.linalg.norm(exact)
        assert error < 0.005 and error < truncated / 5


def test_h1_of_the_synthetic_data_is_the_truth_frf(synthetic, model):
    root, truth = synthetic
    modal = truth_modes(truth["parameters"], damping=truth["modes_kept"]["damping_ratios"], settings=SETTINGS,
                        model=model)
    np.testing.assert_allclose(modal.frequency_hz, truth["modes_kept"]["frequencies_hz"], rtol=1e-9)
    run = open_campaign(root).read_run("run_001")
    force = run.channels["exciter_force"]
    acc = np.column_stack([run.channels[n] for n in truth["sensors"]])
    nperseg = 4096
    n_avg = 1 + (force.size - nperseg) // (nperseg // 2)
    kw = {"fs": 200.0, "nperseg": nperseg, "axis": 0}
    f, Gff = scipy.signal.welch(force, **kw)
    _, Gfy = scipy.signal.csd(force[:, None], acc, **kw)
    _, Gyy = scipy.signal.welch(acc, **kw)
    H1, H = Gfy / Gff[:, None], modal.frf(f)
    band = (f > 6) & (f < 45)
    scale = np.abs(H[band]).max(axis=1, keepdims=True)
    assert np.median(np.abs(H1[band] - H[band]) / scale) < 0.01  # whole band, every sensor
    # at the resonances of the elastic modes, at the sensor that moves most: within a few %,
    # and within H1's own random error sqrt(1 - g^2) / (g sqrt(2 n_avg)) (Bendat & Piersol),
    # which leakage makes large at the sharpest peaks of so short a record
    errors = []
    for label, fk in truth["frequencies_hz"].items():
        if truth["mode_kinds"][label] == "elastic" and 6 < fk < 25:
            i = np.argmin(np.abs(f - fk))
            o = np.argmax(np.abs(H[i]))
            g2 = abs(Gfy[i, o]) ** 2 / (Gff[i] * Gyy[i, o])
            random_error = np.sqrt((1 - g2) / (2 * n_avg * g2))
            errors.append(abs(H1[i, o] - H[i, o]) / abs(H[i, o]))
            assert errors[-1] < 0.02 + 4 * random_error, label
    assert len(errors) >= 5 and np.median(errors) < 0.03


def test_nothing_above_80_hz_but_sensor_noise_through_the_anti_alias_filter(synthetic):
    root, truth = synthetic
    run = open_campaign(root).read_run("run_001")
    s = truth["settings"]
    f, P = scipy.signal.welch(run.channels["acc_f09_r"], fs=200.0, nperseg=1024)
    # white noise at 1000 Hz through the filter, decimated by 5: the PSD at f is the sum over
    # the five frequencies below 500 Hz that fold onto f
    folded = np.stack([f, 200 - f, 200 + f, 400 - f, 400 + f])
    _, h = scipy.signal.sosfreqz(anti_alias_sos(SETTINGS), worN=folded.ravel(), fs=s["fs_sim"])
    white = 2 * s["acc_noise"] ** 2 / s["fs_sim"]  # one-sided PSD [(m/s^2)^2/Hz]
    expected = white * (np.abs(h) ** 2).reshape(folded.shape).sum(axis=0)
    high = (f >= 85) & (f <= 99)
    assert np.mean(P[high]) == pytest.approx(np.mean(expected[high]), rel=0.2)
    assert np.mean(P[high]) < 0.1 * 5 * white  # decimating without the filter would give 5 x white


@pytest.mark.slow
def test_same_seed_same_files_other_seed_other_vehicle(synthetic, tmp_path, model):
    root, truth = synthetic
    again = tmp_path / "test"
    synth_excitation(again, seed=3, settings=SETTINGS, model=model)
    assert (again / "runs" / "run_001.csv").read_bytes() == (root / "runs" / "run_001.csv").read_bytes()
    assert (again / "campaign.toml").read_bytes() == (root / "campaign.toml").read_bytes()
    assert (tmp_path / "test.truth.json").read_bytes() == (root.parent / "test.truth.json").read_bytes()
    other = draw_truth_parameters(SETTINGS, np.random.default_rng(4))
    assert other != truth["parameters"]
    assert draw_truth_parameters(SETTINGS, np.random.default_rng(3)) == truth["parameters"]


def test_synth_excitation_command_refuses_bad_input_with_exit_2(synthetic, tmp_path, capsys):
    root, _ = synthetic
    before = (root / "runs" / "run_001.csv").stat().st_mtime_ns
    assert main(["synth", "excitation", str(root), "--quiet"]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (root / "runs" / "run_001.csv").stat().st_mtime_ns == before
    assert main(["synth", "excitation", str(tmp_path / "x"), "--effect", "cracked_floor"]) == 2
    assert "unknown effect 'cracked_floor'" in capsys.readouterr().err
    assert main(["synth", "excitation", str(tmp_path / "y"), "--duration", "10"]) == 2
    assert "--duration" in capsys.readouterr().err
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_settings_refuse_inconsistent_values():
    with pytest.raises(ValueError, match="integer multiple"):
        ExcitationSettings(fs_sim=900.0)
    with pytest.raises(ValueError, match="anti_alias_hz"):
        ExcitationSettings(anti_alias_hz=120.0)
    with pytest.raises(ValueError, match="order_change"):
        ExcitationSettings(order_change=-5)
    with pytest.raises(ValueError, match="unknown parameter"):
        truth_modes({"roof_stiffness": 1.2})
