"""Hidden effects of the stationary excitation test: underfloor equipment, a softened panel
and (outside the catalogue) a sensor on a resilient bracket are the physics they claim to
be, and the campaigns carry them.

A coarse box model (every panel order - 4) keeps the file fast; the physics checked is the
same at full order."""
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
import scipy.sparse as sp
import scipy.sparse.linalg
from conftest import COARSE_BOX_ORDERS

from calibration.data.campaign import open_campaign
from calibration.data.errors import InputError
from calibration.models.box.fit import sensor_operator
from calibration.models.box.parametric_basis import full_modes
from calibration.truth.effects import EFFECTS, UNCATALOGUED, EffectChoice, EffectSpec, parse_effect
from calibration.models.box.assembly import carbody_mass
from calibration.models.box.modal import ModalModel
from calibration.models.box.rig import EXCITER, SENSOR_GRID
from calibration.truth.excitation import ExcitationSettings, draw_truth_parameters, synth_excitation, truth_model, truth_modes
from calibration.truth.excitation_effects import (BRACKET_CLEARANCE, BRACKET_DAMPING, EQUIPMENT_DETUNING, EQUIPMENT_X,
                                                  EQUIPMENT_Y, SOFTENING_PANELS, SensorBracket, UnderfloorEquipment,
                                                  add_equipment, mount_point, soften_panel)

SETTINGS = ExcitationSettings(runs=1, duration=60.0, order_change=COARSE_BOX_ORDERS)
MOUNT = (-3.3, -0.8, 1.1)  # [m] an off-centre floor point for the physics tests
G = 9.81


@pytest.fixture(scope="module")
def parameters():
    return draw_truth_parameters(SETTINGS, np.random.default_rng(21))


@pytest.fixture(scope="module")
def base(model, parameters):
    """The modal truth with the mount point's residual pseudo-mode, and the modes' values there."""
    mounts = (mount_point(MOUNT),)
    modal = truth_modes(parameters, settings=SETTINGS, model=model, sensors=SENSOR_GRID + mounts,
                        residual_points=mounts)
    return replace(modal, sensor_shapes=modal.sensor_shapes[:-1]), modal.sensor_shapes[-1]


def _tuned(modal, mount_shape, band=(8.0, 20.0)):
    """The elastic mode in band the mount point moves most in."""
    f = modal.frequency_hz
    cand = np.flatnonzero((f >= band[0]) & (f <= band[1]) & (np.array(modal.kind) == "elastic"))
    return int(cand[np.argmax(mount_shape[cand] ** 2)])


# ----------------------------------------------------------------- underfloor equipment
def test_equipment_on_the_modal_truth_is_the_full_box_model_with_one_more_dof(model, parameters, base):
    modal, a = base
    k = _tuned(modal, a)
    eq = UnderfloorEquipment(0.03 * carbody_mass(model), MOUNT, modal.frequency_hz[k] * 1.02)
    coupled = add_equipment(modal, a, eq)
    # the full model (n_dof + 1): the spring k_e between the floor point and the mass
    p = [parameters[n] for n in model.names]
    b = sp.csr_matrix(np.append(sensor_operator(model, (eq.mount(),))[0], -1.0))
    K = sp.block_diag([model.stiffness(p), sp.csr_matrix((1, 1))]) + eq.stiffness * (b.T @ b)
    M = sp.block_diag([model.M, sp.csr_matrix([[eq.mass]])])
    v0 = np.random.default_rng(0).standard_normal(model.n_dof + 1)
    w2 = scipy.sparse.linalg.eigsh(K.tocsc(), k=60, M=M.tocsc(), sigma=-1.0, which="LM", v0=v0)[0]
    exact = np.sort(np.sqrt(w2)) / (2 * np.pi)
    low = coupled.modal.frequency_hz < 40.0
    np.testing.assert_allclose(coupled.modal.frequency_hz[low], exact[:low.sum()], rtol=1e-5)
    # without the mount's residual pseudo-mode the omitted modes' flexibility is missing
    plain = truth_modes(parameters, settings=SETTINGS, model=model, sensors=SENSOR_GRID + (eq.mount(),))
    plain = add_equipment(replace(plain, sensor_shapes=plain.sensor_shapes[:-1]), plain.sensor_shapes[-1], eq)
    truncated = plain.modal.frequency_hz[:low.sum()] / exact[:low.sum()] - 1
    assert np.abs(truncated).max() > 100 * np.abs(coupled.modal.frequency_hz[low] / exact[:low.sum()] - 1).max()
    assert np.all(truncated > -1e-9)  # a modal truncation is stiffer: Rayleigh-Ritz


