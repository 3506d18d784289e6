"""Assembly of the extended box-type vehicle: panels, panel joints, point masses, rigid
bogies and suspension elements, into M, C and K = K0 + sum_i p_i K_i.

Every element contributes through point operators, carbody-frame displacement (3 x n)
or rotation (3 x n) of a material point, so the equations of motion follow from
Lagrange's equation (seed eq. 1-2) with the energies written once:

* panel: T and U of :class:`~calibration.models.box.panel.Panel`;
* joint between two panels along a shared edge (seed Figure 1b), integrated by Gauss
  points along the edge, per unit length:
  1/2 k_t |d_A - d_B|^2 + 1/2 k_r (t . (omega_A - omega_B))^2,
  d the displacement and omega the rotation of each panel's edge point, t the edge
  direction. This is the energy of the seed's two parallel springs across the joint,
  written by what they set: their sum is the translational coupling k_t, their offset the
  rotational coupling about the edge k_r. (Two springs joining points offset *into* each
  panel, as a literal reading of the figure might suggest, would strain under a rigid
  rotation of the whole corner; this form cannot.)
* spring-damper between two points (panel points, rigid-body points or the ground),
  stiffness and damping per carbody axis: 1/2 (d_A - d_B)^T diag(k) (d_A - d_B);
* point mass rigidly attached to a panel point: 1/2 m |d|^2.

Parameters scale groups of these energies: a ``StiffnessParameter`` names which panel
rigidities or joint springs it multiplies, and its matrix K_i is assembled once.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numpy.polynomial import legendre

from .panel import BENDING, MEMBRANE, Panel


@dataclass(frozen=True)
class RigidBody:
    name: str
    mass: float  # [kg]
    inertia: tuple[float, float, float]  # [kg m^2] about x, y, z through the centre of mass
    centre: tuple[float, float, float]  # [m] carbody frame
    fixed: tuple[str, ...] = ()  # constrained DOF among x, y, z, roll, pitch, yaw

    def operator(self, point) -> np.ndarray:
        """(3, 6) displacement of a body point from (x, y, z, roll, pitch, yaw)."""
        r = np.asarray(point, float) - np.asarray(self.centre, float)
        skew = np.array([[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]])
        return np.hstack([np.eye(3), -skew])


RIGID_DOFS = ("x", "y", "z", "roll", "pitch", "yaw")


@dataclass(frozen=True)
class Joint:
    group: str  # joints of a group share k_t, k_r
    panel_a: str
    panel_b: str
    start: tuple[float, float, float]
    end: tuple[float, float, float]
    k_t: float  # [N/m per m of edge]
    k_r: float  # [N m/rad per m of edge]


@dataclass(frozen=True)
class Link:
    """Spring-damper between two points; ``body`` names a panel, a rigid body or "ground"."""
    name: str
    group: str  # e.g. "air_spring"; links of a group share their parameters
    body_a: str
    point_a: tuple[float, float, float]
    body_b: str
    point_b: tuple[float, float, float]
    k: tuple[float, float, float]  # [N/m] along x, y, z
    c: tuple[float, float, float] = (0.0, 0.0, 0.0)  # [N s/m]
    patch: tuple[float, float] = (0.0, 0.0)  # [m] seat size on a panel at point_a (see Patch)


@dataclass(frozen=True)
class PointMass:
    name: str
    panel: str
    point: tuple[float, float, float]
    mass: float
    patch: tuple[float, float] = (0.0, 0.0)  # [m] footprint on the panel (see Patch)


# Patch. A spring or a mass fixed to a plate at one point sees the plate's point
# flexibility, which for in-plane loads is unbounded (log-singular in 2D elasticity), so
# frequencies would keep falling as the polynomial order grows. Real attachments have
# seats, bolsters and brackets; an element with a patch (size along the panel's e1, e2)
# follows the mean displacement of the patch (integrated exactly), which converges.


@dataclass(frozen=True)
class StiffnessParameter:
    """A factor on nominal stiffness: panel rigidities of a group, or joint springs of a group."""
    name: str
    kind: str  # "panel" or "joint"
    group: str
    terms: tuple[str, ...]  # panel: rigidity names; joint: ("k_t",) or ("k_r",)
    description: str = ""
    # panel: > 0 scales only the strips of this length [m] at both ends of each panel's e1
    # axis; the rest of the panel stays with the group's other factor (or nominal)
    end_zone: float = 0.0


@dataclass(frozen=True)
class BoxVehicle:
    panels: tuple[Panel, ...]
    joints: tuple[Joint, ...]
    bodies: tuple[RigidBody, ...]
    links: tuple[Link, ...]
    masses: tuple[PointMass, ...]
    parameters: tuple[StiffnessParameter, ...]
    joint_points: int = 0  # Gauss points per joint edge; 0: from the panel orders


@dataclass
class BoxModel:
    """Assembled matrices; K(p) = K0 + sum_i p_i K_i with p = 1 the nominal vehicle."""
    vehicle: BoxVehicle
    names: tuple[str, ...]
    M: sp.csr_matrix
    C: sp.csr_matrix
    K0: sp.csr_matrix
    K_units: dict[str, sp.csr_matrix]
    dof_slices: dict[str, slice]
    n_dof: int
    _fixed_map: dict = field(default_factory=dict, repr=False)

    def stiffness(self, p) -> sp.csr_matrix:
        p = np.asarray(p, float)
        K = self.K0.copy()
        for name, v in zip(self.names, p):
            K = K + v * self.K_units[name]
        return K.tocsr()

    def displacement(self, body: str, point) -> np.ndarray:
        """(3, n_dof) operator: carbody-frame displacement of a material point."""
        return _point_operator(self, body, point, rotation=False)

    def panel(self, name: str) -> Panel:
        return next(p for p in self.vehicle.panels if p.name == name)


def _local_operators(model, body, points, rotation=False) -> tuple[np.ndarray, np.ndarray]:
    """(dof indices, n x 3 x len(indices) operators) of the material points ``points`` (n, 3)
    of ``body``: a panel's basis is evaluated once for all of them."""
    points = np.atleast_2d(np.asarray(points, float))
    if body == "ground":
        return np.zeros(0, int), np.zeros((points.shape[0], 3, 0))
    s = model.dof_slices.get(body)
    if s is None:
        raise KeyError(f"no panel or rigid body named {body!r}")
    idx = np.arange(s.start, s.stop)
    pn = next((p for p in model.vehicle.panels if p.name == body), None)
    if pn is not None:
        return idx, (pn.rotations if rotation else pn.displacements)(points)
    if rotation:
        raise ValueError("rotation operators are for panels")
    rb = next(b for b in model.vehicle.bodies if b.name == body)
    free = [i for i, d in enumerate(RIGID_DOFS) if d not in rb.fixed]
    return idx, np.stack([rb.operator(q)[:, free] for q in points])


