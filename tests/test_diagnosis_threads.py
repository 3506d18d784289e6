"""A diagnosis's answer must not depend on the machine's BLAS thread count. Both diagnoses
run on one thread for speed; the round-off amplifier that made two threads answer
otherwise (calibration/diagnosis/threads.py) is tested below, without the pin."""
import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from calibration.diagnosis.in_service import diagnose_in_service
from calibration.diagnosis.excitation import diagnose_excitation
from calibration.diagnosis.threads import one_blas_thread


def _blas_threads():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_a_function_pinned_to_one_blas_thread_runs_on_one_and_leaves_the_setting_as_it_was():
    @one_blas_thread
    def inside():
        np.linalg.eigh(np.eye(64))  # some BLAS work
        return _blas_threads()

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert before and all(n == 2 for n in before)
        assert inside() == [1] * len(before)
        assert _blas_threads() == before


def test_both_diagnoses_are_pinned_to_one_blas_thread():
    for entry in (diagnose_in_service, diagnose_excitation):  # for speed: the answers no longer depend on it (below)
        assert entry.__wrapped__.__name__ == entry.__name__  # the one_blas_thread wrapper
        assert entry.__code__ is one_blas_thread(lambda: None).__code__


# ------------------------------------------------- where round-off was amplified, and is not now
def _solver_with_other_round_off(eigsh, angle: float, noise: float):
    """``eigsh`` as another BLAS thread count might return it: the vectors of every pair of
    equal eigenvalues turned by ``angle`` within their plane (any basis of it is right), and
    every vector changed in its last digits (relative ``noise``, seeded)."""
    def solve(*args, **kwargs):
        w2, X = eigsh(*args, **kwargs)
        X = X.copy()
        order = np.argsort(w2)
        c, s = np.cos(angle), np.sin(angle)
        for a, b in zip(order, order[1:]):
            if abs(w2[b] - w2[a]) <= 1e-9 * abs(w2[b]):
                X[:, a], X[:, b] = c * X[:, a] + s * X[:, b], -s * X[:, a] + c * X[:, b]
        X += noise * np.abs(X).max() * np.random.default_rng(5).standard_normal(X.shape)
        return w2, X
    return solve


def test_a_reduced_basis_gives_the_same_frequencies_whatever_basis_of_equal_modes_the_solver_returns(
        coarse_box_model, monkeypatch):
    """The box model's bogies give exactly equal pairs of eigenvalues; a solver may return any
    basis of such a pair, and two BLAS threads did (shapes turned by up to 80 degrees). The
    reduced basis built from them gave frequencies 8e-6 apart 3 % from its centre, enough to
    send a swarm into another basin; built from canonical shapes, and without directions
    that are round-off only, it gives the same frequencies to round-off."""
    import scipy.sparse.linalg

    from calibration.models.box import parametric_basis

    model = coarse_box_model
    p = np.full(len(model.names), 1.05)
    q = p * np.exp(np.random.default_rng(0).uniform(-0.03, 0.03, p.size))
    f0 = parametric_basis.ReducedFamily.build(model, p[None], modes_per_sample=30, size=60, derivatives=20).modes(q, 30)[0]
    w, _ = parametric_basis.full_modes(model, p, 34)
    assert np.min(w[1:] / w[:-1] - 1) < 1e-9  # the model has equal pairs: the case in point
    monkeypatch.setattr(scipy.sparse.linalg, "eigsh",
                        _solver_with_other_round_off(scipy.sparse.linalg.eigsh, angle=1.2, noise=1e-13))
    f1 = parametric_basis.ReducedFamily.build(model, p[None], modes_per_sample=30, size=60, derivatives=20).modes(q, 30)[0]
    assert np.max(np.abs(f1 / f0 - 1)) < 1e-9


def test_equal_eigenvalues_get_a_basis_that_depends_on_their_span_only():
    from calibration.models.box.parametric_basis import canonical_vectors

    rng = np.random.default_rng(1)
    Q = np.linalg.qr(rng.standard_normal((12, 5)))[0]
    w = np.array([1.0, 2.0, 2.0, 2.0 * (1 + 1e-12), 3.0])  # a cluster of three
    t = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    turned = Q.copy()
    turned[:, 1:4] = Q[:, 1:4] @ t
    a, b = canonical_vectors(w, Q), canonical_vectors(w, turned)
    assert np.allclose(a, b, atol=1e-12)
    assert np.allclose(a[:, [0, 4]], Q[:, [0, 4]])  # single eigenvalues keep their vectors
    assert np.allclose(a.T @ a, np.eye(5), atol=1e-12)  # still orthonormal, still the same span
    assert np.allclose(a[:, 1:4] @ a[:, 1:4].T, Q[:, 1:4] @ Q[:, 1:4].T, atol=1e-12)
