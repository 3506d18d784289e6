"""A uniform box carbody built twice: in railcal's box model and as an exudyn beam lattice
(issue 6, independent check of the box carbody).

The shell: the box of :class:`~calibration.models.box.shinkansen.Geometry` (24.5 m x 3.38 m,
floor z = 1.10 m, roof z = 3.55 m, closed ends), every wall one isotropic plate of thickness
t [m], Young's modulus E [Pa], Poisson's ratio nu = 1/3 and areal mass m_h [kg/m^2], free in
space, with no iron blocks, bogies or suspension.

* railcal: the eight Legendre panels of :func:`shinkansen_vehicle` with isotropic rigidities,
  the joints made stiff (k_t = joint_factor * E t / (1 - nu^2), k_r = joint_factor * D; the
  frequencies stop changing by joint_factor ~ 1e3, see the test).
* exudyn: a lattice of ``ObjectBeamGeometricallyExact`` (Simo-Reissner beams on
  ``NodeRigidBodyRotVecLG`` nodes) on a grid over every face: bars along both face axes and
  two crossing diagonals in each cell (Hrennikoff's lattice). For nu = 1/3 such a lattice has
  exactly the smeared membrane stiffness of a plate (C11 = C22, C12 = C66 = C11 / 3) and, with
  the bars' out-of-plane bending, exactly its bending stiffness (D, nu D and the twisting
  term, carried by the diagonals) under uniform curvature; see :func:`lattice_sections`.
  That is why nu = 1/3 (aluminium's nu, 0.33) and not 0.3: the lattice reproduces no other
  nu. The bars' torsion and in-plane bending are set to 1e-3 of their natural scale (a
  lattice of pinned bars); rotary inertia to 1e-3 of the wall's (railcal's panels have none).
  Mass is spread uniformly over the bar length.

  Out-of-plane shear of a bar is G A = 12 E I / a^2: exudyn's two-node beam (linear fields,
  one-point shear) is then exactly the cubic Euler-Bernoulli beam element. A stiff shear
  (the Kirchhoff limit) locks, since the crossing diagonals give four shear constraints per
  grid point against three out-of-plane coordinates: that made a simply supported square
  plate +221 % stiff on an 8 x 8 grid (+76 % on 16 x 16), and the box's torsion and
  cross-section modes +20 to +70 % at 0.5 m cells (the first version of this module). Now
  the plate is +4.1, +0.8, -0.02 % on 4 x 4, 8 x 8, 16 x 16, converging as h^2; pure twist
  (D66 alone) is exact inside and soft by O(h) along free edges only
  (tests/test_reference_uniform_carbody.py).

  Result (scripts/crosscheck_uniform_carbody.py), railcal / lattice [Hz] at 0.8, 0.5,
  0.35 m cells, and the h^2 extrapolation from 0.5 and 0.35 m:

  ====================  =======  ======  ======  ======  ============
  mode                  railcal  0.8 m   0.5 m   0.35 m  extrapolated
  ====================  =======  ======  ======  ======  ============
  vertical bending 1     71.09   +1.6 %  +0.57%  +0.32%  71.13 +0.05%
  cross-section          76.89   +2.4 %  +0.84%  +0.45%  76.94 +0.07%
  lateral bending 1      90.24   +1.5 %  +0.48%  +0.25%  90.28 +0.04%
  torsion 1             115.00   +4.6 %  +1.56%  +0.81% 115.11 +0.10%
  cross-section         116.87   +4.6 %  +1.56%  +0.78% 116.91 +0.03%
  cross-section         122.07   +4.6 %  +1.52%  +0.74% 122.08 +0.01%
  ====================  =======  ======  ======  ======  ============

  MAC >= 0.997 for every pair. The differences are the lattice's discretisation (positive,
  falling as h^2 by a factor 2.0-2.9 per step); railcal's side is converged: its Legendre
  orders raised by one change nothing at 0.01 Hz, and joint_factor 1e2 / 1e3 / 1e4 moves
  the frequencies by <= 0.35 % / - / <= 0.04 %.

  An exudyn beam's cross-section axes are its nodes' axes, so bars of different direction
  cannot share a node: at each grid point there is one node per bar direction, and the
  nodes of a point are welded by stiff ``ObjectConnectorRigidBodySpringDamper`` springs
  (penalty; ``penalty`` times the stiffest bar's EA / a and EI / a).

  exudyn 1.13 exports system matrices dense only (``ComputeLinearizedSystem``), which
  for the lattice (~10^4 coordinates) needs GBs. So :func:`lattice_matrices` asks exudyn
  for the matrices of each distinct element and connector (``ComputeLinearizedSystem`` of a
  two-node system) and adds them into sparse M, K by node coordinates, the way exudyn's
  own assembly adds them; ``tests/test_reference_uniform_carbody.py`` checks on a coarse
  lattice that this gives exudyn's ``ComputeODE2Eigenvalues`` of the whole system.

Modes are paired by the MAC of the displacements at the lattice's grid points (railcal's
panels evaluated there), and named by :func:`mode_name`.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla
from scipy.spatial.transform import Rotation

from calibration.models.box.assembly import assemble
from calibration.models.box.shinkansen import Geometry, free_carbody, shinkansen_vehicle
from calibration.signals.modal import mac_matrix

N_RIGID = 6


@dataclass(frozen=True)
class UniformShell:
    """The uniform shell. Units: t [m], E [Pa], m_h [kg/m^2]."""
    t: float = 0.15
    E: float = 70e9
    nu: float = 1 / 3
    m_h: float = 50.0
    geometry: Geometry = Geometry()

    def __post_init__(self):
        for name in ("t", "E", "m_h"):
            if getattr(self, name) <= 0:
                raise ValueError(f"UniformShell.{name} must be positive, got {getattr(self, name)}")
        if not 0 <= self.nu < 0.5:
            raise ValueError(f"UniformShell.nu must lie in [0, 0.5), got {self.nu}")

    @property
    def Q(self) -> float:
        """Membrane rigidity E t / (1 - nu^2) [N/m]."""
        return self.E * self.t / (1 - self.nu**2)

    @property
    def D(self) -> float:
        """Bending rigidity E t^3 / (12 (1 - nu^2)) [N m]."""
        return self.Q * self.t**2 / 12


@dataclass(frozen=True)
class Modes:
    """Free-free elastic modes: frequencies [Hz] and displacements at ``points`` (n, 3 * n_points)."""
    frequencies: np.ndarray
    shapes: np.ndarray
    points: np.ndarray
    n_dof: int
    seconds: float


# ----------------------------------------------------------------------------- railcal
def uniform_vehicle(shell: UniformShell, *, joint_factor: float = 1e3, order_increase: int = 0,
                    orders: dict | None = None):
    """railcal's box vehicle (free carbody) with every panel the isotropic ``shell``."""
    if joint_factor <= 0:
        raise ValueError(f"joint_factor must be positive, got {joint_factor}")
    Q, D, nu = shell.Q, shell.D, shell.nu
    rig = dict(A11=Q, A22=Q, A12=nu * Q, A66=(1 - nu) / 2 * Q, D11=D, D22=D, D12=nu * D, D66=(1 - nu) / 2 * D)
    v = free_carbody(shinkansen_vehicle(shell.geometry, orders=orders, order_increase=order_increase))
    panels = tuple(replace(p, rho_h=shell.m_h, rigidity=dict(rig)) for p in v.panels)
    joints = tuple(replace(j, k_t=joint_factor * Q, k_r=joint_factor * D) for j in v.joints)
    return replace(v, panels=panels, joints=joints, masses=(), parameters=())


