"""The 2D car: assembled from bodies and springs, checked against closed forms and expm."""
import numpy as np
import pytest
import scipy.linalg

from calibration.models.car2d import (GRAVITY, Output, build_car, damped_modes, frequencies_by_label,
                                      state_space, static_deflection, undamped_modes)
from calibration.models.parameters import CarParameters, ParameterError
from calibration.models.simulate import ModalSimulator, simulate
from calibration.models.vehicles import INTERCITY_TRAILER, infer_seed_geometry

P = INTERCITY_TRAILER


def test_bogie_pitch_is_the_closed_form_of_a_bar_on_two_springs():
    # the secondary spring acts at the bogie centre, so bogie pitch decouples exactly
    f = frequencies_by_label(undamped_modes(build_car(P)))["bogie_pitch"]
    assert f == pytest.approx(np.sqrt(2 * P.k_p * P.L_b**2 / P.J_b) / (2 * np.pi), rel=1e-12)


def test_in_phase_bounce_modes_solve_the_two_mass_closed_form():
    # carbody on both secondaries, both bogies moving together on four primaries
    M = np.diag([P.m_v, 2 * P.m_b])
    K = np.array([[2 * P.k_s, -2 * P.k_s], [-2 * P.k_s, 2 * P.k_s + 4 * P.k_p]])
    f_exact = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)) / (2 * np.pi)
    modes = undamped_modes(build_car(P))
    assert [m.frequency_hz for m in modes if m.label == "carbody_bounce"][0] == pytest.approx(f_exact[0], rel=1e-12)
    bogie = [m.frequency_hz for m in modes if m.label == "bogie_bounce"]
    assert min(abs(b / f_exact[1] - 1) for b in bogie) < 1e-12


def test_carbody_pitch_closed_form_with_series_springs():
    # antisymmetric motion: carbody pitch against bogies bouncing in antiphase
    M = np.diag([P.J_v, 2 * P.m_b])
    L = P.L_v
    K = np.array([[2 * P.k_s * L**2, -2 * P.k_s * L], [-2 * P.k_s * L, 2 * P.k_s + 4 * P.k_p]])
    f_exact = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True)) / (2 * np.pi)
    f = frequencies_by_label(undamped_modes(build_car(P)))["carbody_pitch"]
    assert f == pytest.approx(f_exact[0], rel=1e-12)


def test_static_deflection_under_gravity_matches_hand_calculation():
    asm = build_car(P)
    q = static_deflection(asm)
    bogie = -(P.m_v / 2 + P.m_b) * GRAVITY / (2 * P.k_p)  # both primaries of a bogie carry it
    carbody = bogie - P.m_v * GRAVITY / 2 / P.k_s
    assert q[asm.dof("bogie1_z")] == pytest.approx(bogie, rel=1e-12)
    assert q[asm.dof("carbody_z")] == pytest.approx(carbody, rel=1e-12)
    assert q[asm.dof("carbody_pitch")] == pytest.approx(0.0, abs=1e-15)


def test_free_wheelsets_on_a_stiff_contact_approach_the_rail_model():
    f6 = frequencies_by_label(undamped_modes(build_car(P)))
    f10 = frequencies_by_label(undamped_modes(build_car(P, wheelsets="free", k_contact=1e12)))
    for label in ("carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch"):
        assert f10[label] == pytest.approx(f6[label], rel=1e-4)
    assert "axle_bounce" in f10


