"""The extended box-type carbody model: plates, joints and the assembled vehicle agree
with closed forms and with the physics they encode."""
from dataclasses import replace

import numpy as np
import pytest
import scipy.linalg

from calibration.models.box import assemble, free_carbody, shinkansen_vehicle
from calibration.models.box.assembly import BoxVehicle, Joint, StiffnessParameter
from calibration.models.box.panel import Panel

STRIP = dict(A11=3e8, A22=2e8, A12=0.0, A66=1e8, D11=2e5, D22=1e5, D12=0.0, D66=5e4)


def _frequencies(model, p=None, n=None):
    p = np.ones(len(model.names)) if p is None else p
    K, M = model.stiffness(p).toarray(), model.M.toarray()
    w2 = scipy.linalg.eigh(K, M, eigvals_only=True, subset_by_index=None if n is None else [0, n - 1])
    return np.sign(w2) * np.sqrt(np.abs(w2)) / (2 * np.pi)


def _strip(name="strip", centre=(0.0, 0.0, 0.0), a=6.0, order=(12, 2)):
    return Panel(name, "plate", centre, (1, 0, 0), (0, 1, 0), a, 0.5, order, 40.0, STRIP)


def _alone(*panels, joints=(), parameters=()):
    return assemble(BoxVehicle(tuple(panels), tuple(joints), (), (), (), tuple(parameters)))


def test_a_free_panel_has_exactly_its_six_rigid_motions_at_zero_frequency():
    f = _frequencies(_alone(_strip()), n=8)
    assert np.all(np.abs(f[:6]) < 1e-3) and f[6] > 1.0


def test_free_free_strip_extension_and_bending_match_the_bar_and_beam_closed_forms():
    a, rho_h = 6.0, 40.0
    f = _frequencies(_alone(_strip(a=a)))
    bar = np.sqrt(STRIP["A11"] / rho_h) / (2 * a)  # first extensional mode of a free-free bar
    beam = 4.730040745**2 / (2 * np.pi * a**2) * np.sqrt(STRIP["D11"] / rho_h)  # free-free Euler beam
    assert np.min(np.abs(f - bar)) / bar < 1e-6
    assert np.min(np.abs(f - beam)) / beam < 1e-6


def _halves(k_t, k_r):
    left = _strip("left", (-1.5, 0, 0), a=3.0, order=(8, 2))
    right = _strip("right", (1.5, 0, 0), a=3.0, order=(8, 2))
    joint = Joint("middle", "left", "right", (0, -0.25, 0), (0, 0.25, 0), k_t, k_r)
    return _alone(left, right, joints=[joint])


def test_two_halves_joined_stiffly_behave_as_one_panel():
    whole = _frequencies(_alone(_strip(a=6.0, order=(16, 2))), n=12)
    joined = _frequencies(_halves(k_t=1e12, k_r=1e10), n=12)
    np.testing.assert_allclose(joined[6:], whole[6:], rtol=2e-3)


def test_the_rotational_spring_alone_sets_the_bending_coupling_across_a_joint():
    # k_r = 0 leaves a hinge: a seventh zero-frequency motion; k_t alone cannot stop it
    hinge = _frequencies(_halves(k_t=1e12, k_r=0.0), n=8)
    assert np.sum(np.abs(hinge) < 1e-2) == 7
    stiff = _frequencies(_halves(k_t=1e12, k_r=1e10), n=8)
    assert np.sum(np.abs(stiff) < 1e-2) == 6


@pytest.fixture(scope="module")
def vehicle():
    return shinkansen_vehicle()


