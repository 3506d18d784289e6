"""A thin-walled carbody as flat rectangular shell elements: the independent stationary truth's
structure, a finite element model, not railcal's Rayleigh-Ritz box.

Each element is a rectangle in its own plane with six degrees of freedom per corner node
(three displacements, three rotations):

* **membrane**: bilinear displacements enriched by the two incompatible modes (1 - xi^2),
  (1 - eta^2), condensed out (Wilson-Taylor), so in-plane bending does not lock;
* **bending and transverse shear**: Reissner-Mindlin with the MITC4 assumed transverse
  shear strains (Bathe and Dvorkin 1985), tied at the edge midpoints, so a thin plate does
  not lock in shear;
* **drilling**: the rotation about the normal tied by a soft penalty (a thousandth of the
  membrane's shear stiffness) to the membrane's own in-plane rotation (Hughes and Brezzi
  1989), so a coplanar node's rotation is determined and a rigid rotation costs nothing.

Sections are smeared: a double-skin extrusion acts as a membrane ``A`` (N/m), a bending
plate ``D`` (N m) and a transverse shear ``S`` (N/m), orthotropic along the element's axes;
mass is lumped on the translations (the rotations carry none, so a mass-normalised mode of
K phi = omega^2 M phi has the rotations statically condensed).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

GAUSS = (-1 / np.sqrt(3), 1 / np.sqrt(3))
CORNERS = ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0))  # (xi, eta) of nodes 1-4, counter-clockwise
DRILLING = 1e-3


@dataclass(frozen=True)
class Section:
    """Smeared properties of a panel: membrane ``A`` and bending ``D`` (3 x 3, Voigt order
    xx, yy, xy in the element's axes), transverse shear stiffness ``S`` [N/m] and areal
    mass [kg/m^2]."""

    A: np.ndarray
    D: np.ndarray
    S: float
    areal_mass: float

    def scaled(self, membrane: float = 1.0, bending: float = 1.0) -> Section:
        return Section(self.A * membrane, self.D * bending, self.S * bending, self.areal_mass)


def double_skin(E: float, nu: float, skin: float, depth: float, across: float, shear_web: float,
                areal_mass: float) -> Section:
    """A double-skin extrusion: two skins of ``skin`` [m] at ``depth`` [m] apart, ribs along
    the element's x axis. ``across``: share of the skins' rigidity left across the ribs (the
    ribs bend); ``shear_web``: the core's transverse shear modulus x depth [N/m]."""
    f = E / (1 - nu ** 2)
    iso = np.array([[1.0, nu, 0.0], [nu, 1.0, 0.0], [0.0, 0.0, (1 - nu) / 2]])
    scale = np.diag([1.0, across, np.sqrt(across)])
    A = 2 * skin * f * scale @ iso @ scale
    D = 2 * skin * (depth / 2) ** 2 * f * scale @ iso @ scale
    return Section(A, D, shear_web, areal_mass)


def _bilinear(xi: float, eta: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shape functions of the four corners and their xi, eta derivatives."""
    c = np.array(CORNERS)
    n = 0.25 * (1 + c[:, 0] * xi) * (1 + c[:, 1] * eta)
    return n, 0.25 * c[:, 0] * (1 + c[:, 1] * eta), 0.25 * c[:, 1] * (1 + c[:, 0] * xi)


def membrane_stiffness(a: float, b: float, A: np.ndarray) -> np.ndarray:
    """8 x 8 membrane stiffness (u, v per node) of an a x b rectangle, incompatible modes condensed."""
    K = np.zeros((12, 12))  # 8 nodal + 4 incompatible (u: 1-xi^2, 1-eta^2; v: the same)
    jx, jy = 2 / a, 2 / b
    for xi in GAUSS:
        for eta in GAUSS:
            _, dxi, deta = _bilinear(xi, eta)
            B = np.zeros((3, 12))
            B[0, 0:8:2], B[1, 1:8:2] = dxi * jx, deta * jy
            B[2, 0:8:2], B[2, 1:8:2] = deta * jy, dxi * jx
            g = np.array([-2 * xi * jx, 0.0]), np.array([0.0, -2 * eta * jy])  # grads of the bubbles
            B[0, 8], B[0, 9] = g[0][0], g[1][0]
            B[1, 10], B[1, 11] = g[0][1], g[1][1]
            B[2, 8], B[2, 9], B[2, 10], B[2, 11] = g[0][1], g[1][1], g[0][0], g[1][0]
            K += B.T @ A @ B * (a * b / 4)
    kcc, kci, kii = K[:8, :8], K[:8, 8:], K[8:, 8:]
    return kcc - kci @ np.linalg.solve(kii, kci.T)


def plate_stiffness(a: float, b: float, D: np.ndarray, S: float) -> np.ndarray:
    """12 x 12 MITC4 plate stiffness (w, theta_x, theta_y per node) of an a x b rectangle.
    Rotations are right-handed about the element's axes: the normal's slopes are
    beta_x = theta_y, beta_y = -theta_x; curvatures (beta_x,x, beta_y,y, beta_x,y + beta_y,x);
    transverse shear (w,x + beta_x, w,y + beta_y)."""
    jx, jy = 2 / a, 2 / b

    def shear_rows(xi, eta):
        n, dxi, deta = _bilinear(xi, eta)
        gx, gy = np.zeros(12), np.zeros(12)
        gx[0::3], gx[2::3] = dxi * jx, n  # w,x + theta_y
        gy[0::3], gy[1::3] = deta * jy, -n  # w,y - theta_x
        return gx, gy

    # assumed shear: gamma_xz tied at the midpoints of the edges eta = +-1, gamma_yz at xi = +-1
    gxz_top, gxz_bot = shear_rows(0.0, 1.0)[0], shear_rows(0.0, -1.0)[0]
    gyz_right, gyz_left = shear_rows(1.0, 0.0)[1], shear_rows(-1.0, 0.0)[1]
    K = np.zeros((12, 12))
    for xi in GAUSS:
        for eta in GAUSS:
            _, dxi, deta = _bilinear(xi, eta)
            Bb = np.zeros((3, 12))
            Bb[0, 2::3] = dxi * jx  # beta_x,x
            Bb[1, 1::3] = -deta * jy  # beta_y,y
            Bb[2, 2::3], Bb[2, 1::3] = deta * jy, -dxi * jx
            Bs = np.vstack([0.5 * (1 + eta) * gxz_top + 0.5 * (1 - eta) * gxz_bot,
                            0.5 * (1 + xi) * gyz_right + 0.5 * (1 - xi) * gyz_left])
            K += (Bb.T @ D @ Bb + S * Bs.T @ Bs) * (a * b / 4)
    return K


def element_stiffness(a: float, b: float, section: Section) -> np.ndarray:
    """24 x 24 local stiffness, per node (u, v, w, theta_x, theta_y, theta_z)."""
    K = np.zeros((24, 24))
    m = [6 * i + d for i in range(4) for d in (0, 1)]
    p = [6 * i + d for i in range(4) for d in (2, 3, 4)]
    K[np.ix_(m, m)] = membrane_stiffness(a, b, section.A)
    K[np.ix_(p, p)] += plate_stiffness(a, b, section.D, section.S)
    # drilling: theta_z tied to the membrane's own in-plane rotation (v,x - u,y) / 2, so a
    # rigid rotation costs nothing
    k_drill = DRILLING * section.A[2, 2]
    jx, jy = 2 / a, 2 / b
    for xi in GAUSS:
        for eta in GAUSS:
            n, dxi, deta = _bilinear(xi, eta)
            r = np.zeros(24)
            r[5::6] = n
            r[0::6] += 0.5 * deta * jy
            r[1::6] -= 0.5 * dxi * jx
            K += k_drill * np.outer(r, r) * (a * b / 4)
    return K


@dataclass
class ShellModel:
    """Nodes (n x 3) [m], the sparse stiffness (6n x 6n) and the lumped translational masses
    (n,) [kg]. Degree of freedom 6 i + d: node i, d = ux, uy, uz, rx, ry, rz."""

    nodes: np.ndarray
    K: scipy.sparse.csr_matrix
    mass: np.ndarray

    def node_at(self, point, tol: float = 1e-6) -> int:
        """The node at ``point`` [m]; ValueError when the mesh has none there."""
        d = np.linalg.norm(self.nodes - np.asarray(point, float), axis=1)
        i = int(np.argmin(d))
        if d[i] > tol:
            raise ValueError(f"no mesh node at {tuple(point)} (nearest {tuple(self.nodes[i])}, {d[i]:.3g} m off)")
        return i

    def M(self) -> scipy.sparse.csr_matrix:
        m = np.zeros(6 * len(self.mass))
        for d in range(3):
            m[d::6] = self.mass
        return scipy.sparse.diags(m).tocsr()

    def modes(self, count: int, shift: float = -1.0) -> tuple[np.ndarray, np.ndarray]:
        """The ``count`` lowest modes (rigid-body ones included): frequencies [Hz] and
        mass-normalised shapes (6n x count)."""
        M = self.M()
        lam, phi = scipy.sparse.linalg.eigsh(self.K, k=count, M=M, sigma=shift, which="LM")
        order = np.argsort(lam)
        lam, phi = lam[order], phi[:, order]
        phi /= np.sqrt(np.einsum("ij,i,ij->j", phi, M.diagonal(), phi))
        return np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi), phi


class Mesher:
    """Assembles rectangular elements on shared nodes (nodes merged by position)."""

    def __init__(self):
        self._index: dict[tuple, int] = {}
        self._nodes: list[tuple[float, float, float]] = []
        self._rows, self._cols, self._vals = [], [], []
        self._mass: list[float] = []

    def node(self, p) -> int:
        key = tuple(np.round(np.asarray(p, float), 6))
        if key not in self._index:
            self._index[key] = len(self._nodes)
            self._nodes.append(key)
            self._mass.append(0.0)
        return self._index[key]

    def rectangle(self, origin, e1, e2, a: float, b: float, section: Section):
        """One element: corner ``origin`` [m], unit axes e1, e2, sides a along e1, b along e2."""
        o, e1, e2 = (np.asarray(v, float) for v in (origin, e1, e2))
        e3 = np.cross(e1, e2)
        ids = [self.node(o + e1 * a * (1 + xi) / 2 + e2 * b * (1 + eta) / 2) for xi, eta in CORNERS]
        R = np.vstack([e1, e2, e3])
        T = np.kron(np.eye(8), R)
        Ke = T.T @ element_stiffness(a, b, section) @ T
        dofs = np.array([6 * i + d for i in ids for d in range(6)])
        self._rows.append(np.repeat(dofs, 24))
        self._cols.append(np.tile(dofs, 24))
        self._vals.append(Ke.ravel())
        for i in ids:
            self._mass[i] += section.areal_mass * a * b / 4

    def add_mass(self, node: int, mass: float):
        self._mass[node] += mass

    def model(self) -> ShellModel:
        n = 6 * len(self._nodes)
        K = scipy.sparse.coo_matrix((np.concatenate(self._vals), (np.concatenate(self._rows),
                                                                  np.concatenate(self._cols))), shape=(n, n)).tocsr()
        return ShellModel(np.array(self._nodes), K, np.array(self._mass))