def test_a_wheelset_on_a_flexible_track_follows_the_level_through_the_tracks_and_its_own_dynamic_stiffness():
    """The rail's level is the irregularity at the wheel-rail contact, the track mass under it:
    z_w / r = Z_t / (Z_t + Z_w), Z_t = k + i w c - w^2 m_t the track's dynamic stiffness, Z_w
    the wheelset's own on the car (the seed's car with free wheelsets and no contact, the
    other wheelsets on their tracks). The level goes through at low frequency and dips at
    the track's own frequency."""
    from calibration.models.car2d import CarExtras, dynamic_stiffness, frequency_response, wheel_level_gain

    k, zeta, m_t = 25e6, 0.3, 900.0
    c = 2 * zeta * np.sqrt(k * m_t)
    f = np.array([2.0, 8.0, 20.0, np.sqrt(k / m_t) / (2 * np.pi), 45.0, 60.0])
    w = 2 * np.pi * f
    ex = CarExtras(track_stiffness=k, track_damping_ratio=zeta, track_mass=m_t)
    H = frequency_response(build_car(P, extras=ex), [Output("w1", "displacement", "wheelset1", P.L_v + P.L_b)],
                           f)[:, 0, 0] + wheel_level_gain(P, ex)  # the wheelset is its coordinate plus this x r
    free = build_car(P, wheelsets="free", k_contact=0.0)
    D, _ = dynamic_stiffness(free.K, free.M, free.C, free.B_k, free.B_c, w)
    Z_t = k + 1j * w * c - w * w * m_t
    j = free.dof("wheelset1_z")
    others = [free.dof(f"wheelset{i}_z") for i in (2, 3, 4)]
    rest = [i for i in range(len(free.dofs)) if i != j]
    expected = []
    for n in range(len(f)):
        Dn = D[n].copy()
        Dn[others, others] += Z_t[n]
        Z_w = Dn[j, j] - Dn[j, rest] @ np.linalg.solve(Dn[np.ix_(rest, rest)], Dn[rest, j])
        expected.append(Z_t[n] / (Z_t[n] + Z_w))
    assert H == pytest.approx(np.array(expected), rel=1e-9)
    assert abs(H[0]) == pytest.approx(1.0, abs=0.05)
    assert abs(H[3]) < 0.5 * min(abs(H[2]), abs(H[0]))  # the dip at the track's own frequency


def test_a_wheelsets_dynamic_stiffness_is_its_mass_at_high_frequency_and_the_car_above_it_at_low():
    """Z_w -> -w^2 m_w well above the primary suspension's frequencies (the wheelset alone);
    at low frequency the car above, free to move with this wheelset's contact gone, shows as
    a mass (negative real part); its imaginary part is the suspension's damping (>= 0)."""
    from calibration.models.car2d import wheelset_dynamic_stiffness

    f = np.array([0.3, 2.0, 10.0, 200.0, 2000.0])
    Z = wheelset_dynamic_stiffness(P, f, 1)
    w = 2 * np.pi * f
    assert Z[-1].real == pytest.approx(-w[-1] ** 2 * P.m_w, rel=2e-3)
    assert np.all(Z.imag >= 0)
    assert Z[0].real < 0  # a free car: its mass above the suspension shows at any frequency
    assert wheelset_dynamic_stiffness(P, f, 2) == pytest.approx(Z, rel=1e-6)  # a symmetric bogie


def test_modes_are_labelled_by_their_shape():
    labels = [m.label for m in undamped_modes(build_car(P))]
    assert sorted(set(labels)) == ["bogie_bounce", "bogie_pitch", "carbody_bounce", "carbody_pitch"]
    assert labels.count("bogie_bounce") == 2 and labels.count("bogie_pitch") == 2


def test_damped_modes_match_the_state_matrix_eigenvalues():
    asm = build_car(P)
    lam = scipy.linalg.eigvals(state_space(asm, []).A)
    wn = np.sort(np.abs(lam[lam.imag > 0])) / (2 * np.pi)
    ours = np.sort([m.frequency_hz for m in damped_modes(asm)])
    np.testing.assert_allclose(ours, wn, rtol=1e-10)


def _expm_reference(ss, w, dt):
    """Dense reference: exact first-order-hold stepping with the Van Loan matrix exponential."""
    n, m = ss.B.shape
    big = np.zeros((n + 2 * m, n + 2 * m))
    big[:n, :n] = ss.A * dt
    big[:n, n:n + m] = ss.B * dt
    big[n:n + m, n + m:] = np.eye(m)
    E = scipy.linalg.expm(big)
    Phi, G1, G2 = E[:n, :n], E[:n, n:n + m], E[:n, n + m:]
    # x[k+1] = Phi x + G1 w[k] + G2 (w[k+1] - w[k])
    x = np.zeros(n)
    ys = [ss.C @ x + ss.D @ w[0]]
    for k in range(len(w) - 1):
        x = Phi @ x + G1 @ w[k] + G2 @ (w[k + 1] - w[k])
        ys.append(ss.C @ x + ss.D @ w[k + 1])
    return np.array(ys)


