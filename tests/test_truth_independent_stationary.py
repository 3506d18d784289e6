"""The independent truth's stationary excitation test (issue 31): a shell finite element
carbody checked against closed forms, its modal model against direct solves, exudyn's
integration against the exact steady state, and a short campaign written end to end."""
from __future__ import annotations

import json

import numpy as np
import pytest

from calibration.data.campaign import open_campaign
from calibration.truth.independent.hidden import STATIONARY_RANGES, parse_hidden
from calibration.truth.independent.shell import Mesher, Section
from calibration.truth.independent.stationary import (StationarySettings, integrate, sensor_chain,
                                                     synth_excitation_independent)
from calibration.truth.independent.stationary_model import LinearSystem, carbody_modes

E, NU, RHO = 70e9, 0.3, 2700.0


def _isotropic(t: float, bending_scale: float = 1.0, areal=None) -> Section:
    f = E / (1 - NU ** 2)
    iso = np.array([[1, NU, 0], [NU, 1, 0], [0, 0, (1 - NU) / 2]])
    return Section(f * t * iso, bending_scale * f * t ** 3 / 12 * iso, 5 / 6 * E / (2 * (1 + NU)) * t,
                   RHO * t if areal is None else areal)


def test_a_simply_supported_plate_has_kirchhoffs_frequencies():
    a, b, t, nx, ny = 2.0, 1.0, 0.01, 20, 10
    m = Mesher()
    sec = _isotropic(t)
    for i in range(nx):
        for j in range(ny):
            m.rectangle((i * a / nx, j * b / ny, 0), (1, 0, 0), (0, 1, 0), a / nx, b / ny, sec)
    sm = m.model()
    edge = (np.isclose(sm.nodes[:, 0], 0) | np.isclose(sm.nodes[:, 0], a) | np.isclose(sm.nodes[:, 1], 0)
            | np.isclose(sm.nodes[:, 1], b))
    held = [6 * k + d for k in range(len(sm.nodes)) for d in (0, 1, 5)] + [6 * k + 2 for k in np.flatnonzero(edge)]
    free = np.setdiff1d(np.arange(6 * len(sm.nodes)), held)
    import scipy.sparse.linalg
    lam = np.sort(scipy.sparse.linalg.eigsh(sm.K[free][:, free], 5, sm.M()[free][:, free], sigma=0, which="LM")[0])
    D = E * t ** 3 / (12 * (1 - NU ** 2))
    exact = sorted(np.pi / 2 * np.sqrt(D / (RHO * t)) * ((p / a) ** 2 + (q / b) ** 2)
                   for p in range(1, 5) for q in range(1, 4))[:5]
    assert np.sqrt(lam) / (2 * np.pi) == pytest.approx(exact, rel=0.015)


def _tube(length=24.0, w=0.5, h=0.5, n=(48, 2, 2), t=0.01):
    """A closed square tube with end diaphragms (massless), free in space."""
    m = Mesher()
    sec, end = _isotropic(t), _isotropic(t, areal=1e-9)
    dx, dy, dz = length / n[0], w / n[1], h / n[2]
    for i in range(n[0]):
        x = -length / 2 + i * dx
        for j in range(n[1]):
            for z in (0.0, h):
                m.rectangle((x, -w / 2 + j * dy, z), (1, 0, 0), (0, 1, 0), dx, dy, sec)
        for k in range(n[2]):
            for y in (-w / 2, w / 2):
                m.rectangle((x, y, k * dz), (1, 0, 0), (0, 0, 1), dx, dz, sec)
    for x in (-length / 2, length / 2):
        for j in range(n[1]):
            for k in range(n[2]):
                m.rectangle((x, -w / 2 + j * dy, k * dz), (0, 1, 0), (0, 0, 1), dy, dz, end)
    return m.model(), (length, w, h, t)


def test_a_free_slender_tube_moves_rigidly_for_free_and_bends_like_a_beam():
    sm, (length, w, h, t) = _tube()
    f, _ = sm.modes(10)
    assert np.all(f[:6] < 1e-3 * f[6])  # six rigid-body modes: a rigid rotation strains nothing
    inertia = 2 * t * h ** 3 / 12 + 2 * w * t * (h / 2) ** 2
    mu = RHO * t * 2 * (w + h)
    euler_bernoulli = 4.7300 ** 2 * np.sqrt(E * inertia / (mu * length ** 4)) / (2 * np.pi)
    assert f[6] == pytest.approx(euler_bernoulli, rel=0.02)  # a square tube: vertical and lateral alike
    assert f[7] == pytest.approx(euler_bernoulli, rel=0.02)