def test_equipment_static_deflection_and_energy(model, base):
    modal, a = base
    k = _tuned(modal, a)
    eq = UnderfloorEquipment(0.05 * carbody_mass(model), MOUNT, modal.frequency_hz[k])
    c = add_equipment(modal, a, eq)
    w, wc = 2 * np.pi * modal.frequency_hz, 2 * np.pi * c.modal.frequency_hz
    # each coupled mode's kinetic energy is shared between structure and mass: sums to 1
    np.testing.assert_allclose(np.sum(c.structure**2, axis=0) + c.equipment_share, 1.0, atol=1e-10)
    assert np.sum(c.equipment_share) == pytest.approx(1.0, abs=1e-10)  # M^-1 of the mass DOF is 1 / m_e
    # its weight m_e g: from the coupled modes, the floor sinks by m_e g sum a^2 / omega^2 (the
    # structure's flexibility at the mount) and the spring compresses by m_e g / k_e
    weight = eq.mass * G
    floor = weight * np.sum(c.mount_shape * c.equipment_shape / wc**2)
    mass = weight * np.sum(c.equipment_shape**2 / wc**2)
    assert floor == pytest.approx(weight * np.sum(a**2 / w**2), rel=1e-9)
    assert mass - floor == pytest.approx(weight / eq.stiffness, rel=1e-9)
    assert c.modal.frequency_hz.size == modal.frequency_hz.size + 1 and c.modal.kind[-1] == "residual"


def test_a_light_tuned_mass_splits_a_mode_as_the_two_dof_closed_form(model, base):
    modal, a = base
    k = _tuned(modal, a)
    wk = 2 * np.pi * modal.frequency_hz[k]
    for ratio in (1e-5, 1e-4):
        eq = UnderfloorEquipment(ratio * carbody_mass(model), MOUNT, modal.frequency_hz[k])  # tuned exactly
        c = add_equipment(modal, a, eq)
        lo, hi = c.split(k)
        f = c.modal.frequency_hz
        assert f[lo] < modal.frequency_hz[k] < f[hi]
        # modal mass 1 with the shape a_k at the mount: mass ratio mu = m_e a_k^2
        mu = eq.mass * a[k] ** 2
        we2 = eq.stiffness / eq.mass
        s = wk**2 + we2 * (1 + mu)
        d = np.sqrt(s**2 - 4 * wk**2 * we2)
        closed = np.sqrt([(s - d) / 2, (s + d) / 2]) / (2 * np.pi)
        width = f[hi] - f[lo]
        assert width == pytest.approx(closed[1] - closed[0], rel=0.05)
        assert width / modal.frequency_hz[k] == pytest.approx(np.sqrt(mu), rel=0.05)  # tuned: split = sqrt(mu)
        np.testing.assert_allclose(f[[lo, hi]], closed, atol=0.05 * width)
        content = c.structure[k, [lo, hi]] ** 2
        assert content.sum() > 0.95 and np.all(c.equipment_share[[lo, hi]] > 0.4)  # a tuned-mass pair