def elastic_modes(K, M, n_modes: int, shift_hz: float = 0.5):
    w2, X = sla.eigsh(K.tocsc(), k=n_modes + N_RIGID, M=M.tocsc(), sigma=-(2 * np.pi * shift_hz) ** 2, which="LM")
    order = np.argsort(w2)
    w2, X = w2[order], X[:, order]
    return np.sqrt(np.abs(w2[N_RIGID:])) / (2 * np.pi), X[:, N_RIGID:]


def box_modes(shell: UniformShell, points: np.ndarray, n_modes: int = 6, **vehicle_options) -> Modes:
    """railcal's free-free elastic modes of ``shell``, displacements at ``points`` (n, 3) [m]."""
    t0 = time.perf_counter()
    model = assemble(uniform_vehicle(shell, **vehicle_options))
    f, X = elastic_modes(model.K0, model.M, n_modes)
    S = np.vstack([model.displacement(_panel_at(model, p, shell.geometry), p) for p in points])
    return Modes(f, (S @ X).T, points, model.n_dof, time.perf_counter() - t0)


def _panel_at(model, point, g: Geometry) -> str:
    """A panel holding ``point`` (any of them on an edge: the joints are stiff)."""
    x, y, z = point
    if abs(z - g.roof_z) < 1e-9:
        return "roof"
    if abs(z - g.floor_z) < 1e-9:
        return "floor_front" if x > g.floor_split else "floor_rear" if x < -g.floor_split else "floor_middle"
    if abs(y - g.width / 2) < 1e-9:
        return "side_left"
    if abs(y + g.width / 2) < 1e-9:
        return "side_right"
    return "end_front" if x > 0 else "end_rear"