def test_the_attachment_mode_makes_the_drive_points_static_flexibility_exact():
    """Modes up to a low cut-off plus the attachment mode give the drive point's elastic
    static flexibility of a direct solve: the free tube under a unit force balanced by its
    own inertia (inertia relief), held statically determinate, its rigid motion removed."""
    import scipy.sparse.linalg
    sm, _ = _tube(length=12.0, n=(24, 2, 2))
    node = sm.node_at((3.0, 0.0, 0.5))
    modes = carbody_modes(sm, 60.0, node)
    f_all, phi = sm.modes(6)  # the rigid-body modes
    M = sm.M()
    load = np.zeros(phi.shape[0])
    load[6 * node + 2] = 1.0
    relieved = load - M @ (phi @ (phi.T @ load))
    corners = [sm.node_at(p) for p in ((-6.0, -0.25, 0.0), (6.0, -0.25, 0.0), (-6.0, 0.25, 0.0))]
    held = [6 * corners[0], 6 * corners[0] + 1, 6 * corners[0] + 2, 6 * corners[1] + 1, 6 * corners[1] + 2,
            6 * corners[2] + 2]
    free = np.setdiff1d(np.arange(phi.shape[0]), held)
    u = np.zeros(phi.shape[0])
    u[free] = scipy.sparse.linalg.spsolve(sm.K[free][:, free].tocsc(), relieved[free])
    u -= phi @ (phi.T @ (M @ u))
    exact = u[6 * node + 2]
    elastic = np.array(modes.kind) != "rigid"
    w2 = (2 * np.pi * modes.frequency_hz[elastic]) ** 2
    z = modes.translations[node, 2, elastic]
    assert np.sum(z * z / w2) == pytest.approx(exact, rel=1e-6)
    assert abs(np.sum(z[:-1] * z[:-1] / w2[:-1]) / exact - 1) > 0.02  # the kept modes alone miss a share


def test_exudyns_integration_reaches_the_exact_steady_state():
    """Three masses on springs and dampers driven by a 9 Hz sine: exudyn's steady-state
    amplitude and phase against the exact frequency response."""
    M = np.diag([100.0, 50.0, 20.0])
    K = np.array([[3e5, -1e5, 0], [-1e5, 2e5, -1e5], [0, -1e5, 1e5]])
    C = 1e-3 * K + 2.0 * M  # every mode damped 5 % or more: the start transient is gone after 6 s
    b = np.array([0.0, 0.0, 1.0])
    S = np.eye(3)
    system = LinearSystem(M, C, K, b, S, ("a", "b", "c"), None, {})
    rate, f0, T = 1000.0, 9.0, 8.0
    t = np.arange(0, T + 1 / rate, 1 / rate)
    acc = integrate(system, np.sin(2 * np.pi * f0 * t), rate)
    late = t > T - 2.0
    basis = np.column_stack([np.sin(2 * np.pi * f0 * t[late]), np.cos(2 * np.pi * f0 * t[late])])
    coef, *_ = np.linalg.lstsq(basis, acc[late], rcond=None)
    simulated = coef[0] + 1j * coef[1]  # response to sin: Im of H e^{i w t} -> (Re H, Im H)
    exact = system.frf(np.array([f0]))[0]
    assert np.abs(simulated) == pytest.approx(np.abs(exact), rel=0.01)
    assert np.max(np.abs(np.angle(simulated / exact))) < 0.01  # [rad]


def test_the_stationary_effects_have_their_own_names_and_ranges():
    (e,) = parse_hidden("underfloor_equipment=0.02", STATIONARY_RANGES)
    assert e.catalogued and e.magnitude == 0.02
    (b,) = parse_hidden("sensor_bracket", STATIONARY_RANGES)
    assert not b.catalogued
    with pytest.raises(Exception, match="outside its range"):
        parse_hidden("local_panel_softening=20", STATIONARY_RANGES)


def test_a_force_calibration_error_changes_the_load_cell_alone():
    """The hidden load-cell error multiplies the force channel's own drawn gain and leaves
    every other draw as the clean campaign's of the same seed."""
    (e,) = parse_hidden("force_calibration=0.94", STATIONARY_RANGES)
    assert e.catalogued
    names, s = ["acc_a", "acc_b"], StationarySettings()
    g0, o0 = sensor_chain(names, "force", s, np.random.default_rng(4))
    g1, o1 = sensor_chain(names, "force", s, np.random.default_rng(4), e)
    assert o1 == o0 and all(g1[n] == g0[n] for n in names)
    assert g1["force"] == pytest.approx(0.94 * g0["force"], rel=1e-15)
    assert abs(g0["force"] - 1) <= s.force_gain_error


@pytest.mark.slow
def test_a_short_campaign_is_written_with_its_truth(tmp_path):
    root = tmp_path / "shaker"
    truth = synth_excitation_independent(root, seed=3, settings=StationarySettings(runs=1, duration=20.0),
                                         effect=parse_hidden("underfloor_equipment=0.03", STATIONARY_RANGES),
                                         fmt="parquet")
    c = open_campaign(root)
    assert c.meta.kind == "stationary_excitation" and len(c.meta.sensors) == 28
    assert c.meta.priors == {}  # what a box model's factors may be is not the test's to say
    run = c.read_run(c.run_ids[0])
    assert run.time.size == 4000 and np.isfinite(run.channels["acc_f05_c"]).all()
    assert 3.0 <= min(truth["frequencies_hz"].values()) and max(truth["frequencies_hz"].values()) <= 25.0
    assert truth["effect"]["name"] == "underfloor_equipment"
    assert truth["effect"]["frequency_hz"] == pytest.approx(truth["effect"]["tuned_mode_hz"], rel=0.041)
    assert json.loads((tmp_path / "shaker.truth.json").read_text())["seed"] == 3
