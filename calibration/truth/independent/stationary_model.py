"""The stationary test's vehicle as one linear system: the shell carbody's modes, two rigid
bogies, the suspension, and what a hidden effect adds (resiliently mounted equipment, an
accelerometer on a bracket).

The carbody enters by its free-free modes (mass-normalised, rigid-body modes included:
the test's motions are small) up to ``max_mode_hz``, plus one *attachment mode*: the
static deflection under the exciter's force that the kept modes miss, so the drive point's
low-frequency flexibility is exact (modal truncation augmentation; without it the modes
above 100 Hz would be missing from the drive point's accelerance). A bogie is a rigid body
whose point r moves by t + theta x r. Each suspension element is a spring and damper per
axis between a patch of floor nodes (their mean displacement) and a bogie point, or
between a bogie and the ground (the wheelsets stand on the rails).

Everything is assembled here into M, C, K; :mod:`.stationary` integrates it with exudyn.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from .shell import ShellModel
from .shell_car import ShellCar, floor_patch


#: a free-free shell mode below this is a rigid-body mode (the first elastic one is near 7 Hz)
RIGID_BELOW_HZ = 0.5


def _skew(r) -> np.ndarray:
    x, y, z = r
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


@dataclass(frozen=True)
class CarbodyModes:
    """The carbody's kept modes: frequencies [Hz] (the attachment mode last), translations of
    every node (n_nodes, 3, n_modes), and which are rigid, elastic or the attachment mode."""

    frequency_hz: np.ndarray
    translations: np.ndarray
    kind: tuple

    def at(self, nodes) -> np.ndarray:
        """Mean translation of ``nodes`` per mode (3, n_modes)."""
        return self.translations[np.asarray(nodes)].mean(axis=0)


def carbody_modes(shell: ShellModel, max_mode_hz: float, load_node: int, count_guess: int = 180) -> CarbodyModes:
    """Free-free modes up to ``max_mode_hz`` and the attachment mode of a vertical unit
    force at ``load_node``."""
    n = count_guess
    while True:
        f, phi = shell.modes(n)
        if f[-1] > max_mode_hz or n >= phi.shape[0] // 2:
            break
        n = int(n * 1.5)
    keep = f <= max_mode_hz
    f, phi = f[keep], phi[:, keep]
    rigid = f < RIGID_BELOW_HZ
    M = shell.M()
    load = np.zeros(phi.shape[0])
    load[6 * load_node + 2] = 1.0
    # inertia relief: the force less what accelerates the free body rigidly, then the body
    # held at three nodes statically determinate (the relieved load needs no reaction there)
    pr = phi[:, rigid]
    relieved = load - M @ (pr @ (pr.T @ load))
    held = _statically_determinate(shell)
    free = np.setdiff1d(np.arange(phi.shape[0]), held)
    psi = np.zeros(phi.shape[0])
    psi[free] = scipy.sparse.linalg.spsolve(shell.K[free][:, free].tocsc(), relieved[free])
    psi -= pr @ (pr.T @ (M @ psi))  # no rigid motion
    el = phi[:, ~rigid]
    w2 = (2 * np.pi * f[~rigid]) ** 2
    psi -= el @ ((el.T @ load) / w2)  # what the kept elastic modes already carry
    psi -= phi @ (phi.T @ (M @ psi))  # M-orthogonal to every kept mode (round-off)
    psi /= np.sqrt(psi @ (M @ psi))
    f_att = np.sqrt(psi @ (shell.K @ psi)) / (2 * np.pi)
    allphi = np.column_stack([phi, psi])
    trans = np.stack([allphi[d::6] for d in range(3)], axis=1)  # (n_nodes, 3, n_modes)
    kind = tuple("rigid" if r else "elastic" for r in rigid) + ("attachment",)
    return CarbodyModes(np.append(f, f_att), trans, kind)


def _statically_determinate(shell: ShellModel) -> np.ndarray:
    """Six translations that hold a free body without constraining it (3-2-1): three at the
    corner A of least x, y, z, two (y, z) at the corner B of most x, one (z) at the corner C
    of most y."""
    p = shell.nodes
    a = int(np.argmin(p @ [1.0, 1.0, 1.0]))
    b = int(np.argmax(p @ [1.0, -1.0, -1.0]))
    c = int(np.argmax(p @ [-1.0, 1.0, -1.0]))
    return np.array([6 * a, 6 * a + 1, 6 * a + 2, 6 * b + 1, 6 * b + 2, 6 * c + 2])


@dataclass
class Element:
    """A spring-damper per axis [N/m, N s/m] between two points, each given by its (3, n)
    map from the system's coordinates to the point's displacement."""

    name: str
    k: tuple
    c: tuple
    a: np.ndarray
    b: np.ndarray | None  # None: the ground


@dataclass
class LinearSystem:
    """M q'' + C q' + K q = b F(t); sensor accelerations = S q''. ``coordinates`` names
    the blocks (carbody modes, bogies, hidden bodies)."""

    M: np.ndarray
    C: np.ndarray
    K: np.ndarray
    b: np.ndarray
    S: np.ndarray
    sensors: tuple
    modes: CarbodyModes
    blocks: dict

    def frf(self, f_hz: np.ndarray) -> np.ndarray:
        """Accelerance of every sensor to the exciter force, (n_f, n_sensors), exact."""
        out = np.empty((len(f_hz), self.S.shape[0]), complex)
        for i, f in enumerate(f_hz):
            w = 2 * np.pi * f
            q = np.linalg.solve(self.K - w * w * self.M + 1j * w * self.C, self.b)
            out[i] = -w * w * (self.S @ q)
        return out

    def poles(self) -> tuple[np.ndarray, np.ndarray]:
        """Natural frequencies |s| / 2 pi [Hz] and damping ratios of the oscillatory poles, ascending."""
        n = self.M.shape[0]
        A = np.block([[np.zeros((n, n)), np.eye(n)],
                      [-np.linalg.solve(self.M, self.K), -np.linalg.solve(self.M, self.C)]])
        s = np.linalg.eigvals(A)
        s = s[s.imag > 1e-9]
        order = np.argsort(np.abs(s))
        s = s[order]
        return np.abs(s) / (2 * np.pi), -s.real / np.abs(s)


@dataclass(frozen=True)
class Mounted:
    """A body hung under the floor on springs: mass [kg], floor point (x, y) [m], vertical
    mount frequency [Hz] (on a fixed floor) and damping ratio; horizontally half as stiff."""

    mass: float
    x: float
    y: float
    frequency_hz: float
    damping_ratio: float


@dataclass(frozen=True)
class Bracket:
    """A sensor on a resilient bracket: which sensor, frequency [Hz], damping ratio."""

    sensor: str
    frequency_hz: float
    damping_ratio: float
    mass: float = 0.2  # [kg] the bracket's moving mass with the accelerometer


def assemble(car: ShellCar, shell: ShellModel, modes: CarbodyModes, damping: np.ndarray, sensors: dict,
             exciter: int, mounted: Mounted | None = None, bracket: Bracket | None = None) -> LinearSystem:
    """The linear system. ``damping``: each elastic and attachment mode's ratio;
    ``sensors``: name -> floor node; ``exciter``: the force's node."""
    nm = modes.frequency_hz.size
    sizes = {"carbody": nm, "bogie_front": 6, "bogie_rear": 6}
    if mounted:
        sizes["equipment"] = 3
    if bracket:
        sizes["bracket"] = 1
    blocks, start = {}, 0
    for name, size in sizes.items():
        blocks[name] = slice(start, start + size)
        start += size
    n = start
    M, C, K = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
    w = 2 * np.pi * modes.frequency_hz
    cb = blocks["carbody"]
    M[cb, cb] = np.eye(nm)
    K[cb, cb] = np.diag(np.where(np.array(modes.kind) == "rigid", 0.0, w ** 2))
    C[cb, cb] = np.diag(2 * damping * w)

    def body_point(block: str, centre, point) -> np.ndarray:
        G = np.zeros((3, n))
        r = np.asarray(point, float) - np.asarray(centre, float)
        s = blocks[block]
        G[:, s.start:s.start + 3] = np.eye(3)
        G[:, s.start + 3:s.start + 6] = -_skew(r)
        return G

    def floor(x, y) -> np.ndarray:
        G = np.zeros((3, n))
        G[:, cb] = modes.at(floor_patch(shell, car, x, y))
        return G

    elements = []
    for name, xb in (("bogie_front", car.bogie_x), ("bogie_rear", -car.bogie_x)):
        s = blocks[name]
        centre = (xb, 0.0, car.bogie_z)
        M[s, s] = np.diag([car.bogie_mass] * 3 + list(car.bogie_inertia))
        for dx in (-car.semi_wheelbase, car.semi_wheelbase):
            for y in (-car.axle_y, car.axle_y):
                elements.append(Element(f"{name}_axle_box", car.axle_k, car.axle_c,
                                        body_point(name, centre, (xb + dx, y, car.bogie_z)), None))
        for y in (-car.spring_y, car.spring_y):
            elements.append(Element(f"{name}_air_spring", car.air_k, car.air_c, floor(xb, y),
                                    body_point(name, centre, (xb, y, car.floor_z))))
            yd = np.sign(y) * car.yaw_damper_y
            elements.append(Element(f"{name}_yaw_damper", (0.0, 0.0, 0.0), (car.yaw_damper_c, 0.0, 0.0),
                                    floor(xb, yd), body_point(name, centre, (xb, yd, car.floor_z))))
        elements.append(Element(f"{name}_traction", (car.traction_k, 0.0, 0.0), (0.0, 0.0, 0.0), floor(xb, 0.0),
                                body_point(name, centre, (xb, 0.0, car.floor_z))))
    if mounted:
        s = blocks["equipment"]
        M[s, s] = mounted.mass * np.eye(3)
        kz = mounted.mass * (2 * np.pi * mounted.frequency_hz) ** 2
        cz = 2 * mounted.damping_ratio * np.sqrt(kz * mounted.mass)
        G = np.zeros((3, n))
        G[:, s] = np.eye(3)
        elements.append(Element("equipment_mount", (kz / 2, kz / 2, kz), (cz / 2, cz / 2, cz), floor(mounted.x,
                                                                                                   mounted.y), G))
    for e in elements:
        rel = e.a if e.b is None else e.a - e.b
        K += rel.T @ np.diag(e.k) @ rel
        C += rel.T @ np.diag(e.c) @ rel
    names = tuple(sensors)
    S = np.zeros((len(names), n))
    for i, name in enumerate(names):
        S[i, cb] = modes.translations[sensors[name], 2]
    if bracket:
        s = blocks["bracket"]
        i = names.index(bracket.sensor)
        kb = bracket.mass * (2 * np.pi * bracket.frequency_hz) ** 2
        cbr = 2 * bracket.damping_ratio * np.sqrt(kb * bracket.mass)
        rel = np.zeros(n)
        rel[s] = 1.0
        rel[cb] -= modes.translations[sensors[bracket.sensor], 2]
        M[s, s] = bracket.mass
        K += kb * np.outer(rel, rel)
        C += cbr * np.outer(rel, rel)
        S[i] = 0.0
        S[i, s] = 1.0  # the accelerometer rides on the bracket
    b = np.zeros(n)
    b[cb] = modes.translations[exciter, 2]
    return LinearSystem(M, C, K, b, S, names, modes, blocks)