def local_operator(model, body, point, rotation=False, patch=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """(dof indices, 3 x len(indices) operator) of a material point of ``body``, or the
    mean over a patch of that size around it (panels only)."""
    if not any(patch) or body == "ground" or body not in {p.name for p in model.vehicle.panels}:
        idx, G = _local_operators(model, body, point, rotation)
        return idx, G[0]
    pn = model.panel(body)
    xg, wg = legendre.leggauss(max(pn.order) + 1)  # the patch mean, exact for the basis
    p0 = np.asarray(point, float)
    points, weights = [], []
    for x, wx in zip(xg, wg):
        for y, wy in zip(xg, wg):
            points.append(p0 + pn.axes[:, 0] * x * patch[0] / 2 + pn.axes[:, 1] * y * patch[1] / 2)
            weights.append(wx * wy / 4)
    idx, ops = _local_operators(model, body, points, rotation)  # the grid's basis values at once
    G = 0.0
    for w, op in zip(weights, ops):  # summed in the order of the point-by-point quadrature
        G = G + w * op
    return idx, G


def _point_operator(model, body, point, rotation=False) -> np.ndarray:
    idx, G = local_operator(model, body, point, rotation)
    out = np.zeros((3, model.n_dof))
    out[:, idx] = G
    return out


def _difference(model, body_a, point_a, body_b, point_b, rotation=False, patch=(0.0, 0.0)):
    """(indices, operator) of the relative motion of two material points."""
    ia, Ga = local_operator(model, body_a, point_a, rotation, patch)
    ib, Gb = local_operator(model, body_b, point_b, rotation)
    idx = np.union1d(ia, ib)
    D = np.zeros((3, idx.size))
    D[:, np.searchsorted(idx, ia)] += Ga
    D[:, np.searchsorted(idx, ib)] -= Gb
    return idx, D


def _differences(model, body_a, body_b, points, rotation=False):
    """(indices, n x 3 x len(indices) operators) of the relative motion of the material
    points of two bodies at the same ``points`` (n, 3)."""
    ia, Ga = _local_operators(model, body_a, points, rotation)
    ib, Gb = _local_operators(model, body_b, points, rotation)
    idx = np.union1d(ia, ib)
    D = np.zeros((Ga.shape[0], 3, idx.size))
    D[:, :, np.searchsorted(idx, ia)] += Ga
    D[:, :, np.searchsorted(idx, ib)] -= Gb
    return idx, D


def _gauss_sum(rows: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """sum_g weights[g] rows[g]^T rows[g] (n x n) for rows (G, k, n): a quadrature of the
    energy density |rows q|^2 over G points.

    When every column has its entries in one row only (panels along the carbody axes: each
    generalised coordinate moves a point along one axis), the sum has a block per row,
    taken over that row's columns alone; it is summed point after point, each term
    weight x (product), which is the value the point-by-point formula
    K = K + w_g (D_g^T D_g) gives, to the bit. Otherwise, one product of the stacked rows
    scaled by sqrt(w), equal to round-off."""
    G, k, n = rows.shape
    used = (rows != 0).any(axis=0)  # (k, n): which columns each row touches
    if np.all(used.sum(axis=0) <= 1):
        out = np.zeros((n, n))
        for row in range(k):
            c = np.flatnonzero(used[row])
            if c.size:
                d = rows[:, row, c]
                terms = d[:, :, None] * d[:, None, :]
                terms *= weights[:, None, None]
                acc = terms[0].copy()
                for term in terms[1:]:  # point after point (np.add.reduce may pair them up)
                    acc += term
                out[np.ix_(c, c)] = acc
        return out
    W = (np.sqrt(weights)[:, None, None] * rows).reshape(G * k, n)
    return W.T @ W


class _Triplets:
    def __init__(self, n):
        self.n, self.rows, self.cols, self.vals = n, [], [], []

    def add(self, idx, block):
        r, c = np.meshgrid(idx, idx, indexing="ij")
        self.rows.append(r.ravel())
        self.cols.append(c.ravel())
        self.vals.append(np.asarray(block).ravel())

    def matrix(self) -> sp.csr_matrix:
        """The sum of the blocks, without the blocks' zeros: a panel's mass block is
        diagonal, its energy blocks are Kronecker products with zero bands, and stored
        zeros made 85-95 % of the entries, each one a cost in every product and
        factorisation."""
        if not self.rows:
            return sp.csr_matrix((self.n, self.n))
        A = sp.coo_matrix((np.concatenate(self.vals), (np.concatenate(self.rows), np.concatenate(self.cols))),
                          shape=(self.n, self.n)).tocsr()
        A.sum_duplicates()
        A.eliminate_zeros()
        return A


def scaling_parameter(parameters, kind: str, group: str, term: str, zoned: bool = False):
    """The parameter of ``parameters`` scaling ``term`` of ``kind`` ``group`` (of the panels'
    end strips with ``zoned``), or None; ValueError where several would."""
    hits = [q for q in parameters if q.kind == kind and q.group == group and term in q.terms
            and (q.end_zone > 0) == zoned]
    if len(hits) > 1:
        where = "end strips of " if zoned else ""
        raise ValueError(f"{where}{kind} {group} {term} is scaled by several parameters: {[q.name for q in hits]}")
    return hits[0] if hits else None


def panel_parts(parameters, pn: Panel) -> dict[str | None, np.ndarray]:
    """The stiffness of panel ``pn`` at its rigidities, split by the parameter that scales
    each part (None: no parameter): a term's end strips to a zoned parameter, the rest of it
    to the group's."""
    units = pn.unit_stiffness()
    strips = {}  # end-strip matrices, once per zone length
    parts: dict[str | None, np.ndarray] = {}

    def add(q, block):
        key = None if q is None else q.name
        parts[key] = parts.get(key, 0.0) + block

    for term in MEMBRANE + BENDING:
        group_q = scaling_parameter(parameters, "panel", pn.group, term)
        zone = scaling_parameter(parameters, "panel", pn.group, term, zoned=True)
        if zone is None:
            add(group_q, pn.rigidity[term] * units[term])
        else:
            if zone.end_zone not in strips:
                strips[zone.end_zone] = pn.unit_stiffness(zone.end_zone)
            end = strips[zone.end_zone][term]
            add(zone, pn.rigidity[term] * end)
            add(group_q, pn.rigidity[term] * (units[term] - end))
    return parts


def assemble(vehicle: BoxVehicle) -> BoxModel:
    slices, n = {}, 0
    for pn in vehicle.panels:
        slices[pn.name] = slice(n, n + pn.n_dof)
        n += pn.n_dof
    for rb in vehicle.bodies:
        k = sum(d not in rb.fixed for d in RIGID_DOFS)
        slices[rb.name] = slice(n, n + k)
        n += k
    names = tuple(p.name for p in vehicle.parameters)
    if len(set(names)) != len(names):
        raise ValueError("parameter names must be unique")
    model = BoxModel(vehicle, names, None, None, None, {}, slices, n)
    M, C, K0 = _Triplets(n), _Triplets(n), _Triplets(n)
    K_units = {name: _Triplets(n) for name in names}

    def owner(kind, group, term):
        q = scaling_parameter(vehicle.parameters, kind, group, term)
        return K0 if q is None else K_units[q.name]

    for pn in vehicle.panels:
        idx = np.arange(slices[pn.name].start, slices[pn.name].stop)
        M.add(idx, pn.rho_h * pn.unit_mass())
        for key, block in panel_parts(vehicle.parameters, pn).items():
            (K0 if key is None else K_units[key]).add(idx, block)

    for rb in vehicle.bodies:
        idx = np.arange(slices[rb.name].start, slices[rb.name].stop)
        free = [i for i, d in enumerate(RIGID_DOFS) if d not in rb.fixed]
        M.add(idx, np.diag([rb.mass] * 3 + list(rb.inertia))[np.ix_(free, free)])

    for pm in vehicle.masses:
        idx, G = local_operator(model, pm.panel, pm.point, patch=pm.patch)
        M.add(idx, pm.mass * (G.T @ G))

    for jt in vehicle.joints:
        pa, pb = model.panel(jt.panel_a), model.panel(jt.panel_b)
        p0, p1 = np.asarray(jt.start, float), np.asarray(jt.end, float)
        length = float(np.linalg.norm(p1 - p0))
        t = (p1 - p0) / length
        npts = vehicle.joint_points or (max(pa.order + pb.order) + 2)
        xg, wg = legendre.leggauss(npts)
        points = p0[None, :] + ((xg + 1) / 2)[:, None] * (p1 - p0)[None, :]
        weights = wg * length / 2
        # every Gauss point's relative displacement D (3 x n) and rotation about the edge
        # r = t . omega (n,) at once (each panel's basis evaluated once for all points)
        idx, D = _differences(model, pa.name, pb.name, points)
        _, R = _differences(model, pa.name, pb.name, points, rotation=True)
        r = np.einsum("j,gjk->gk", t, R)
        owner("joint", jt.group, "k_t").add(idx, jt.k_t * _gauss_sum(D, weights))
        owner("joint", jt.group, "k_r").add(idx, jt.k_r * _gauss_sum(r[:, None, :], weights))

    for ln in vehicle.links:
        idx, D = _difference(model, ln.body_a, ln.point_a, ln.body_b, ln.point_b, patch=ln.patch)
        K0.add(idx, D.T @ np.diag(ln.k) @ D)
        if any(ln.c):
            C.add(idx, D.T @ np.diag(ln.c) @ D)

    model.M, model.C, model.K0 = M.matrix(), C.matrix(), K0.matrix()
    model.K_units = {k: v.matrix() for k, v in K_units.items()}
    return model


def carbody_mass(model: BoxModel) -> float:
    """Carbody mass [kg]: the panels' areal masses and the masses carried on them."""
    return float(sum(pn.mass for pn in model.vehicle.panels) + sum(pm.mass for pm in model.vehicle.masses))
