"""One orthotropic plate panel of the box-type carbody, with exact unit energy matrices.

A panel is a flat rectangle of length ``a`` along its first axis e1 and ``b`` along e2,
centred at ``centre`` of the carbody frame, its normal e3 = e1 x e2. It carries three
fields over (xi, eta) in [-1, 1]^2, x = a xi / 2, y = b eta / 2:

    u (along e1), v (along e2): in-plane (membrane), w (along e3): out of plane (bending),

each a double Legendre series of orders (n_xi, n_eta) (see ``basis``). The generalised
coordinates are the series coefficients, ordered [u..., v..., w...], index i * (n_eta+1) + j.

Energies (smeared properties of skin and stiffeners, SI):
    T = 1/2 rho_h int (u'^2 + v'^2 + w'^2) dA
    U = 1/2 int (A11 u_x^2 + 2 A12 u_x v_y + A22 v_y^2 + A66 (u_y + v_x)^2) dA
      + 1/2 int (D11 w_xx^2 + 2 D12 w_xx w_yy + D22 w_yy^2 + 4 D66 w_xy^2) dA
The stiffness is linear in the eight rigidities, so :meth:`Panel.unit_stiffness` returns
one exact matrix per rigidity (Kronecker products of 1D integrals) and nothing is ever
re-integrated when a rigidity changes.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from . import basis

MEMBRANE = ("A11", "A22", "A12", "A66")
BENDING = ("D11", "D22", "D12", "D66")
RIGIDITIES = MEMBRANE + BENDING


@dataclass(frozen=True, eq=False)
class Panel:
    name: str
    group: str  # panels of a group share their rigidity parameters (roof, floor, side, end)
    centre: tuple[float, float, float]  # [m] in the carbody frame
    e1: tuple[float, float, float]  # unit vector of the panel's first axis
    e2: tuple[float, float, float]  # unit vector of the second axis (orthogonal to e1)
    a: float  # [m] length along e1
    b: float  # [m] length along e2
    order: tuple[int, int]  # Legendre orders (n_xi, n_eta) of every field
    rho_h: float  # [kg/m^2] areal mass
    rigidity: dict  # A11, A22, A12, A66 [N/m]; D11, D22, D12, D66 [N m]

    def __post_init__(self):
        R = self.axes
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-12):
            raise ValueError(f"panel {self.name}: e1 and e2 must be orthonormal")
        if min(self.order) < 1:
            raise ValueError(f"panel {self.name}: orders must be >= 1 to hold the rigid motions")
        if self.a <= 0 or self.b <= 0 or self.rho_h <= 0:
            raise ValueError(f"panel {self.name}: a, b and rho_h must be positive")
        missing = set(RIGIDITIES) - set(self.rigidity)
        if missing:
            raise ValueError(f"panel {self.name}: rigidities {sorted(missing)} missing")

    @cached_property
    def axes(self) -> np.ndarray:
        """3 x 3, columns e1, e2, e3 in the carbody frame."""
        e1, e2 = np.asarray(self.e1, float), np.asarray(self.e2, float)
        return np.column_stack([e1, e2, np.cross(e1, e2)])

    @property
    def n_terms(self) -> int:
        return (self.order[0] + 1) * (self.order[1] + 1)

    @property
    def n_dof(self) -> int:
        return 3 * self.n_terms

    @property
    def mass(self) -> float:
        return self.rho_h * self.a * self.b

    # -- energy matrices --------------------------------------------------------------
    def unit_mass(self) -> np.ndarray:
        """Mass matrix for rho_h = 1: (a b / 4) I, the basis being orthonormal."""
        return np.eye(self.n_dof) * self.a * self.b / 4

    def unit_stiffness(self, end_zone: float = 0.0) -> dict[str, np.ndarray]:
        """One (n_dof, n_dof) matrix per rigidity, for that rigidity = 1; with ``end_zone``
        [m] > 0, of the two strips of that length at the ends of the panel's e1 axis only
        (a rigidity that differs there, e.g. a side wall's at its door openings)."""
        if end_zone > 0:
            if 2 * end_zone >= self.a:
                raise ValueError(f"panel {self.name}: end zones of {end_zone} m overlap (length {self.a} m)")
            c = 1.0 - 2.0 * end_zone / self.a
            Ex = basis.integrals_over(self.order[0], ((-1.0, -c), (c, 1.0)))
        else:
            Ex = basis.integrals(self.order[0])
        Ey = basis.integrals(self.order[1])
        a, b, n = self.a, self.b, self.n_terms

        def kron(r, s, p, q):
            return np.kron(Ex[(r, s)], Ey[(p, q)])

        def block(**blocks):
            K = np.zeros((3 * n, 3 * n))
            for key, val in blocks.items():
                i, j = "uvw".index(key[0]), "uvw".index(key[1])
                K[i * n:(i + 1) * n, j * n:(j + 1) * n] += val
            return K

        uv = kron(1, 0, 0, 1)  # int u_x v_y (the 2 a b / 4 / (a b / 4) scale factors cancel)
        uyvx = kron(0, 1, 1, 0)  # int u_y v_x
        return {
            "A11": block(uu=(b / a) * kron(1, 1, 0, 0)),
            "A22": block(vv=(a / b) * kron(0, 0, 1, 1)),
            "A12": block(uv=uv, vu=uv.T),
            "A66": block(uu=(a / b) * kron(0, 0, 1, 1), vv=(b / a) * kron(1, 1, 0, 0), uv=uyvx, vu=uyvx.T),
            "D11": block(ww=(4 * b / a**3) * kron(2, 2, 0, 0)),
            "D22": block(ww=(4 * a / b**3) * kron(0, 0, 2, 2)),
            "D12": block(ww=(4 / (a * b)) * (kron(2, 0, 0, 2) + kron(0, 2, 2, 0))),
            "D66": block(ww=(16 / (a * b)) * kron(1, 1, 1, 1)),
        }

    def stiffness(self, scale: dict[str, float] | None = None) -> np.ndarray:
        """Stiffness with this panel's rigidities, each times ``scale[rigidity]`` (default 1)."""
        scale = scale or {}
        units = self.unit_stiffness()
        return sum(self.rigidity[k] * scale.get(k, 1.0) * units[k] for k in RIGIDITIES)

    # -- kinematics at points ---------------------------------------------------------
    def local(self, point) -> tuple[float, float]:
        """(xi, eta) of a carbody-frame point lying in the panel's plane."""
        xi, eta = self.local_many(np.asarray(point, float)[None, :])
        return float(xi[0]), float(eta[0])

    def local_many(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(xi, eta), each (n,), of n carbody-frame points (n, 3) lying in the panel's plane."""
        P = np.atleast_2d(np.asarray(points, float))
        d = P - np.asarray(self.centre, float)
        off = np.abs(d @ self.axes[:, 2]) > 1e-9 * max(self.a, self.b, 1.0)
        if off.any():
            raise ValueError(f"point {P[np.argmax(off)].tolist()} is not in the plane of panel {self.name}")
        xi, eta = 2 * (d @ self.axes[:, 0]) / self.a, 2 * (d @ self.axes[:, 1]) / self.b
        out = (np.abs(xi) > 1 + 1e-9) | (np.abs(eta) > 1 + 1e-9)
        if out.any():
            raise ValueError(f"point {P[np.argmax(out)].tolist()} lies outside panel {self.name}")
        return xi, eta

    def _shapes(self, xi, eta, dx=0, dy=0) -> np.ndarray:
        """(n, n_terms): the (dx, dy)-th derivative of every basis function p_i(xi) p_j(eta)
        at n points; each 1D basis is evaluated once for all the points."""
        px = basis.values(self.order[0], xi, dx) * (2 / self.a) ** dx
        py = basis.values(self.order[1], eta, dy) * (2 / self.b) ** dy
        return (px[:, :, None] * py[:, None, :]).reshape(px.shape[0], -1)

    def displacements(self, points) -> np.ndarray:
        """(n, 3, n_dof): carbody-frame displacement of the panel's material points at
        ``points`` (n, 3) [m]."""
        phi = self._shapes(*self.local_many(points))
        n, m = phi.shape
        local = np.zeros((n, 3, 3 * m))
        for k in range(3):
            local[:, k, k * m:(k + 1) * m] = phi
        return self._rotate(local)

    def rotations(self, points) -> np.ndarray:
        """(n, 3, n_dof): small rotation vector at ``points`` (n, 3) [m] in the carbody
        frame: the normal's tilt (w_y, -w_x) and the in-plane drilling rotation (v_x - u_y) / 2."""
        xi, eta = self.local_many(points)
        px, py = self._shapes(xi, eta, dx=1), self._shapes(xi, eta, dy=1)
        n, m = px.shape
        local = np.zeros((n, 3, 3 * m))
        local[:, 0, 2 * m:] = py
        local[:, 1, 2 * m:] = -px
        local[:, 2, :m] = -py / 2
        local[:, 2, m:2 * m] = px / 2
        return self._rotate(local)

    def _rotate(self, local: np.ndarray) -> np.ndarray:
        """Panel-frame rows (n, 3, n_dof) to the carbody frame: row i = sum_k axes[i, k] local_k."""
        R = self.axes
        return sum(R[None, :, k, None] * local[:, k, None, :] for k in range(3))

    def displacement(self, point) -> np.ndarray:
        """(3, n_dof): carbody-frame displacement of the panel's material point at ``point``."""
        return self.displacements(np.asarray(point, float)[None, :])[0]

    def rotation(self, point) -> np.ndarray:
        """(3, n_dof): small rotation vector at ``point`` in the carbody frame (:meth:`rotations`)."""
        return self.rotations(np.asarray(point, float)[None, :])[0]