# ----------------------------------------------------------------------------- lattice
@dataclass(frozen=True)
class LatticeSettings:
    """Grid and penalty of the exudyn lattice. ``cell`` [m] is the target cell size."""
    cell: float = 0.5
    penalty: float = 1e4
    soft: float = 1e-3  # bar torsion and in-plane bending, relative to their natural scale
    rotary: float = 1e-3  # rotary inertia, relative to the wall's m_h t^2 / 12 (railcal's panels have none)

    def __post_init__(self):
        if self.cell <= 0 or self.penalty <= 0 or self.soft <= 0 or self.rotary <= 0:
            raise ValueError(f"LatticeSettings: cell, penalty and soft must be positive, got {self}")


def lattice_sections(shell: UniformShell, a: float, b: float) -> dict[str, tuple[float, float, float]]:
    """Bars of a lattice cell a x b [m] with a plate's smeared stiffness (nu = 1/3).

    Returns {"axis1", "axis2", "diagonal"}: (E A [N], E I_out [N m^2], mass per length
    [kg/m]) of an interior bar along face axis 1 (representing a strip b wide), along
    axis 2 (a wide) and of each diagonal. Derivation: a diagonal at direction cosines
    (c, s) of axial rigidity k_d per unit area contributes 2 k_d (c^4, s^4, c^2 s^2, c^2 s^2)
    to (C11, C22, C12, C66); a bar along axis 1 contributes E A / b to C11. Matching
    C12 = C66 = Q / 3 (true for nu = 1/3 only) gives k_d, then C11 = C22 = Q gives the bars.
    The bending rigidities follow the same algebra with curvatures (kappa_xy = 2 w_xy) and D.
    """
    if abs(shell.nu - 1 / 3) > 1e-9:
        raise ValueError(f"the lattice reproduces a plate of nu = 1/3 only, got nu = {shell.nu}")
    d = np.hypot(a, b)
    c2, s2 = (a / d) ** 2, (b / d) ** 2
    if max(c2 / s2, s2 / c2) > 3:
        raise ValueError(f"lattice cell {a:.3f} x {b:.3f} m: aspect ratio beyond sqrt(3) needs negative bars")
    out = {}
    for key, rigidity in (("membrane", shell.Q), ("bending", shell.D)):
        k_d = rigidity / 3 / (2 * c2 * s2)  # per unit area
        out[key] = (b * (rigidity - 2 * k_d * c2**2), a * (rigidity - 2 * k_d * s2**2), k_d * a * b / d)
    mu = shell.m_h * a * b / (a + b + 2 * d)
    return {name: (out["membrane"][i], out["bending"][i], mu) for i, name in enumerate(("axis1", "axis2", "diagonal"))}