@pytest.fixture(scope="module")
def carbody(vehicle):
    return assemble(free_carbody(replace(vehicle, panels=tuple(
        replace(p, order=(max(p.order[0] // 2, 3), max(p.order[1] // 2, 3))) for p in vehicle.panels))))


def test_the_full_model_has_between_1000_and_3500_degrees_of_freedom(vehicle):
    n = sum(p.n_dof for p in vehicle.panels) + 6 * len(vehicle.bodies)
    assert 1000 <= n <= 3500


def test_the_free_carbody_has_six_rigid_modes_no_joint_strains_under_rigid_motion(carbody):
    f = _frequencies(carbody, n=8)
    assert np.all(np.abs(f[:6]) < 1e-3) and f[6] > 1.0


def test_the_mass_matrix_carries_the_panel_and_iron_block_masses(carbody):
    q = np.zeros(carbody.n_dof)
    for pn in carbody.vehicle.panels:  # uniform vertical translation: p0(xi) p0(eta) = 1/2
        s = carbody.dof_slices[pn.name]
        local = pn.axes.T @ np.array([0.0, 0.0, 1.0])
        for field in range(3):
            q[s.start + field * pn.n_terms] = 2 * local[field]
    expected = sum(p.mass for p in carbody.vehicle.panels) + sum(m.mass for m in carbody.vehicle.masses)
    assert q @ carbody.M @ q == pytest.approx(expected, rel=1e-12)
    assert np.allclose(carbody.stiffness(np.ones(len(carbody.names))) @ q, 0, atol=1e-6 * expected)


def test_scaling_a_parameter_equals_reassembling_with_scaled_rigidities(carbody):
    i = carbody.names.index("roof_bending")
    p = np.ones(len(carbody.names))
    p[i] = 2.0
    doubled = replace(carbody.vehicle, panels=tuple(
        replace(pn, rigidity={k: v * (2.0 if k.startswith("D") else 1.0) for k, v in pn.rigidity.items()})
        if pn.group == "roof" else pn for pn in carbody.vehicle.panels))
    np.testing.assert_allclose(_frequencies(carbody, p, n=20), _frequencies(assemble(doubled), n=20),
                               rtol=1e-9, atol=1e-6)


def test_parameters_must_not_scale_the_same_rigidity_twice():
    twice = (StiffnessParameter("a", "panel", "plate", ("D11",)), StiffnessParameter("b", "panel", "plate", ("D11",)))
    with pytest.raises(ValueError, match="several parameters"):
        _alone(_strip(), parameters=twice)


def test_the_rigid_carbody_bounces_on_its_suspension_as_the_two_mass_closed_form(vehicle):
    # every searched rigidity and joint spring x 1000: the carbody's vertical mode on the air
    # springs in series with the bogie frames on the axle springs
    from calibration.models.box.shinkansen import BOGIE, SUSPENSION
    coarse = replace(vehicle, panels=tuple(replace(p, order=(3, 3)) for p in vehicle.panels))
    model = assemble(coarse)
    f = _frequencies(model, np.full(len(model.names), 1000.0), n=12)
    m_c = sum(pn.mass for pn in coarse.panels) + sum(m.mass for m in coarse.masses)
    k_s = 4 * SUSPENSION["air_spring"]["k"][2]
    k_p = 8 * SUSPENSION["axle_box"]["k"][2]
    Mm = np.diag([m_c, 2 * BOGIE["mass"]])
    Kk = np.array([[k_s, -k_s], [-k_s, k_s + k_p]])
    bounce = np.sqrt(scipy.linalg.eigh(Kk, Mm, eigvals_only=True)[0]) / (2 * np.pi)
    assert np.min(np.abs(f - bounce)) / bounce < 0.01


def test_a_reduced_basis_reproduces_the_full_model_near_where_it_was_built(vehicle):
    from calibration.models.box.parametric_basis import ReducedFamily, full_modes
    coarse = assemble(replace(vehicle, panels=tuple(
        replace(p, order=(max(p.order[0] // 2, 3), max(p.order[1] // 2, 3))) for p in vehicle.panels)))
    p0 = np.ones(len(coarse.names))
    family = ReducedFamily.build(coarse, p0[None], modes_per_sample=20, size=50,
                                 derivatives=12)
    assert family.size == 50 and np.allclose(family.V.T @ (coarse.M @ family.V), np.eye(50), atol=1e-9)
    f0, _ = family.modes(p0[None], 20)
    np.testing.assert_allclose(f0[0], full_modes(coarse, p0, 20)[0], rtol=1e-8)  # its own modes exactly
    p = p0 * np.exp(np.random.default_rng(2).uniform(-0.05, 0.05, p0.size))
    # the bound is checked against the dense solve: shift-invert Lanczos (full_modes) has the
    # two bogies' near-degenerate pair at 10.27 Hz only to about 5e-10, of either sign
    # depending on round-off (-4.2e-10 and +4.9e-10 for matrices equal to 6e-16)
    full = _frequencies(coarse, p, n=12)
    reduced = family.modes(p[None], 12)[0][0]
    assert np.all(reduced >= full * (1 - 1e-10))  # Rayleigh-Ritz: upper bounds
    assert np.max(reduced / full - 1) < 5e-4
    assert np.max(family.residuals(p, 12)) < 0.05


# ---------------------------------------------------------------- assembly on quadrature grids
def test_a_patch_mean_from_one_grid_evaluation_equals_a_finer_point_by_point_quadrature():
    # the patch mean evaluates the basis once on the whole Gauss grid; the basis being
    # polynomial, any finer rule gives the same mean (here 40 x 40 points, one at a time)
    from calibration.models.box.assembly import local_operator
    strip = _strip(order=(12, 4))
    model = _alone(strip)
    centre, patch = np.array([1.3, 0.05, 0.0]), (0.8, 0.3)
    _, G = local_operator(model, "strip", centre, patch=patch)
    x, w = np.polynomial.legendre.leggauss(40)
    fine = sum(wi * wj / 4 * strip.displacement(centre + [xi * patch[0] / 2, xj * patch[1] / 2, 0.0])
               for xi, wi in zip(x, w) for xj, wj in zip(x, w))
    np.testing.assert_allclose(G, fine, rtol=0, atol=1e-13 * np.abs(fine).max())
    # and the grid's operators are the single points' operators, bit for bit
    pts = centre + np.column_stack([x * patch[0] / 2, x * patch[1] / 2, 0 * x])
    for many, one in ((strip.displacements(pts), strip.displacement), (strip.rotations(pts), strip.rotation)):
        assert all(np.array_equal(many[k], one(q)) for k, q in enumerate(pts))


def _joint_halves(k_t=2.0e9, k_r=3.0e5):
    """Two strips joined along x = 0 (0.5 m of edge), each joint spring its own parameter
    (so K_units holds each spring's matrix alone, for k = 1)."""
    left = _strip("left", (-1.5, 0, 0), a=3.0, order=(8, 3))
    right = _strip("right", (1.5, 0, 0), a=3.0, order=(8, 3))
    joint = Joint("middle", "left", "right", (0, -0.25, 0), (0, 0.25, 0), k_t, k_r)
    parameters = (StiffnessParameter("kt", "joint", "middle", ("k_t",)),
                  StiffnessParameter("kr", "joint", "middle", ("k_r",)))
    return _alone(left, right, joints=[joint], parameters=parameters)


def test_joint_springs_store_their_closed_form_energies():
    # 1/2 k_t |d|^2 and 1/2 k_r (t . omega)^2 per metre of edge, over L = 0.5 m: a unit
    # relative translation stores k_t L / 2, a relative rotation theta about the edge
    # (y) with the edge points held together k_r theta^2 L / 2
    model = _joint_halves()
    left = model.panel("left")
    s, m = model.dof_slices["left"], left.n_terms
    L, a, theta = 0.5, left.a, 1e-3
    Kt, Kr = model.K_units["kt"] / 2.0e9, model.K_units["kr"] / 3.0e5
    q = np.zeros(model.n_dof)
    q[s.start + 2 * m] = 2.0  # w = 1 m on the left strip: p0(xi) p0(eta) = 1/2
    assert q @ Kt @ q == pytest.approx(L, rel=1e-12) and abs(q @ Kr @ q) < 1e-20
    # w = -theta (x_local - a/2): zero at the edge (x_local = a/2), slope -theta, omega_y = theta
    q = np.zeros(model.n_dof)
    q[s.start + 2 * m] = theta * a  # the constant theta a / 2, as 2 x coefficient
    q[s.start + 2 * m + (left.order[1] + 1)] = -theta * a / np.sqrt(3)  # -theta (a/2) xi = -theta a/sqrt(3) p1 p0
    assert q @ Kr @ q == pytest.approx(theta**2 * L, rel=1e-12)
    assert abs(q @ Kt @ q) < 1e-12 * theta**2 * L


def test_joint_matrices_are_the_point_by_point_gauss_sums_to_the_bit():
    # each joint's matrix comes from all its Gauss points at once (each basis evaluated once
    # per edge); it is the point-by-point sum of w_g D_g^T D_g the energies are written in,
    # bit for bit (panels along the axes: one product per entry and point, summed in order)
    model = _joint_halves()
    left, right = model.panel("left"), model.panel("right")
    idx = np.r_[np.arange(model.dof_slices["left"].start, model.dof_slices["left"].stop),
                np.arange(model.dof_slices["right"].start, model.dof_slices["right"].stop)]
    x, w = np.polynomial.legendre.leggauss(max(left.order + right.order) + 2)
    Kt, Kr = 0.0, 0.0
    for xg, wg in zip(x, w):
        q, weight = np.array([0.0, -0.25, 0.0]) + (xg + 1) / 2 * np.array([0.0, 0.5, 0.0]), wg * 0.5 / 2
        D = np.hstack([left.displacement(q), -right.displacement(q)])
        r = np.array([0.0, 1.0, 0.0]) @ np.hstack([left.rotation(q), -right.rotation(q)])
        Kt, Kr = Kt + weight * (D.T @ D), Kr + weight * np.outer(r, r)
    for name, k, ref in (("kt", 2.0e9, Kt), ("kr", 3.0e5, Kr)):
        A = model.K_units[name].toarray()[np.ix_(idx, idx)]
        assert np.array_equal(A, k * ref) and np.array_equal(A, A.T)


def test_the_assembled_matrices_store_no_zeros(carbody):
    for A in (carbody.M, carbody.K0, *carbody.K_units.values()):
        assert np.all(A.data != 0)


# ---------------------------------------------------------------- the carbody's modal basis
def test_the_inertia_count_is_the_number_of_modes_below_the_cut_off(carbody):
    from calibration.signals.modal import count_modes_below
    f = _frequencies(carbody, n=60)
    for cutoff in (5.0, 25.0, 0.5 * (f[40] + f[41])):
        assert count_modes_below(carbody.stiffness(np.ones(len(carbody.names))), carbody.M, cutoff) == \
            np.count_nonzero(f < cutoff)


def test_the_carbody_basis_is_one_eigen_solve_of_the_dense_modes_and_the_static_shapes(carbody, monkeypatch):
    import scipy.sparse.linalg

    from calibration.models.box import vehicle_reduction
    calls = {"eigsh": 0}
    eigsh = scipy.sparse.linalg.eigsh

    def counted(*args, **kwargs):
        calls["eigsh"] += 1
        return eigsh(*args, **kwargs)

    monkeypatch.setattr(vehicle_reduction.scipy.sparse.linalg, "eigsh", counted)
    p = np.ones(len(carbody.names))
    f = _frequencies(carbody, n=80)
    cutoff = 0.5 * (f[55] + f[56])  # 56 modes below, more than the 40 once asked for first
    loads = np.random.default_rng(3).standard_normal((carbody.n_dof, 4))
    V, omega, n_modes = vehicle_reduction.carbody_basis(carbody, p, cutoff, loads)
    assert calls["eigsh"] == 1 and n_modes == 56
    np.testing.assert_allclose(omega[6:n_modes] / (2 * np.pi), f[6:56], rtol=1e-9)
    K, M = carbody.stiffness(p), carbody.M
    np.testing.assert_allclose(V.T @ (M @ V), np.eye(V.shape[1]), atol=1e-9)
    KV = V.T @ (K @ V)
    assert np.abs(KV - np.diag(omega**2)).max() < 1e-8 * omega.max() ** 2
    # the static shapes of the loads lie in the span of the basis (static correction)
    sigma = -(2 * np.pi * 0.5) ** 2
    X = scipy.sparse.linalg.spsolve((K - sigma * M).tocsc(), loads)
    fit = V @ (V.T @ (M @ X))
    assert np.linalg.norm(X - fit) < 1e-9 * np.linalg.norm(X)


def test_end_zone_rigidity_holds_the_energy_share_of_its_strips():
    """A uniform in-plane shear (u = y) stores energy evenly over the panel: the two end
    strips of length z hold 2 z / a of it, exactly (the 1D integrals are split, not
    approximated)."""
    strip = _strip(a=6.0)
    q = np.zeros(strip.n_dof)
    q[1] = 1.0  # u = p_0(xi) p_1(eta): a uniform shear strain u_y
    whole, ends = strip.unit_stiffness()["A66"], strip.unit_stiffness(end_zone=1.5)["A66"]
    assert q @ ends @ q == pytest.approx(2 * 1.5 / 6.0 * (q @ whole @ q), rel=1e-12)
    with pytest.raises(ValueError, match="overlap"):
        strip.unit_stiffness(end_zone=3.0)


def test_an_end_zone_factor_splits_the_panel_and_leaves_the_nominal_vehicle_unchanged():
    zone = StiffnessParameter("plate_ends", "panel", "plate", ("A11", "D11"), end_zone=1.0)
    rest = StiffnessParameter("plate_rest", "panel", "plate", ("A11", "D11"))
    plain, zoned = _alone(_strip()), _alone(_strip(), parameters=(zone, rest))
    assert np.allclose(zoned.stiffness(np.ones(2)).toarray(), plain.stiffness(np.ones(0)).toarray(),
                       rtol=1e-12, atol=1e-6)
    # softer ends lower the free-free bar's first extension and the beam's first bending
    f_plain, f_soft = _frequencies(plain, n=8), _frequencies(zoned, np.array([0.3, 1.0]), n=8)
    assert np.all(f_soft[6:] < f_plain[6:])


def test_every_factor_set_is_the_nominal_vehicle_at_nominal_factors_and_names_one_meaning_once():
    """A factor set only chooses which rigidities move together: at factors 1 each set's
    stiffness is the same; a name shared by two sets scales the same rigidities in both; each
    set's range holds the nominal."""
    from calibration.models.box import FACTOR_SETS
    from calibration.models.box.shinkansen import ZONED, factor_set

    sets = [*FACTOR_SETS.values(), *(factor_set(name, side_end_zone=5.0) for name in ZONED)]
    stiffness = {}
    for fs in sets:
        assert len(set(fs.names)) == len(fs.names) == len(fs.ranges)
        assert all(lo < 1.0 < hi for lo, hi in fs.ranges)
        m = assemble(shinkansen_vehicle(order_increase=-4, parameters=fs.parameters))
        stiffness[fs.name] = m.stiffness(np.ones(len(m.names))).toarray()
    first, *rest = stiffness.values()
    for K in rest:
        np.testing.assert_allclose(K, first, rtol=0, atol=1e-12 * np.abs(first).max())
    meaning = {}
    for fs in sets:
        for q in fs.parameters:
            what = (q.kind, q.group, set(q.terms), q.end_zone)
            assert meaning.setdefault(q.name, what) == what, q.name


def test_the_credible_set_frees_the_end_and_floor_joints_only_in_the_polish():
    from calibration.models.box import factor_set

    fs = factor_set("credible")
    assert len(fs.names) == 18 and fs.polish_only == 4
    assert {q.group for q in fs.parameters[-4:]} == {"end", "floor_floor"}
    assert factor_set(None).name == "grouped"
    with pytest.raises(ValueError, match="known: grouped, credible, windowed, orthotropic"):
        factor_set("nonesuch")
    with pytest.raises(ValueError, match="orthotropic factor set needs the length"):
        factor_set("orthotropic")