def test_a_single_mode_with_a_tuned_mass_is_exactly_the_two_dof_system():
    f0, a, m = 12.0, 0.02, 300.0  # [Hz], [1/sqrt(kg)] (modal mass 1), [kg]
    modal = ModalModel({}, np.array([f0]), np.array([0.02]), ("elastic",), np.array([[a]]), np.array([a]),
                       np.array([0.0]))
    eq = UnderfloorEquipment(m, MOUNT, f0 * 1.03)
    c = add_equipment(modal, np.array([a]), eq)
    wk2, we2, mu = (2 * np.pi * f0) ** 2, eq.stiffness / m, m * a**2
    s = wk2 + we2 * (1 + mu)
    d = np.sqrt(s**2 - 4 * wk2 * we2)
    np.testing.assert_allclose(c.modal.frequency_hz, np.sqrt([(s - d) / 2, (s + d) / 2]) / (2 * np.pi), rtol=1e-12)
    # damping kept whole: poles and FRF of the modal form are the second-order system's
    Mf, Kf = np.diag([1.0, m]), np.array([[wk2 + eq.stiffness * a**2, -eq.stiffness * a], [-eq.stiffness * a,
                                                                                             eq.stiffness]])
    Cf = np.diag([2 * 0.02 * 2 * np.pi * f0, 0.0]) + eq.damping * np.outer([a, -1.0], [a, -1.0])
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.linalg.solve(Mf, Kf), -np.linalg.solve(Mf, Cf)]])
    lam = np.linalg.eigvals(A)
    lam = lam[lam.imag > 0]
    lam = lam[np.argsort(np.abs(lam))]
    f_pole, z_pole = c.modal.poles()
    np.testing.assert_allclose(f_pole, np.abs(lam) / (2 * np.pi), rtol=1e-10)
    np.testing.assert_allclose(z_pole, -lam.real / np.abs(lam), rtol=1e-8)
    for f in (9.0, 11.7, 12.4, 15.0):
        w = 2 * np.pi * f
        x = np.linalg.solve(Kf - w**2 * Mf + 1j * w * Cf, [a, 0.0])
        assert c.modal.frf([f])[0, 0] == pytest.approx(-w**2 * a * x[0], rel=1e-10)


@pytest.fixture(scope="module")
def equipment_campaign(tmp_path_factory, model):
    root = tmp_path_factory.mktemp("exc_eq")
    effect = parse_effect("underfloor_equipment=0.03", "stationary_excitation")
    truth = synth_excitation(root / "eq", seed=5, settings=SETTINGS, effect=effect, model=model)
    plain = synth_excitation(root / "plain", seed=5, settings=SETTINGS, model=model)
    return root, truth, plain


def test_equipment_campaign_lists_the_split_modes_and_reads_back(equipment_campaign, model):
    root, truth, plain = equipment_campaign
    e = truth["effect"]
    assert e["name"] == "underfloor_equipment" and e["magnitude"] == 0.03
    assert e["equipment_mass_kg"] == pytest.approx(0.03 * carbody_mass(model))
    x, y, z = e["position_m"]
    assert EQUIPMENT_X[0] <= x <= EQUIPMENT_X[1] and abs(y) == EQUIPMENT_Y and z == SENSOR_GRID[0].position[2]
    assert np.hypot(x - EXCITER.position[0], y - EXCITER.position[1]) >= 2.0
    tuned = e["tuned_mode"]
    assert 8.0 <= tuned["frequency_hz"] <= 20.0 and tuned["label"] in plain["frequencies_hz"]
    assert tuned["frequency_hz"] == pytest.approx(plain["frequencies_hz"][tuned["label"]], rel=1e-12)
    assert abs(e["mounting_frequency_hz"] / tuned["frequency_hz"] - 1) <= EQUIPMENT_DETUNING
    assert e["mounting_damping_ratio"] == 0.05
    (lo, f_lo), (hi, f_hi) = e["split_modes"].items()
    assert f_lo < tuned["frequency_hz"] < f_hi  # the two it became bracket it
    assert truth["frequencies_hz"][lo] == f_lo and truth["frequencies_hz"][hi] == f_hi
    assert e["split_hz"] == pytest.approx(f_hi - f_lo) and e["split_hz"] > 0.02 * tuned["frequency_hz"]
    assert sum(e["split_content"]) > 0.3
    # one mode more than without; same vehicle, same force (the effect draws from its own stream)
    assert truth["modes_kept"]["count"] == plain["modes_kept"]["count"] + 1
    assert truth["parameters"] == plain["parameters"]
    assert e["uncoupled_frequencies_hz"] == plain["frequencies_hz"]
    a, b = open_campaign(root / "eq").read_run("run_001"), open_campaign(root / "plain").read_run("run_001")
    np.testing.assert_array_equal(a.channels["exciter_force"], b.channels["exciter_force"])
    assert not np.allclose(a.channels["acc_f05_c"], b.channels["acc_f05_c"])
    # the file rebuilds the simulated system exactly
    f, zeta = truth_model(truth, model=model).poles()
    np.testing.assert_allclose(f, truth["modes_kept"]["frequencies_hz"], rtol=1e-12)
    np.testing.assert_allclose(zeta, truth["modes_kept"]["damping_ratios"], rtol=1e-9)
    assert all(0.005 < truth["damping_ratios"][m] < 0.06 for m in (lo, hi))


