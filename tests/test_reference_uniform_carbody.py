"""The exudyn lattice of reference_models.uniform_carbody (issue 6, box carbody): its parts
checked against closed forms and against exudyn's own whole-system eigen-analysis."""
import numpy as np
import scipy.sparse.linalg as sla

from reference_models.uniform_carbody import (N_RIGID, LatticeSettings, UniformShell, elastic_modes,
                                              build_exudyn_system, build_lattice, build_panel_lattice,
                                              lattice_matrices)


def _coarse():
    shell, settings = UniformShell(), LatticeSettings(cell=2.5)
    lattice = build_lattice(shell, settings)
    return shell, settings, lattice, lattice_matrices(shell, lattice, settings)


def test_lattice_mass_and_membrane_stiffness_are_the_shells():
    shell, _, lattice, (M, K, nodes) = _coarse()
    g = shell.geometry
    H = g.roof_z - g.floor_z
    u = np.zeros(M.shape[0])
    u[0::6] = 1.0
    assert np.isclose(u @ M @ u, shell.m_h * (2 * g.length * (g.width + H) + 2 * g.width * H), rtol=1e-9)
    eps = 1e-6  # uniform axial strain along x, lateral strain held at zero: energy 1/2 Q eps^2 per area
    for (p, _), i in nodes.items():
        u[6 * i:6 * i + 3] = (eps * lattice.points[p][0], 0.0, 0.0)
    expected = 0.5 * shell.Q * eps**2 * 2 * g.length * (g.width + H)
    assert np.isclose(0.5 * u @ K @ u, expected, rtol=2e-3)


def test_sparse_assembly_equals_exudyn_whole_system_eigenvalues():
    shell, settings, lattice, (M, K, _) = _coarse()
    f, _ = elastic_modes(K, M, 6)
    mbs, _, _ = build_exudyn_system(shell, lattice, settings)
    w, _ = mbs.ComputeODE2Eigenvalues(convert2Frequencies=True)
    assert np.allclose(f, w[N_RIGID:N_RIGID + 6], rtol=1e-5)  # the weld penalty's conditioning


def _panel(shell, size, n, held):
    """Sparse K, M of a flat panel lattice with in-plane motion held (a flat plate's bending
    is uncoupled from it) and w held at the grid points where held(point) is true; and the
    kept coordinate of w at each grid point (None where held)."""
    lattice = build_panel_lattice(shell, size, n)
    M, K, nodes = lattice_matrices(shell, lattice, LatticeSettings())
    keep = np.ones(M.shape[0], bool)
    w_of = {}
    for (p, _), i in nodes.items():
        keep[6 * i:6 * i + 2] = False
        if held(lattice.points[p]):
            keep[6 * i + 2] = False
        else:
            w_of.setdefault(p, 6 * i + 2)
    new = np.cumsum(keep) - 1
    return K[keep][:, keep], M[keep][:, keep], lattice.points, {p: new[c] for p, c in w_of.items()}


def test_panel_twisting_stiffness_converges_to_the_plates():
    """D66 alone: a square plate on three corners with a corner force F is in pure twist,
    w = F x y / (2 D (1 - nu)) (Timoshenko & Woinowsky-Krieger, sec. 44). The lattice's
    diagonals carry uniform twist exactly inside; along free edges the nodes' rotations
    relax within one cell, so the corner deflection is high by O(h) (14, 6.8, 3.2, 1.5 %
    at n = 2, 4, 8, 16). The closed box has no free edges."""
    shell, A, F = UniformShell(), 2.0, 1e3
    corners = [(0.0, 0.0), (A, 0.0), (0.0, A)]
    err = []
    for n in (4, 8):
        K, _, pts, w_of = _panel(shell, (A, A), (n, n), lambda x: any(np.allclose(x[:2], c) for c in corners))
        corner = int(np.flatnonzero(np.all(np.isclose(pts[:, :2], (A, A)), axis=1))[0])
        f = np.zeros(K.shape[0])
        f[w_of[corner]] = F
        u = sla.spsolve(K.tocsc(), f)
        err.append(u[w_of[corner]] / (F * A * A / (2 * shell.D * (1 - shell.nu))) - 1)
    assert 0 < err[1] < 0.04
    assert 1.8 < err[0] / err[1] < 2.5  # first order in the cell size


def test_simply_supported_panel_converges_to_the_plates_first_frequency():
    """D11, D22, D12 + 2 D66 together, under a varying curvature: the (1, 1) mode of a
    simply supported square plate, f = pi / a^2 sqrt(D / m_h) [Hz], approached as h^2
    (+4.1, +0.8 % at n = 4, 8; a lattice with stiff transverse bar shear locks
    instead: +221 % at n = 8)."""
    shell, A = UniformShell(), 2.0
    exact = np.pi / A**2 * np.sqrt(shell.D / shell.m_h)
    err = []
    for n in (4, 8):
        K, M, _, _ = _panel(shell, (A, A), (n, n), lambda x: np.isclose(x[:2], 0).any() or np.isclose(x[:2], A).any())
        w2 = sla.eigsh(K.tocsc(), k=1, M=M.tocsc(), sigma=0, which="LM", return_eigenvectors=False)
        err.append(np.sqrt(w2[0]) / (2 * np.pi) / exact - 1)
    assert 0 < err[1] < 0.01
    assert 3 < err[0] / err[1] < 16  # second order in the cell size