def _frame(d) -> np.ndarray:
    """Columns e1 = d, e2, e3: a bar's (and its nodes') axes."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    h = np.array([0.0, 0.0, 1.0]) if abs(d[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e2 = np.cross(h, d)
    e2 /= np.linalg.norm(e2)
    return np.column_stack([d, e2, np.cross(d, e2)])


def _direction_key(d) -> tuple:
    d = np.asarray(d, float) / np.linalg.norm(d)
    if d[np.flatnonzero(np.abs(d) > 1e-9)[0]] < 0:
        d = -d
    return tuple(np.round(d, 9) + 0.0)


@dataclass(frozen=True)
class Bar:
    p0: int  # grid point indices
    p1: int
    direction: tuple
    normal: tuple  # face normal (out-of-plane axis)
    EA: float  # [N]
    EI: float  # [N m^2] out of plane
    mu: float  # [kg/m]


@dataclass
class Lattice:
    """Grid points (n, 3) [m] and bars of the lattice."""
    points: np.ndarray
    bars: list = field(default_factory=list)


def build_lattice(shell: UniformShell, settings: LatticeSettings = LatticeSettings()) -> Lattice:
    """Grid points on the box's faces and the bars of every face (a bar on a box edge
    appears once per face, each carrying that face's half strip)."""
    g = shell.geometry
    L, W, H = g.length, g.width, g.roof_z - g.floor_z
    n = [max(1, int(round(s / settings.cell))) for s in (L, W, H)]
    lo = np.array([-L / 2, -W / 2, g.floor_z])
    step = np.array([L, W, H]) / n
    index = {}
    pts = []
    for i in range(n[0] + 1):
        for j in range(n[1] + 1):
            for k in range(n[2] + 1):
                if i in (0, n[0]) or j in (0, n[1]) or k in (0, n[2]):
                    index[(i, j, k)] = len(pts)
                    pts.append(lo + step * (i, j, k))
    lat = Lattice(np.array(pts))
    for normal_axis in range(3):
        a1, a2 = [ax for ax in range(3) if ax != normal_axis]
        for level in (0, n[normal_axis]):
            def pid(p, q, normal_axis=normal_axis, a1=a1, a2=a2, level=level):
                ijk = [0, 0, 0]
                ijk[normal_axis], ijk[a1], ijk[a2] = level, p, q
                return index[tuple(ijk)]

            _add_face(lat, shell, pid, (n[a1], n[a2]), (step[a1], step[a2]), (a1, a2), normal_axis)
    return lat


def _add_face(lat: Lattice, shell: UniformShell, pid, n: tuple, step: tuple, axes: tuple, normal_axis: int):
    """Bars of one rectangular face: n = (n1, n2) cells of step (a, b) [m] along global
    axes (a1, a2); pid(p, q) the grid point index. Bars on the face's border carry half a strip."""
    (n1, n2), (a, b), (a1, a2) = n, step, axes
    sec = lattice_sections(shell, a, b)
    nrm = tuple(np.eye(3)[normal_axis])
    e1, e2 = np.eye(3)[a1], np.eye(3)[a2]
    for p in range(n1 + 1):
        for q in range(n2 + 1):
            for dp, dq, name, border in ((1, 0, "axis1", q in (0, n2)), (0, 1, "axis2", p in (0, n1))):
                if p + dp > n1 or q + dq > n2:
                    continue
                EA, EI, mu = sec[name]
                f = 0.5 if border else 1.0
                d = e1 * dp * a + e2 * dq * b
                lat.bars.append(Bar(pid(p, q), pid(p + dp, q + dq), _direction_key(d), nrm, f * EA, f * EI, f * mu))
            if p < n1 and q < n2:
                EA, EI, mu = sec["diagonal"]
                for (p0, q0), (p1, q1) in (((p, q), (p + 1, q + 1)), ((p + 1, q), (p, q + 1))):
                    d = e1 * (p1 - p0) * a + e2 * (q1 - q0) * b
                    lat.bars.append(Bar(pid(p0, q0), pid(p1, q1), _direction_key(d), nrm, EA, EI, mu))