def test_h1_of_the_equipment_campaign_is_its_truth_frf(equipment_campaign, model):
    root, truth, plain = equipment_campaign
    run = open_campaign(root / "eq").read_run("run_001")
    force = run.channels["exciter_force"]
    acc = np.column_stack([run.channels[n] for n in truth["sensors"]])
    kw = {"fs": 200.0, "nperseg": 2048, "axis": 0}
    f, Gff = scipy.signal.welch(force, **kw)
    _, Gfy = scipy.signal.csd(force[:, None], acc, **kw)
    H1, H = Gfy / Gff[:, None], truth_model(truth, model=model).frf(f)
    band = (f > 6) & (f < 45)
    scale = np.abs(H[band]).max(axis=1, keepdims=True)
    assert np.median(np.abs(H1[band] - H[band]) / scale) < 0.01
    # and around the split it is not the equipment-free vehicle's
    split = list(truth["effect"]["split_modes"].values())
    near = (f > 0.95 * split[0]) & (f < 1.05 * split[1])
    without = truth_model(plain, model=model).frf(f)
    peak = np.abs(H[near]).max(axis=1, keepdims=True)
    with_eq, without_eq = (np.median(np.abs(H1[near] - h[near]) / peak) for h in (H, without))
    assert without_eq > 0.05 and without_eq > 5 * with_eq


# --------------------------------------------------------------- local panel softening
def test_softening_scales_only_that_panel_by_its_divisor(model, parameters):
    soft = soften_panel(model, "floor_middle", 4.0)
    p = [parameters[n] for n in model.names]
    dK = (soft.stiffness(p) - model.stiffness(p)).toarray()
    s = model.dof_slices["floor_middle"]
    panel = model.panel("floor_middle")
    factor = {t: parameters[q.name] for q in model.vehicle.parameters if q.kind == "panel" and q.group == "floor"
              for t in q.terms}
    expected = (1 / 4.0 - 1) * panel.stiffness(factor)
    assert np.abs(dK[s, s] - expected).max() <= 1e-9 * np.abs(expected).max()
    dK[s, s] = 0.0
    assert not dK.any()  # nothing else changes: joints, other panels, suspension
    assert (soft.M != model.M).nnz == 0 and (soft.C != model.C).nnz == 0
    with pytest.raises(ValueError, match="no panel 'floor_centre'"):
        soften_panel(model, "floor_centre", 4.0)


@pytest.mark.parametrize("panel", ["floor_front", "roof"])
def test_a_softer_panel_never_raises_a_frequency_and_lowers_the_modes_straining_it(model, panel):
    p = np.ones(len(model.names))
    f0, X0 = full_modes(model, p, 60)
    w2 = (2 * np.pi * f0) ** 2
    K_panel = (model.stiffness(p) - soften_panel(model, panel, 2.0).stiffness(p)) * 2  # this panel's stiffness
    strain = np.einsum("ij,ij->j", X0, K_panel @ X0) / w2  # share of each mode's strain energy in the panel
    # small softening: d(omega^2) / omega^2 = -(1 - 1 / divisor) x strain share (Rayleigh)
    f1 = full_modes(soften_panel(model, panel, 1.001), p, 60)[0]
    gap = np.minimum(np.diff(f0, prepend=0.0), np.diff(f0, append=np.inf)) / f0
    isolated = (gap > 0.01) & (strain > 0.02)
    assert isolated.sum() >= 5
    np.testing.assert_allclose((f1 / f0)[isolated] ** 2 - 1, -(1 - 1 / 1.001) * strain[isolated], rtol=0.02)
    # a real softening: the frequencies never rise (Courant-Fischer) and lie below the Ritz
    # values of the softened stiffness on the unsoftened modes; modes that strain the panel
    # fall by several per cent
    f5 = full_modes(soften_panel(model, panel, 5.0), p, 60)[0]
    assert np.all(f5 <= f0 * (1 + 1e-9))
    ritz = np.sqrt(scipy.linalg.eigvalsh(np.diag(w2) - (1 - 1 / 5) * (X0.T @ (K_panel @ X0)))) / (2 * np.pi)
    assert np.all(f5[:40] <= ritz[:40] * (1 + 1e-9)) and np.all(ritz <= f0 * (1 + 1e-9))
    band = (f0 > 8) & (f0 < 25)
    assert np.any(band & (strain > 0.2)) and np.max(1 - (f5 / f0)[band]) > 0.05


