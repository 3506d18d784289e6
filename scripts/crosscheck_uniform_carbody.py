"""Acceptance check (issue 6, box carbody): railcal's box model of a uniform shell against an
independent exudyn beam lattice of the same shell (reference_models.uniform_carbody).
Acceptance: the first six elastic free-free frequencies within 5 %. The differences are the
lattice's discretisation (positive, O(h^2)): max 4.6 % at 0.8 m cells (16 s), 1.6 % at 0.5 m
(28 s), 0.8 % at 0.35 m (2.3 min, 67k DOF); see the module docstring for the table.

    python scripts/crosscheck_uniform_carbody.py [--cell 0.5]
"""
from __future__ import annotations

import argparse
import sys

from reference_models.uniform_carbody import LatticeSettings, UniformShell, compare

TOL = 0.05


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cell", type=float, default=0.5, help="lattice cell size [m]")
    args = ap.parse_args()
    shell = UniformShell()
    c = compare(shell, LatticeSettings(cell=args.cell))
    print(f"uniform shell t = {shell.t} m, E = {shell.E:.3g} Pa, nu = {shell.nu:.4f}, m_h = {shell.m_h} kg/m^2")
    print(f"railcal {c.box.n_dof} DOF ({c.box.seconds:.1f} s), exudyn lattice {c.lattice.n_dof} DOF "
          f"({c.lattice.seconds:.1f} s), cell {args.cell} m")
    print(f"{'mode':>4} {'type':<22} {'railcal Hz':>10} {'exudyn Hz':>10} {'MAC':>6} {'diff %':>7}")
    for (i, j, m, name), e in zip(c.pairs, c.errors):
        print(f"{i + 1:>4} {name:<22} {c.box.frequencies[i]:>10.2f} {c.lattice.frequencies[j]:>10.2f} {m:>6.3f} "
              f"{100 * e:>7.2f}")
    ok = bool(abs(c.errors).max() <= TOL)
    print("PASS" if ok else "FAIL", f"(max |diff| {100 * abs(c.errors).max():.1f} %, tolerance {100 * TOL:.0f} %)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