def build_panel_lattice(shell: UniformShell, size: tuple, n: tuple) -> Lattice:
    """A flat rectangular panel size = (A, B) [m] in the plane z = 0 with n = (n1, n2) cells:
    the lattice of one box face alone, for checks against plate closed forms."""
    (A, B), (n1, n2) = size, n
    pts = [(A * p / n1, B * q / n2, 0.0) for p in range(n1 + 1) for q in range(n2 + 1)]
    lat = Lattice(np.array(pts))
    _add_face(lat, shell, lambda p, q: p * (n2 + 1) + q, (n1, n2), (A / n1, B / n2), (0, 1), 2)
    return lat


def _section(bar: Bar, length: float, shell: UniformShell, soft: float, rotary: float):
    """exudyn BeamSection of a bar in its node axes (_frame of its direction)."""
    import exudyn as exu
    R = _frame(bar.direction)
    nrm = R.T @ np.asarray(bar.normal, float)  # face normal in bar axes (no e1 part)
    inplane = np.cross([1.0, 0.0, 0.0], nrm)  # in-plane transverse axis
    EI_in = soft * bar.EA * length**2 / 12
    GA_out = 12 * bar.EI / length**2  # out of plane: exactly the cubic (Euler-Bernoulli) beam, no locking
    GA_in = 12 * EI_in / length**2  # in plane: a (nearly) pinned bar, as EI_in
    GJ = soft * bar.EI
    C = np.zeros((6, 6))
    C[0, 0] = bar.EA
    # (exudyn's two-node beam integrates shear at one point: no locking, see the test)
    C[1:3, 1:3] = GA_out * np.outer(nrm[1:], nrm[1:]) + GA_in * np.outer(inplane[1:], inplane[1:])
    C[3, 3] = GJ
    # bending about the in-plane transverse axis moves the bar out of plane: E I_out
    C[4:6, 4:6] = bar.EI * np.outer(inplane[1:], inplane[1:]) + EI_in * np.outer(nrm[1:], nrm[1:])
    s = exu.BeamSection()
    s.stiffnessMatrix = C
    s.massPerLength = bar.mu
    s.inertia = rotary * bar.mu * shell.t**2 / 12 * np.eye(3)  # kept > 0: a regular mass matrix
    return s


def _node_ref(point, direction):
    rv = Rotation.from_matrix(_frame(direction)).as_rotvec()
    return list(np.asarray(point, float)) + list(rv)


def build_exudyn_system(shell: UniformShell, lattice: Lattice, settings: LatticeSettings):
    """The whole lattice as one exudyn system (dense export: coarse lattices only).
    Returns (mbs, SC, node_of) with node_of[(point, direction)] the exudyn node."""
    import exudyn as exu
    from exudyn.itemInterface import NodeRigidBodyRotVecLG, ObjectBeamGeometricallyExact
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    node_of, items = _lattice_items(shell, lattice, settings)
    nodes = {key: mbs.AddNode(NodeRigidBodyRotVecLG(referenceCoordinates=_node_ref(lattice.points[key[0]], key[1])))
             for key in node_of}
    for kind, data in items:
        if kind == "beam":
            k0, k1, length, sec = data
            mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[nodes[k0], nodes[k1]], length=length,
                                                       sectionData=sec))
        else:
            k0, k1, kt, kr = data
            _add_weld(mbs, nodes[k0], nodes[k1], k0[1], k1[1], kt, kr)
    mbs.Assemble()
    return mbs, SC, nodes


def _add_weld(mbs, n0, n1, d0, d1, kt, kr):
    """Weld nodes n0, n1 (frames _frame(d0), _frame(d1)) by translational and rotational
    springs kt [N/m], kr [N m/rad]. Each marker is turned back by its node's frame (its localHT),
    so both marker frames are the global axes in the reference configuration: the weld is
    relaxed there, whatever the two nodes' directions."""
    import exudyn as exu
    from exudyn.itemInterface import MarkerNodeRigid, ObjectConnectorRigidBodySpringDamper
    m0, m1 = (mbs.AddMarker(MarkerNodeRigid(nodeNumber=n, localHT=exu.HT(rotation=_frame(d).T, translation=[0.0] * 3)))
              for n, d in ((n0, d0), (n1, d1)))
    mbs.AddObject(ObjectConnectorRigidBodySpringDamper(
        markerNumbers=[m0, m1], stiffness=np.diag([kt] * 3 + [kr] * 3), damping=np.zeros((6, 6))))