@pytest.fixture(scope="module")
def softening_campaign(tmp_path_factory, model):
    root = tmp_path_factory.mktemp("exc_soft") / "soft"
    effect = parse_effect("local_panel_softening=6", "stationary_excitation")
    return root, synth_excitation(root, seed=2, settings=replace(SETTINGS, duration=30.0), effect=effect, model=model)


def test_softening_campaign_names_the_panel_and_reads_back(softening_campaign, model):
    root, truth = softening_campaign
    e = truth["effect"]
    assert e["name"] == "local_panel_softening" and e["magnitude"] == 6.0 and e["unit"] == "-"
    assert e["panel"] in SOFTENING_PANELS and e["group"] in ("floor", "roof")
    assert e["panel"] == SOFTENING_PANELS[np.random.default_rng([2, 7]).integers(len(SOFTENING_PANELS))]
    assert e["panel_area_m2"] == pytest.approx(model.panel(e["panel"]).a * model.panel(e["panel"]).b)
    # Courant-Fischer on the truth's own listing: the k-th mode of the softened vehicle lies
    # below the k-th of the unsoftened one (labels number the full model's modes)
    before = e["unsoftened_frequencies_hz"]
    common = set(before) & set(truth["frequencies_hz"])
    assert len(common) >= 10 and all(truth["frequencies_hz"][m] <= before[m] * (1 + 1e-9) for m in common)
    changes = e["frequency_changes"]
    assert changes and all(c["change_pct"] <= 1e-6 and c["mac"] >= 0.9 for c in changes.values())
    assert min(c["change_pct"] for c in changes.values()) < -1.0
    assert all(c["unsoftened"] in e["unsoftened_frequencies_hz"] or c["unsoftened_hz"] > 25 for c in changes.values())
    campaign = open_campaign(root)
    assert campaign.meta.kind == "stationary_excitation"
    run = campaign.read_run("run_001")
    assert run.time.size == 30 * 200 and set(truth["sensors"]) <= set(run.channels)
    f, zeta = truth_model(truth, model=model).poles()
    np.testing.assert_allclose(f, truth["modes_kept"]["frequencies_hz"], rtol=1e-12)
    # the same vehicle parameters as the effect-free campaign of the seed
    assert truth["parameters"] == draw_truth_parameters(SETTINGS, np.random.default_rng(2))


