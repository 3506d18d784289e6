"""Unique mode labels (``railcal modes``, ``car2d.undamped_modes`` / ``damped_modes``) and the
box-type vehicle's eigen-analysis (``railcal modes --model box``).

The bogie pitch pair is exactly degenerate in both models (the bogie's pitch does not reach
the carbody), so its in-phase / anti-phase members are fixed by recombination, not by the
solver's round-off; both members sit at the closed-form frequency sqrt(k_theta / J) / 2 pi."""
import json

import numpy as np
import pytest

from railcal.cli import main
from calibration.models.assembly import Body, Attachment, SpringDamper
from calibration.models.car2d import (CarExtras, build_car, damped_modes, frequencies_by_label, undamped_modes)
from calibration.models.vehicles import INTERCITY_TRAILER as CAR
from calibration.models.vehicles import VEHICLES, box_modes


def _amplitudes(asm, mode, family):
    coord = family.split("_")[1]
    dof = {"bounce": "z", "pitch": "pitch"}[coord]
    return mode.shape[asm.dof(f"bogie1_{dof}")], mode.shape[asm.dof(f"bogie2_{dof}")]


@pytest.mark.parametrize("vehicle", sorted(VEHICLES))
def test_each_car_mode_has_a_unique_label_and_the_bogie_pairs_are_told_apart_by_their_shape(vehicle):
    p = VEHICLES[vehicle]
    asm = build_car(p)
    for modes in (undamped_modes(asm), damped_modes(asm)):
        names = [m.name for m in modes]
        assert len(set(names)) == len(names) == 6, names
        assert {m.label for m in modes} == {"carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch"}
        for m in modes:
            if m.label.startswith("bogie_"):
                a1, a2 = _amplitudes(asm, m, m.label)
                assert abs(abs(a1) - abs(a2)) <= 1e-6 * abs(a1)  # a symmetric car: both bogies alike
                phase = "in_phase" if np.real(a1 * np.conj(a2)) > 0 else "anti_phase"
                assert m.name == f"{m.label}_{phase}" and m.family == m.label
    pitch = [m for m in undamped_modes(asm) if m.label == "bogie_pitch"]
    closed = np.sqrt(2 * p.k_p * p.L_b**2 / p.J_b) / (2 * np.pi)  # two primary springs at +-L_b
    assert [m.frequency_hz for m in pitch] == pytest.approx([closed, closed], rel=1e-10)
    for m in pitch:  # recombined, still eigenvectors and M-orthonormal
        w2 = (2 * np.pi * m.frequency_hz) ** 2
        assert np.linalg.norm(asm.K @ m.shape - w2 * asm.M @ m.shape) <= 1e-9 * np.linalg.norm(asm.K @ m.shape)
        assert m.shape @ asm.M @ m.shape == pytest.approx(1.0, rel=1e-12)
    assert pitch[0].shape @ asm.M @ pitch[1].shape == pytest.approx(0.0, abs=1e-12)


def test_the_degenerate_pair_is_named_the_same_whatever_the_round_off():
    """A relative change of 1e-13 in J_b moves the solver's basis of the pitch eigenspace,
    not the names or the recombined shapes."""
    ref = {m.name: m for m in undamped_modes(build_car(CAR))}
    for eps in (1e-13, -1e-13, 3e-14):
        asm = build_car(CAR.replace(J_b=CAR.J_b * (1 + eps)))
        for m in undamped_modes(asm):
            assert m.name in ref
            overlap = abs(m.shape @ asm.M @ ref[m.name].shape)
            assert overlap == pytest.approx(1.0, abs=1e-6), (m.name, overlap)


def test_a_bogie_moving_alone_gets_its_per_bogie_spec_label():
    """2 t of equipment hung stiffly at bogie 1's centre: its bounce no longer pairs with
    bogie 2's; the spec's per-bogie labels name them, and their pitch stays a pair. (The
    mount's own mode, far above, is bogie 1's bounce too: the two get _1 and _2.)"""
    extras = CarExtras(bodies=(Body("equipment", 2000.0, CAR.L_v),),
                       elements=(SpringDamper("equipment_mount", Attachment("bogie1", CAR.L_v),
                                              Attachment("equipment", CAR.L_v), 1e10, 0.0),))
    modes = undamped_modes(build_car(CAR, extras=extras))
    names = [m.name for m in modes]
    assert len(set(names)) == len(names)
    assert {"bogie1_bounce_1", "bogie2_bounce", "bogie_pitch_in_phase", "bogie_pitch_anti_phase"} <= set(names), names
    heavy = next(m for m in modes if m.name == "bogie1_bounce_1")
    light = next(m for m in modes if m.name == "bogie2_bounce")
    assert heavy.frequency_hz < light.frequency_hz  # the heavier bogie bounces lower