def _lattice_items(shell, lattice, settings):
    """Nodes {(point, direction)} and items [("beam", ...), ("weld", ...)]."""
    items, nodes = [], {}
    ea_max = ei_max = 0.0
    for bar in lattice.bars:
        length = float(np.linalg.norm(lattice.points[bar.p1] - lattice.points[bar.p0]))
        k0, k1 = (bar.p0, bar.direction), (bar.p1, bar.direction)
        nodes.setdefault(k0, len(nodes))
        nodes.setdefault(k1, len(nodes))
        items.append(("beam", (k0, k1, length, _section(bar, length, shell, settings.soft, settings.rotary))))
        ea_max, ei_max = max(ea_max, bar.EA / length), max(ei_max, bar.EI / length)
    by_point = {}
    for key in nodes:
        by_point.setdefault(key[0], []).append(key)
    kt, kr = settings.penalty * ea_max, settings.penalty * ei_max
    for keys in by_point.values():
        for k in keys[1:]:
            items.append(("weld", (keys[0], k, kt, kr)))
    return nodes, items


def _item_matrices(kind, data, points):
    """exudyn's (M, K) (12 x 12) of one element or weld, from a two-node system."""
    mbs, _, nodes = _two_node_system(kind, data, points)
    M, K, _ = mbs.ComputeLinearizedSystem()
    return np.asarray(M), np.asarray(K)


def _two_node_system(kind, data, points):
    import exudyn as exu
    from exudyn.itemInterface import NodeRigidBodyRotVecLG, ObjectBeamGeometricallyExact
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    k0, k1 = data[0], data[1]
    n0, n1 = (mbs.AddNode(NodeRigidBodyRotVecLG(referenceCoordinates=_node_ref(points[k[0]], k[1]))) for k in (k0, k1))
    if kind == "beam":
        mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[n0, n1], length=data[2], sectionData=data[3]))
    else:
        _add_weld(mbs, n0, n1, k0[1], k1[1], data[2], data[3])
    mbs.Assemble()
    return mbs, SC, (n0, n1)


def lattice_matrices(shell: UniformShell, lattice: Lattice, settings: LatticeSettings):
    """Sparse M, K of the lattice from exudyn's element and weld matrices; coordinates
    6 per node in the order of ``node_of``. Items equal up to a translation share one
    exudyn evaluation. Returns (M, K, node_of)."""
    nodes, items = _lattice_items(shell, lattice, settings)
    cache, rows, cols, mv, kv = {}, [], [], [], []
    origin = lattice.points[0]
    for kind, data in items:
        k0, k1 = data[0], data[1]
        rel = np.round(lattice.points[k1[0]] - lattice.points[k0[0]], 9)
        if kind == "beam":
            sec = data[3]
            key = (kind, k0[1], k1[1], tuple(rel), round(data[2], 9), sec.massPerLength,
                   tuple(np.round(np.asarray(sec.stiffnessMatrix).ravel(), 3)))
        else:
            key = (kind, k0[1], k1[1], tuple(rel), data[2], data[3])
        if key not in cache:
            pts = {k0[0]: origin, k1[0]: origin + rel}
            cache[key] = _item_matrices(kind, data, pts)
        Me, Ke = cache[key]
        dofs = np.concatenate([6 * nodes[k0] + np.arange(6), 6 * nodes[k1] + np.arange(6)])
        r, c = np.meshgrid(dofs, dofs, indexing="ij")
        rows.append(r.ravel())
        cols.append(c.ravel())
        mv.append(Me.ravel())
        kv.append(Ke.ravel())
    n = 6 * len(nodes)
    r, c = np.concatenate(rows), np.concatenate(cols)
    M = sp.coo_matrix((np.concatenate(mv), (r, c)), shape=(n, n)).tocsr()
    K = sp.coo_matrix((np.concatenate(kv), (r, c)), shape=(n, n)).tocsr()
    return M, (K + K.T) / 2, nodes


