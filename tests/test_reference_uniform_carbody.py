"""The exudyn lattice of reference_models.uniform_carbody (issue 6, box carbody): its parts
checked against closed forms and against exudyn's own whole-system eigen-analysis."""
import numpy as np

from reference_models.uniform_carbody import (N_RIGID, LatticeSettings, UniformShell, _elastic_modes,
                                              build_exudyn_system, build_lattice, lattice_matrices)


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
    f, _ = _elastic_modes(K, M, 6)
    mbs, _, _ = build_exudyn_system(shell, lattice, settings)
    w, _ = mbs.ComputeODE2Eigenvalues(convert2Frequencies=True)
    assert np.allclose(f, w[N_RIGID:N_RIGID + 6], rtol=1e-6)