def test_time_response_agrees_with_dense_expm_to_1e8():
    asm = build_car(P)
    outputs = [Output("acc", "acceleration", "bogie1", P.L_v + 0.45), Output("rate", "pitch_rate", "bogie1"),
               Output("z", "displacement", "carbody", 0.0), Output("v", "velocity", "carbody", -5.0)]
    ss = state_space(asm, outputs)
    rng = np.random.default_rng(3)
    dt = 0.002
    u = np.cumsum(rng.normal(0, 1e-4, (1500, 4)), axis=0)
    w = np.hstack([u, np.gradient(u, dt, axis=0)])
    y = simulate(ss, w, dt)
    ref = _expm_reference(ss, w, dt)
    rel = np.abs(y - ref).max(axis=0) / np.abs(ref).max(axis=0)  # per output, relative to its range
    assert rel.max() < 1e-8, rel


def test_streaming_in_chunks_equals_one_call():
    ss = state_space(build_car(P), [Output("acc", "acceleration", "carbody", 3.0)])
    rng = np.random.default_rng(4)
    w = rng.normal(0, 1e-3, (1000, 8))
    whole = simulate(ss, w, 0.002)
    sim = ModalSimulator(ss, 0.002)
    parts = np.vstack([sim.step_chunk(w[a:a + 137]) for a in range(0, 1000, 137)])
    np.testing.assert_allclose(parts, whole, rtol=1e-10, atol=1e-14)


def test_static_start_has_no_transient_on_a_constant_rail():
    ss = state_space(build_car(P), [Output("acc", "acceleration", "bogie1", P.L_v)])
    w = np.hstack([np.full((500, 4), 3e-3), np.zeros((500, 4))])
    y = ModalSimulator(ss, 0.002, x0="static").step_chunk(w)
    assert np.abs(y).max() < 1e-9


def test_parameters_refuse_non_physical_values_and_unknown_names():
    with pytest.raises(ParameterError, match=r"m_v .*must be > 0"):
        P.replace(m_v=-1.0)
    with pytest.raises(ParameterError, match="not finite"):
        P.replace(k_s=float("nan"))
    with pytest.raises(ParameterError, match="unknown parameter name.*k_x"):
        CarParameters.from_mapping({"k_x": 1.0}, base=P)
    with pytest.raises(ParameterError, match="L_b .* must be smaller"):
        P.replace(L_b=9.0)


def test_seed_geometry_is_inferred_from_tables_8_and_9():
    L_v, L_b, rms = infer_seed_geometry()
    assert (round(L_v, 2), round(L_b, 2)) == (P.L_v, P.L_b)
    assert rms < 0.002  # what remains is Table 8's rounding to 0.01 Hz (1.07 or 1.08 for the same set)


def test_manchester_benchmark_reproduces_the_seed_table_2_row(tmp_path, capsys):
    import json

    from railcal.cli import main
    from calibration.models.vehicles import SEED_TABLE2_MANCHESTER

    out = tmp_path / "modes.json"
    assert main(["modes", "--model", "car2d", "--vehicle", "manchester", "--out", str(out)]) == 0
    capsys.readouterr()
    modes = json.loads(out.read_text())["modes"]
    for label, published in SEED_TABLE2_MANCHESTER.items():
        f = np.mean([m["frequency_hz"] for m in modes if m["family"] == label])  # both bogies' modes
        assert f == pytest.approx(published, rel=0.02), label


def test_empty_chunk_streams_nothing():
    sim = ModalSimulator(state_space(build_car(P), [Output("a", "acceleration", "carbody", 0.0)]), 0.002)
    assert sim.step_chunk(np.zeros((0, 8))).shape == (0, 1)


def test_modes_command_pairs_each_bogie_mode_with_its_own_damping(tmp_path, capsys):
    import json

    from railcal.cli import main

    out = tmp_path / "m.json"
    assert main(["modes", "--out", str(out)]) == 0
    capsys.readouterr()
    bounce = [m for m in json.loads(out.read_text())["modes"] if m["family"] == "bogie_bounce"]
    assert len(bounce) == 2 and bounce[0]["damping_ratio"] != bounce[1]["damping_ratio"]
    assert len({m["label"] for m in bounce}) == 2  # one label each
