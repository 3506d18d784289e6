"""The box model's factorisations (models/box/factor.py) and the batched close-pair
pairing (models/box/fit.py): the same answers as the textbook solvers, at a fraction of
the cost on a stiffness matrix that is a third full."""
import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg

from calibration.models.box import assemble, factor_set, shinkansen_vehicle
from calibration.models.box.factor import factorise
from calibration.models.box.fit import band_pairing
from calibration.signals.modal import mac_matrix
from calibration.models.box.parametric_basis import full_modes


@pytest.fixture(scope="module")
def coarse():
    return assemble(shinkansen_vehicle(order_increase=-3, parameters=factor_set(None).swarm_parameters))


def test_the_box_stiffness_is_solved_dense_and_agrees_with_sparse_lu(coarse):
    K = coarse.stiffness(np.ones(len(coarse.names)))
    assert K.nnz > 0.02 * K.shape[0] ** 2  # the panels' bases couple their DOF: dense enough
    f = factorise(K)
    assert f.kind == "cholesky"
    b = np.random.default_rng(0).standard_normal((K.shape[0], 3))
    # K is ill-conditioned (stiff joint penalties): compare backward errors, as good as SuperLU's
    norm = scipy.sparse.linalg.norm(K, 1)

    def backward(x):
        return np.max(np.abs(K @ x - b).sum(axis=0) / (norm * np.abs(x).sum(axis=0)))

    x, x_lu = f.solve(b), scipy.sparse.linalg.splu(K.tocsc()).solve(b)
    assert backward(x) < 1e-14 and backward(x) <= 10 * backward(x_lu)


def test_an_indefinite_matrix_is_solved_by_lu_and_a_sparse_one_by_superlu():
    A = np.array([[1.0, 2.0], [2.0, -3.0]])
    f = factorise(sp.csc_matrix(A))
    assert f.kind == "lu" and np.allclose(A @ f.solve([1.0, 1.0]), [1.0, 1.0])
    D = sp.diags(np.arange(1.0, 201.0)).tocsc()
    g = factorise(D)
    assert g.kind == "splu" and np.allclose(g.solve(np.ones(200)), 1.0 / np.arange(1.0, 201.0))
    with pytest.raises(RuntimeError, match="singular"):
        factorise(np.zeros((3, 3)))


def test_full_modes_are_eigenpairs_of_the_full_model(coarse):
    p = np.full(len(coarse.names), 1.1)
    f, X = full_modes(coarse, p, 12)
    K, M = coarse.stiffness(p), coarse.M
    lam = (2 * np.pi * f) ** 2
    R = K @ X - (M @ X) * lam
    assert np.all(np.diff(f) >= 0) and f[0] > 0
    assert np.max(np.linalg.norm(R, axis=0) / np.linalg.norm(K @ X, axis=0)) < 1e-8
    assert np.allclose(X.T @ (M @ X), np.eye(12), atol=1e-8)  # M-normalised


def _pairing_one_by_one(f, phi, shapes, f_t, band, mac, eligible=None):
    """The definition: for each (particle, target) whose band holds two or more modes, the
    MAC with the projection on their span, by one least-squares solve each."""
    idx = np.argmax(mac, axis=2)
    best = np.take_along_axis(mac, idx[..., None], 2)[..., 0]
    inside = (np.abs(f[:, None, :] - f_t[None, :, None]) <= (band * f_t)[None, :, None]) & (band > 0)[None, :, None]
    if eligible is not None:
        inside &= eligible[:, None, :]
    for n, t in zip(*np.nonzero(inside.sum(axis=2) >= 2)):
        ks = np.flatnonzero(inside[n, t])
        U = phi[n][:, ks] / np.linalg.norm(phi[n][:, ks], axis=0)
        c, *_ = np.linalg.lstsq(U, shapes[:, t], rcond=1e-10)
        proj = U @ c
        v = shapes[:, t]
        m = float(np.abs(np.vdot(proj, v)) ** 2 / np.real(np.vdot(proj, proj) * np.vdot(v, v)))
        if m > best[n, t]:
            idx[n, t], best[n, t] = ks[int(np.argmax(np.abs(c)))], m
    return idx, best


@pytest.mark.parametrize("with_eligible", [False, True])
def test_batched_close_pair_pairing_equals_one_solve_per_pair(with_eligible):
    rng = np.random.default_rng(1)
    N, s, m, T = 300, 27, 30, 6
    f = np.sort(rng.uniform(5, 25, (N, m)), axis=1)
    phi = rng.standard_normal((N, s, m))
    shapes = rng.standard_normal((s, T)) + 1j * rng.standard_normal((s, T))
    f_t, band = rng.uniform(8, 20, T), np.full(T, 0.05)  # bands holding 1-4 modes
    eligible = rng.uniform(size=(N, m)) > 0.2 if with_eligible else None
    mac = mac_matrix(shapes, phi)
    if eligible is not None:
        mac = np.where(eligible[:, None, :], mac, 0.0)
    idx, best = band_pairing(f, phi, shapes, f_t, band, mac, eligible)
    ref_idx, ref_best = _pairing_one_by_one(f, phi, shapes, f_t, band, mac, eligible)
    assert np.array_equal(idx, ref_idx) and np.allclose(best, ref_best, rtol=1e-12, atol=1e-12)
    single = np.take_along_axis(mac, np.argmax(mac, axis=2)[..., None], 2)[..., 0]
    assert np.all(best >= single - 1e-12) and np.all(best <= 1 + 1e-12)  # a span fits at least as well as a member