# ------------------------------------------------- sensor on a bracket (outside the catalogue)
def test_a_bracketed_sensor_reads_the_floor_through_the_base_excited_oscillator(model, parameters):
    """The state space with the bracket in series: the bracketed channel's accelerance is
    the floor's times T = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2) (1 at low
    frequency, 1 / (2 zeta) sqrt(1 + 4 zeta^2) at w, falling as 2 zeta w / s well above),
    the other channels are untouched."""
    modal = truth_modes(parameters, settings=SETTINGS, model=model)
    br = SensorBracket("acc_f07_r", 17.0, 0.04)
    ss = br.in_series(modal.state_space())
    f = np.array([6.0, 11.3, 17.0, 24.9, 45.0])
    s = 2j * np.pi * f[:, None, None]
    H = np.linalg.solve(s * np.eye(ss.A.shape[0]) - ss.A, np.broadcast_to(ss.B, (f.size, *ss.B.shape)))
    H = (ss.C @ H)[..., 0] + ss.D[:, 0]
    Hs = modal.frf(f)
    k = ss.outputs.index("acc_f07_r")
    others = np.arange(len(SENSOR_GRID)) != k
    np.testing.assert_allclose(H[:, others], Hs[:, others], rtol=1e-8)
    np.testing.assert_allclose(H[:, k], Hs[:, k] * br.transmissibility(f), rtol=1e-8)
    assert abs(br.transmissibility(17.0)) == pytest.approx(np.sqrt(1 + 4 * 0.04**2) / (2 * 0.04))
    assert abs(br.transmissibility(0.01)) == pytest.approx(1.0, abs=1e-6)
    assert abs(br.transmissibility(17000.0)) == pytest.approx(2 * 0.04 * 17.0 / 17000.0, rel=1e-3)
    with pytest.raises(ValueError, match="no sensor 'acc_x'"):
        SensorBracket("acc_x", 17.0, 0.04)


@pytest.mark.slow
def test_bracket_campaign_changes_one_channel_by_its_transmissibility(tmp_path, model):
    """Outside the catalogue (the CLI does not offer it): the truth file names the sensor,
    away from the exciter; that channel's H1 is the truth's accelerance times T, and every
    other channel is the effect-free campaign's of the same seed."""
    with pytest.raises(InputError, match="unknown effect 'sensor_bracket'"):
        parse_effect("sensor_bracket=20", "stationary_excitation")
    effect = EffectChoice(UNCATALOGUED["sensor_bracket"], 15.0)
    settings = replace(SETTINGS, duration=120.0)
    truth = synth_excitation(tmp_path / "br", seed=4, settings=settings, effect=effect, model=model)
    plain = synth_excitation(tmp_path / "plain", seed=4, settings=settings, model=model)
    e = truth["effect"]
    assert e["frequency_hz"] == 15.0 and BRACKET_DAMPING[0] <= e["damping_ratio"] <= BRACKET_DAMPING[1]
    pos = next(s.position for s in SENSOR_GRID if s.name == e["sensor"])
    assert np.hypot(pos[0] - EXCITER.position[0], pos[1] - EXCITER.position[1]) >= BRACKET_CLEARANCE
    assert truth["frequencies_hz"] == plain["frequencies_hz"]  # the structure is unchanged
    a, b = open_campaign(tmp_path / "br").read_run("run_001"), open_campaign(tmp_path / "plain").read_run("run_001")
    for name in truth["sensors"]:
        if name != e["sensor"]:
            np.testing.assert_allclose(a.channels[name], b.channels[name], rtol=1e-6, atol=1e-9)
    kw = {"fs": 200.0, "nperseg": 1024}
    f, Gff = scipy.signal.welch(a.channels["exciter_force"], **kw)
    _, Gfy = scipy.signal.csd(a.channels["exciter_force"], a.channels[e["sensor"]], **kw)
    k = truth["sensors"].index(e["sensor"])
    H = truth_model(truth, model=model).frf(f)[:, k] * SensorBracket(e["sensor"], 15.0, e["damping_ratio"]) \
        .transmissibility(f)
    band = (f > 8) & (f < 40)
    assert np.median(np.abs(Gfy[band] / Gff[band] / H[band] - 1)) < 0.05


def test_effects_for_other_campaign_kinds_are_refused(tmp_path, model):
    choice = EffectChoice(EFFECTS["cog_offset"], 0.8)
    with pytest.raises(ValueError, match="cog_offset is for in_service"):
        synth_excitation(tmp_path / "x", seed=1, settings=SETTINGS, effect=choice, model=model)
    unknown = EffectChoice(EffectSpec("cracked_sill", ("stationary_excitation",), (1.0, 2.0), 1.5, "-", "x"), 1.5)
    with pytest.raises(NotImplementedError, match="cracked_sill"):
        synth_excitation(tmp_path / "x", seed=1, settings=SETTINGS, effect=unknown, model=model)
    assert not (tmp_path / "x").exists()
    with pytest.raises(ValueError, match="mass > 0"):
        UnderfloorEquipment(0.0, MOUNT, 12.0)