def lattice_modes(shell: UniformShell, settings: LatticeSettings = LatticeSettings(), n_modes: int = 6) -> Modes:
    """The exudyn lattice's free-free elastic modes, displacements at its grid points."""
    t0 = time.perf_counter()
    lattice = build_lattice(shell, settings)
    M, K, nodes = lattice_matrices(shell, lattice, settings)
    f, X = elastic_modes(K, M, n_modes)
    first = {}
    for (p, d), i in nodes.items():
        first.setdefault(p, i)
    idx = np.concatenate([6 * first[p] + np.arange(3) for p in range(len(lattice.points))])
    return Modes(f, X[idx].T, lattice.points, M.shape[0], time.perf_counter() - t0)


# ----------------------------------------------------------------------------- pairing
def mode_name(shape: np.ndarray, points: np.ndarray, geometry: Geometry) -> str:
    """A coarse type: vertical / lateral bending (node count), torsion, or cross-section
    (breathing/distortion), from how the section's mean motion and twist vary along x."""
    u = shape.reshape(-1, 3)
    x, y, z = points.T
    zc = (geometry.floor_z + geometry.roof_z) / 2
    xs = np.unique(np.round(x, 6))
    mean = np.array([u[np.isclose(x, xi)].mean(0) for xi in xs])
    twist = np.array([np.mean(u[np.isclose(x, xi), 2] * y[np.isclose(x, xi)] - u[np.isclose(x, xi), 1] *
                              (z[np.isclose(x, xi)] - zc)) / np.mean(y[np.isclose(x, xi)] ** 2 +
                                                                       (z[np.isclose(x, xi)] - zc) ** 2)
                      for xi in xs])
    rms = np.sqrt(np.mean(u**2))
    scores = {"vertical": np.sqrt(np.mean(mean[:, 2] ** 2)), "lateral": np.sqrt(np.mean(mean[:, 1] ** 2)),
              "torsion": np.sqrt(np.mean(twist**2)) * np.sqrt(np.mean(y**2 + (z - zc) ** 2))}
    kind = max(scores, key=scores.get)
    if scores[kind] < 0.5 * rms:
        return "cross-section"
    sig = {"vertical": mean[:, 2], "lateral": mean[:, 1], "torsion": twist}[kind]
    crossings = int(np.sum(np.diff(np.sign(sig[np.abs(sig) > 0.05 * np.abs(sig).max()])) != 0))
    return f"{kind} {'bending ' if kind != 'torsion' else ''}{crossings - 1 if kind != 'torsion' else crossings}"


@dataclass(frozen=True)
class Comparison:
    """Pairs of modes: railcal index, exudyn index, frequencies [Hz], MAC, names."""
    box: Modes
    lattice: Modes
    pairs: tuple  # (i_box, i_lattice, MAC, name)

    @property
    def errors(self) -> np.ndarray:
        """(f_lattice - f_box) / f_box per pair."""
        return np.array([(self.lattice.frequencies[j] - self.box.frequencies[i]) / self.box.frequencies[i]
                         for i, j, _, _ in self.pairs])


def compare(shell: UniformShell = UniformShell(), settings: LatticeSettings = LatticeSettings(), *,
            n_modes: int = 6, n_search: int = 12, **vehicle_options) -> Comparison:
    """railcal's first ``n_modes`` elastic modes, each paired with the exudyn lattice mode
    (among its first ``n_search``) of largest MAC."""
    lat = lattice_modes(shell, settings, n_search)
    box = box_modes(shell, lat.points, n_search, **vehicle_options)
    A = mac_matrix(box.shapes.T, lat.shapes.T)  # shapes are rows here
    pairs = []
    for i in range(n_modes):
        j = int(np.argmax(A[i]))
        pairs.append((i, j, float(A[i, j]), mode_name(box.shapes[i], box.points, shell.geometry)))
    return Comparison(box, lat, tuple(pairs))