def test_the_v1_family_labels_still_give_one_frequency_each():
    f = frequencies_by_label(undamped_modes(build_car(CAR)))
    assert set(f) == {"carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch"}
    pair = sorted(m.frequency_hz for m in undamped_modes(build_car(CAR)) if m.label == "bogie_bounce")
    assert f["bogie_bounce"] == pair[0]  # the in-phase, lower member (the seed's convention)


def test_railcal_modes_writes_unique_labels_with_their_family(tmp_path, capsys):
    out = tmp_path / "modes.json"
    assert main(["modes", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    rep = json.loads(out.read_text())
    labels = [m["label"] for m in rep["modes"]]
    assert len(set(labels)) == len(labels) == 6
    assert "bogie_bounce_in_phase" in printed and "bogie_pitch_anti_phase" in printed
    families = [m["family"] for m in rep["modes"]]
    assert families.count("bogie_bounce") == 2 and families.count("bogie_pitch") == 2
    for m in rep["modes"]:  # each undamped mode with the damped mode of the same shape
        assert 0 < m["damping_ratio"] < 0.5 and abs(m["damped_frequency_hz"] / m["frequency_hz"] - 1) < 0.1


# ------------------------------------------------------------------ the box-type vehicle

@pytest.fixture(scope="module")
def coarse_box_modes(coarse_box_model):
    return box_modes(coarse_box_model, {}, max_hz=25.0)


def test_box_modes_have_unique_labels_and_the_bogie_pitch_pair_its_closed_form(coarse_box_model, coarse_box_modes):
    from calibration.models.box.shinkansen import BOGIE, SUSPENSION, Geometry

    modes = coarse_box_modes
    labels = [m.label for m in modes]
    assert len(set(labels)) == len(labels)
    assert [m.frequency_hz for m in modes] == sorted(m.frequency_hz for m in modes)
    assert {"carbody_bounce", "carbody_pitch", "carbody_roll", "bogie_bounce_in_phase", "bogie_bounce_anti_phase",
            "vertical_bending_1"} <= set(labels), labels
    # four axle boxes at +-semi_wheelbase carry the bogie's pitch: k_theta = 4 k_z a^2
    k_theta = 4 * SUSPENSION["axle_box"]["k"][2] * Geometry().semi_wheelbase ** 2
    closed = np.sqrt(k_theta / BOGIE["inertia"][1]) / (2 * np.pi)
    pitch = [m for m in modes if m.family == "bogie_pitch"]
    assert [m.label for m in pitch] == ["bogie_pitch_in_phase", "bogie_pitch_anti_phase"]
    assert [m.frequency_hz for m in pitch] == pytest.approx([closed, closed], rel=1e-8)
    bounce = next(m for m in modes if m.label == "carbody_bounce")
    assert 0.5 < bounce.frequency_hz < 2.0 and 0 < bounce.damping_ratio < 1  # on the air springs
    assert all(m.damping_ratio is None for m in modes if m.kind == "elastic")


def test_railcal_modes_box_takes_factors_and_refuses_bad_ones(tmp_path, capsys, monkeypatch, coarse_box_model):
    import calibration.models.box.shinkansen as shinkansen

    def coarse(calibration):  # the coarse model: the full one takes half a minute to assemble and solve
        return coarse_box_model, {n: float(calibration["parameters"].get(n, 1.0)) for n in coarse_box_model.names}

    # bad factors are refused before the model is assembled
    assert main(["modes", "--model", "box", "--param", "roof_membrane=-1"]) == 2
    assert "roof_membrane must be positive" in capsys.readouterr().err
    assert main(["modes", "--model", "box", "--param", "nosuch=1"]) == 2
    assert "nosuch unknown" in capsys.readouterr().err
    monkeypatch.setattr(shinkansen, "calibrated_box_model", coarse)
    out = tmp_path / "box.json"
    assert main(["modes", "--model", "box", "--param", "floor_bending=1.5", "--out", str(out)]) == 0
    rep = json.loads(out.read_text())
    assert rep["model"] == "box" and rep["parameters"]["floor_bending"] == 1.5
    labels = [m["label"] for m in rep["modes"]]
    assert len(set(labels)) == len(labels) and "vertical_bending_1" in labels
    stiffer = next(m["frequency_hz"] for m in rep["modes"] if m["label"] == "vertical_bending_1")
    nominal = next(m.frequency_hz for m in box_modes(coarse_box_model, {}) if m.label == "vertical_bending_1")
    assert stiffer > nominal  # a stiffer floor raises the first bending
