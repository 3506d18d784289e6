"""The 2D car model of the in-service seed (Figure 2): carbody, two bogies, four wheelsets.

Built from :mod:`calibration.models.assembly` bodies and spring-dampers. Two variants:

* ``wheelsets="rail"`` (6 DOF): wheelsets rigidly on the rail; the rail level under
  wheelset i is the input ``z_rail_i`` (the seed's coupling, Lin & Trethewey 1990).
* ``wheelsets="free"`` (10 DOF): wheelsets are point masses on a vertical contact /
  track spring ``k_contact`` (and damper ``c_contact``) to the rail input.

:class:`CarExtras` adds the physics the seed's car leaves out (issue 7): a carbody centre
of mass off its geometric centre, the carbody's first vertical bending mode, air springs
with a reservoir branch, wheelsets on a flexible track. The truth simulator uses them to
hide effects and the diagnosis to extend the model; zero / None leaves the seed's car.

Wheelset 1 leads: bogie 1 sits at x = +L_v, wheelset 1 at x = L_v + L_b.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg

from .assembly import Assembly, Attachment, Body, ElasticMode, SpringDamper, assemble, beam_bending_shape
from .parameters import CarParameters

RAIL_INPUTS = ("z_rail_1", "z_rail_2", "z_rail_3", "z_rail_4")
GRAVITY = 9.80665  # [m/s^2] standard gravity


def wheelset_positions(p: CarParameters) -> np.ndarray:
    """Longitudinal positions [m] of wheelsets 1..4 in the vehicle frame (1 leads)."""
    return np.array([p.L_v + p.L_b, p.L_v - p.L_b, -p.L_v + p.L_b, -p.L_v - p.L_b])


def bogie_positions(p: CarParameters) -> np.ndarray:
    return np.array([p.L_v, -p.L_v])


@dataclass(frozen=True)
class CarExtras:
    """Physical additions to the seed's 2D car (SI units; the defaults add nothing).

    cog_offset : [m] carbody centre of mass ahead (+) of its geometric centre (J_v stays
        about the centre of mass).
    bending_hz : [Hz] first vertical bending of the carbody (free-free uniform beam shape of
        ``carbody_length``, scaled to 1 at the ends, generalised mass ``bending_mass_ratio``
        x m_v, damping ratio ``bending_damping``); None: a rigid carbody.
    bending_node : the bending's nodes at +- this fraction of the half-length
        (:func:`~calibration.models.assembly.beam_bending_shape`); None: a uniform beam's.
    reservoir_ratio : each air spring gets a reservoir branch in parallel with k_s: a
        stiffness ``reservoir_ratio`` x k_s in series with an orifice damper whose corner
        frequency k_r / (2 pi c_o) is ``reservoir_corner_hz``. The node between them carries
        ``node_mass`` (a massless node would make the mass matrix singular; 1 kg puts the
        node's own pole near -c_o / 1 kg, far above any band of interest).
    bodies, elements : further bodies and spring-dampers added as they are (e.g. equipment
        hung resiliently on a frame).
    hung_in_m_v : the further bodies' masses are part of m_v and J_v (equipment of a carbody
        weighed or calibrated whole): the rigid carbody keeps the rest, its centre of mass
        and inertia moved so that the whole keeps m_v, its centre at ``cog_offset`` and J_v
        about it; the equipment then changes nothing at low frequency, where it moves with
        the carbody, only around its mounts.
    track_stiffness : [N/m] per wheelset: a flexible track. Under each wheelset ``track_mass``
        [kg] of rail and sleepers rests on the track's stiffness (rail pads, ballast) and its
        damping, ``track_damping_ratio`` of the track mass's own critical damping; the rail
        input is the rail's level at the wheel-rail contact (the irregularity between wheel
        and rail), the wheelset on the rail. The wheelset then follows the level with
        T = Z_t / (Z_t + Z_w), Z_t the track's dynamic stiffness and Z_w the wheelset's on
        the vehicle (:func:`wheelset_dynamic_stiffness`): T falls towards m_t / (m_t + m_w)
        above the track's own frequency, with a dip near it on a lightly damped track. The
        wheelset's coordinate is then the centre of mass of wheelset and track mass; the
        wheelset itself is :func:`wheel_level_gain` x the rail level above it. None:
        wheelsets on a rigid rail.
    """

    cog_offset: float = 0.0
    bending_hz: float | None = None
    bending_damping: float = 0.02
    bending_mass_ratio: float = 0.25
    bending_node: float | None = None
    carbody_length: float = 23.0
    reservoir_ratio: float = 0.0
    reservoir_corner_hz: float = 2.5
    node_mass: float = 1.0
    track_stiffness: float | None = None
    track_damping_ratio: float = 0.5  # 70 kN s/m on a 20 MN/m track of 250 kg: a well-damped P2 resonance
    track_mass: float = 250.0
    bodies: tuple[Body, ...] = ()
    elements: tuple[SpringDamper, ...] = ()
    hung_in_m_v: bool = False


#: The additions a calibration file carries (``extras``): CarExtras' scalar fields.
EXTRAS_FIELDS = ("cog_offset", "bending_hz", "bending_damping", "bending_mass_ratio", "bending_node",
                 "carbody_length", "reservoir_ratio", "reservoir_corner_hz", "node_mass", "track_stiffness",
                 "track_damping_ratio", "track_mass", "hung_in_m_v")


#: A calibration file's form of extra bodies: each a point mass hung under the carbody at its
#: x on one spring-damper (equipment on its mounts).
HUNG_KEYS = ("name", "mass", "x", "mount_stiffness", "mount_damping")


def hung_body(name: str, mass: float, x: float, stiffness: float, damping: float) -> tuple[Body, SpringDamper]:
    """A point mass [kg] hung under the carbody at ``x`` [m] on a spring [N/m] and damper [N s/m]."""
    return Body(name, mass, x), SpringDamper(f"{name}_mount", Attachment("carbody", x), Attachment(name, x),
                                             stiffness, damping)


def _hung_to_json(extras: CarExtras) -> list[dict]:
    out = []
    for body in extras.bodies:
        made = [e for e in extras.elements if e.bottom.body == body.name]
        if body.inertia is not None or len(made) != 1 or made[0] != hung_body(body.name, body.mass, body.x,
                                                                           made[0].stiffness, made[0].damping)[1]:
            raise ValueError(f"extra body {body.name!r} is not a point mass hung under the carbody on one mount: "
                             "it has no calibration-file form")
        out.append(dict(zip(HUNG_KEYS, (body.name, float(body.mass), float(body.x), float(made[0].stiffness),
                                      float(made[0].damping)))))
    if len(extras.elements) != len(out):
        raise ValueError("extra spring-dampers other than equipment mounts have no calibration-file form")
    return out


def _finite_number(v) -> bool:
    """A calibration file's number: an int or float (not a bool), finite."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def extras_to_json(extras: CarExtras) -> dict:
    """The additions ``extras`` makes to the seed's car, as a calibration file's ``extras``
    (the fields that differ from the defaults; a bending's shape fields with it; bodies hung
    under the carbody as ``hung_bodies``)."""
    default = CarExtras()
    out = {k: getattr(extras, k) for k in EXTRAS_FIELDS if getattr(extras, k) != getattr(default, k)}
    if extras.bending_hz is not None:
        out.update({k: getattr(extras, k) for k in ("bending_damping", "bending_mass_ratio", "carbody_length")})
    if extras.bodies or extras.elements:
        out["hung_bodies"] = _hung_to_json(extras)
    return out


def extras_from_json(data) -> CarExtras:
    """A calibration file's ``extras`` (ValueError naming what is wrong)."""
    if not isinstance(data, dict):
        raise ValueError(f"'extras' must map names to numbers, got {type(data).__name__}")
    data = dict(data)
    hung = data.pop("hung_bodies", [])
    unknown = sorted(set(data) - set(EXTRAS_FIELDS))
    if unknown:
        raise ValueError(f"unknown extras {unknown}; known: {', '.join(EXTRAS_FIELDS + ('hung_bodies',))}")
    if not isinstance(data.get("hung_in_m_v", False), bool):
        raise ValueError(f"extras.hung_in_m_v must be true or false, got {data['hung_in_m_v']!r}")
    for k, v in data.items():
        if k == "hung_in_m_v":
            continue
        if not (v is None and k in ("bending_hz", "bending_node", "track_stiffness")) and \
                not _finite_number(v):
            raise ValueError(f"extras.{k} must be a finite number, got {v!r}")
    if not isinstance(hung, list):
        raise ValueError("extras.hung_bodies must be a list of bodies")
    bodies, elements = [], []
    for i, h in enumerate(hung):
        if not isinstance(h, dict) or set(h) != set(HUNG_KEYS):
            raise ValueError(f"extras.hung_bodies[{i}] must give exactly {', '.join(HUNG_KEYS)}")
        if not isinstance(h["name"], str) or h["name"] in ("carbody",) or h["name"].startswith(("bogie", "wheelset")):
            raise ValueError(f"extras.hung_bodies[{i}].name must be a new body's name, got {h['name']!r}")
        for k in HUNG_KEYS[1:]:
            v = h[k]
            if not _finite_number(v) or \
                    (k != "x" and not v > 0 and not (k == "mount_damping" and v == 0)):
                raise ValueError(f"extras.hung_bodies[{i}].{k} must be a finite number (positive, but x), got {v!r}")
        b, e = hung_body(h["name"], float(h["mass"]), float(h["x"]), float(h["mount_stiffness"]),
                         float(h["mount_damping"]))
        bodies.append(b)
        elements.append(e)
    return CarExtras(**data, bodies=tuple(bodies), elements=tuple(elements))


def sensor_model_from_json(data) -> tuple[float, float]:
    """A calibration file's ``sensor_model``: (bogie_dx [m], gyro_gain) (ValueError naming what
    is wrong; its ``floor``, :func:`floor_sensors_from_json`, checked too)."""
    data = {} if data is None else data
    if not isinstance(data, dict) or set(data) - {"bogie_dx", "gyro_gain", "floor"}:
        raise ValueError("'sensor_model' must map bogie_dx and gyro_gain to numbers (and floor to sensors)")
    for k, v in data.items():
        if k != "floor" and not _finite_number(v):
            raise ValueError(f"sensor_model.{k} must be a finite number, got {v!r}")
    floor_sensors_from_json(data)
    return float(data.get("bogie_dx", 0.0)), float(data.get("gyro_gain", 1.0))


def floor_sensors_from_json(data) -> dict[str, tuple[float, float]]:
    """A calibration file's ``sensor_model.floor``: {floor accelerometer: (dx [m], gain)}, the
    sensor found dx off its declared x, reading gain x the acceleration there (ValueError
    naming what is wrong)."""
    floor = (data or {}).get("floor") or {}
    if not isinstance(floor, dict):
        raise ValueError("sensor_model.floor must map sensor names to {dx_m, gain}")
    out = {}
    for name, v in floor.items():
        if not isinstance(v, dict) or set(v) != {"dx_m", "gain"} or not all(_finite_number(x) for x in v.values()) \
                or not v["gain"] > 0:
            raise ValueError(f"sensor_model.floor.{name} must be {{dx_m: finite number, gain: positive number}}, "
                             f"got {v!r}")
        out[str(name)] = (float(v["dx_m"]), float(v["gain"]))
    return out


def _carbody_rest(p: CarParameters, ex: CarExtras) -> tuple[float, float, float]:
    """(mass [kg], centre x [m], pitch inertia [kg m^2] about it) of the rigid carbody: m_v
    at ``cog_offset`` with J_v, less the hung bodies when they are part of it."""
    if not (ex.hung_in_m_v and ex.bodies):
        return p.m_v, ex.cog_offset, p.J_v
    m_e = sum(b.mass for b in ex.bodies)
    m = p.m_v - m_e
    x = (p.m_v * ex.cog_offset - sum(b.mass * b.x for b in ex.bodies)) / m if m > 0 else 0.0
    # J about x = 0 of the whole, less the bodies' (point masses), moved to the rest's centre
    J = p.J_v + p.m_v * ex.cog_offset ** 2 - sum(b.mass * b.x ** 2 for b in ex.bodies) - m * x ** 2
    if not (m > 0 and J > 0):
        raise ValueError(f"hung bodies of {m_e:.0f} kg (part of m_v = {p.m_v:.0f} kg) leave the carbody "
                         f"{m:.0f} kg and J {J:.3g} kg m^2: they must leave it a positive mass and inertia")
    return m, x, J


def with_campaign_geometry(p: CarParameters, geometry: dict) -> tuple[CarParameters, dict]:
    """``p`` with the campaign's measured L_v and L_b (its ``[vehicle]`` bogie_semi_spacing and
    semi_wheelbase) where they differ from the calibration's, and what changed: the sensors'
    positions and the rail's timing refer to the campaign's own geometry."""
    given = {"L_v": geometry.get("bogie_semi_spacing"), "L_b": geometry.get("semi_wheelbase")}
    changed = {k: v for k, v in given.items() if v is not None and abs(v - getattr(p, k)) > 1e-6}
    return (p.replace(**changed) if changed else p), changed


def wheel_level_gain(p: CarParameters, extras: CarExtras) -> float:
    """On a flexible track (``extras.track_stiffness``) a wheelset's coordinate is the centre
    of mass of the wheelset and its track mass; the wheelset itself is that plus this
    gain, m_t / (m_w + m_t), times the rail level under it (0 on a rigid rail)."""
    if extras.track_stiffness is None:
        return 0.0
    return float(extras.track_mass / (p.m_w + extras.track_mass))


def carbody_centre(p: CarParameters, extras: CarExtras | None = None) -> float:
    """[m] The rigid carbody's centre of mass in the vehicle frame: its body's ``x``, where
    its outputs' centre and its bending shape's middle are (ValueError when hung bodies leave
    it no positive mass or inertia)."""
    return _carbody_rest(p, CarExtras() if extras is None else extras)[1]


def build_car(p: CarParameters, *, wheelsets: str = "rail", k_contact: float = 1.0e9,
              c_contact: float = 0.0, extras: CarExtras | None = None) -> Assembly:
    """Assemble the 2D car from rigid bodies and spring-dampers (plus ``extras``)."""
    if wheelsets not in ("rail", "free"):
        raise ValueError(f"wheelsets must be 'rail' or 'free', not {wheelsets!r}")
    ex = CarExtras() if extras is None else extras
    if ex.track_stiffness is not None:
        if not (ex.track_stiffness > 0 and ex.track_mass > 0 and ex.track_damping_ratio >= 0):
            raise ValueError(f"a flexible track needs a positive track_stiffness ({ex.track_stiffness}) and "
                             f"track_mass ({ex.track_mass}) and a track_damping_ratio >= 0 "
                             f"({ex.track_damping_ratio})")
        wheelsets = "free"
    xb = bogie_positions(p)
    xw = wheelset_positions(p)
    modes = ()
    if ex.bending_hz is not None:
        modes = (ElasticMode("bending", beam_bending_shape(ex.carbody_length, ex.bending_node), ex.bending_mass_ratio * p.m_v,
                             ex.bending_hz, ex.bending_damping),)
    bodies = [Body("carbody", *_carbody_rest(p, ex), modes)]
    bodies += [Body(f"bogie{i + 1}", p.m_b, xb[i], p.J_b) for i in range(2)]
    elements = [
        SpringDamper(f"secondary{i + 1}", Attachment("carbody", xb[i]), Attachment(f"bogie{i + 1}", xb[i]),
                     p.k_s, p.c_s)
        for i in range(2)
    ]
    if ex.reservoir_ratio > 0:
        k_r = ex.reservoir_ratio * p.k_s
        c_o = k_r / (2 * np.pi * ex.reservoir_corner_hz)
        for i in range(2):
            node = f"reservoir{i + 1}"
            bodies.append(Body(node, ex.node_mass, xb[i]))
            elements.append(SpringDamper(f"{node}_spring", Attachment("carbody", xb[i]), Attachment(node, xb[i]), k_r))
            elements.append(SpringDamper(f"{node}_orifice", Attachment(node, xb[i]), Attachment(f"bogie{i + 1}", xb[i]),
                                         0.0, c_o))
    for j in range(4):
        bogie = f"bogie{1 + j // 2}"
        if wheelsets == "rail":
            below = Attachment(input=RAIL_INPUTS[j])
        elif ex.track_stiffness is None:
            bodies.append(Body(f"wheelset{j + 1}", p.m_w, xw[j]))
            below = Attachment(f"wheelset{j + 1}", xw[j])
            elements.append(SpringDamper(f"contact{j + 1}", below, Attachment(input=RAIL_INPUTS[j]),
                                         k_contact, c_contact))
        else:
            # the wheelset rigidly on the rail, the track mass under it: with u the track's
            # deflection and r the level, the wheelset is at u + r. Its coordinate, their centre
            # of mass y = u + r m_w / (m_w + m_t), has the inertia (m_w + m_t) y'' with no r''
            # term: the wheelset is at y + g r, the track at y - (1 - g) r, g = m_t / (m_w + m_t).
            g = wheel_level_gain(p, ex)
            name = f"wheelset{j + 1}"
            bodies.append(Body(name, p.m_w + ex.track_mass, xw[j]))
            below = Attachment(name, xw[j], input=RAIL_INPUTS[j], gain=g)
            elements.append(SpringDamper(f"track{j + 1}", Attachment(name, xw[j], input=RAIL_INPUTS[j], gain=g - 1.0),
                                         Attachment(fixed=True), ex.track_stiffness,
                                         2 * ex.track_damping_ratio * np.sqrt(ex.track_stiffness * ex.track_mass)))
        elements.append(SpringDamper(f"primary{j + 1}", Attachment(bogie, xw[j]), below, p.k_p, p.c_p))
    return assemble(bodies + list(ex.bodies), elements + list(ex.elements), list(RAIL_INPUTS))


# --------------------------------------------------------------------------- modes
_GROUPS = {
    "carbody_bounce": ("carbody_z",),
    "carbody_pitch": ("carbody_pitch",),
    "carbody_bending": ("carbody_bending",),
    "bogie_bounce": ("bogie1_z", "bogie2_z"),
    "bogie_pitch": ("bogie1_pitch", "bogie2_pitch"),
    "axle_bounce": ("wheelset1_z", "wheelset2_z", "wheelset3_z", "wheelset4_z"),
}


# Families whose modes come one per bogie (both bogies share m_b, J_b): the coordinate of
# each bogie that tells the pair's members apart by their relative sign.
PAIRED_FAMILIES = {"bogie_bounce": ("bogie1_z", "bogie2_z"), "bogie_pitch": ("bogie1_pitch", "bogie2_pitch")}
DEGENERATE_RTOL = 1e-6  # modes of one family closer than this (relative) span one eigenspace
LOCALISED_RATIO = 1 / 3  # a bogie moving less than this x the other (energy < 10 %) is at rest


@dataclass(frozen=True)
class Mode:
    """One vibration mode.

    ``label`` is the mode's family of ``shared/spec/interfaces.md`` v1 (``bogie_bounce``,
    ...), from its kinetic-energy distribution over the DOFs; the two members of a bogie pair
    share it, and calibration targets and identification match on it. ``name`` is unique
    within one analysis (``railcal modes`` prints it as the label, the family beside it):
    the family label, or for a bogie pair ``<family>_in_phase`` / ``<family>_anti_phase``
    (both bogies moving in the same / opposite sense) or ``bogie1_bounce``, ``bogie2_pitch``,
    ... when one bogie alone moves (an asymmetric car); any remaining repeat gets ``_1``,
    ``_2``, ... in frequency order."""

    label: str
    frequency_hz: float  # undamped natural frequency [Hz]
    damped_frequency_hz: float | None  # [Hz]; None when overdamped or undamped analysis
    damping_ratio: float | None
    shape: np.ndarray  # mode shape over the assembly DOFs (undamped: real, mass-normalised)
    energy: dict  # kinetic-energy fraction per DOF
    name: str = ""  # unique label (see above); :func:`undamped_modes` and :func:`damped_modes` set it

    @property
    def family(self) -> str:
        return self.label


def _label(asm: Assembly, shape: np.ndarray) -> tuple[str, dict]:
    ke = np.real(np.conj(shape) * (asm.M @ shape))
    ke = ke / ke.sum()
    energy = {d: float(e) for d, e in zip(asm.dofs, ke)}
    scores = {g: sum(energy.get(d, 0.0) for d in dofs) for g, dofs in _GROUPS.items()}
    return max(scores, key=scores.get), energy


def _symmetric_basis(asm: Assembly, shapes: list[np.ndarray], family: str, mass_normalise: bool) -> list[np.ndarray]:
    """Two shapes spanning one (degenerate) eigenspace of a bogie pair, recombined into the
    in-phase and the anti-phase member: any basis of the space is an eigenbasis, and the
    solver's choice is round-off; this one is fixed by the physics."""
    i1, i2 = (asm.dofs.index(d) for d in PAIRED_FAMILIES[family])
    Q = np.array([[shapes[0][i1], shapes[1][i1]], [shapes[0][i2], shapes[1][i2]]])
    if np.linalg.cond(Q) > 1e8:  # the space does not reach both bogies: leave it
        return shapes
    out = []
    for target in ((1.0, 1.0), (1.0, -1.0)):
        c = np.linalg.solve(Q, np.array(target, dtype=Q.dtype))
        v = c[0] * shapes[0] + c[1] * shapes[1]
        if mass_normalise:
            v = np.real(v) / np.sqrt(np.real(v) @ asm.M @ np.real(v))
        else:
            v = v * (np.linalg.norm(shapes[0]) / np.linalg.norm(v))
        out.append(v)
    return out


def _pair_name(asm: Assembly, family: str, shape: np.ndarray) -> str:
    a1, a2 = (shape[asm.dofs.index(d)] for d in PAIRED_FAMILIES[family])
    big, small = max(abs(a1), abs(a2)), min(abs(a1), abs(a2))
    if small < LOCALISED_RATIO * big:
        return f"bogie{1 if abs(a1) >= abs(a2) else 2}_{family.split('_', 1)[1]}"
    return f"{family}_{'in_phase' if np.real(a1 * np.conj(a2)) > 0 else 'anti_phase'}"


def _named(asm: Assembly, modes: list[Mode], *, mass_normalise: bool) -> list[Mode]:
    """``modes`` (ascending frequency) with unique names; a degenerate bogie pair's shapes
    recombined into its in-phase and anti-phase members first."""
    modes = list(modes)
    for family in PAIRED_FAMILIES:
        if not all(d in asm.dofs for d in PAIRED_FAMILIES[family]):
            continue
        idx = [k for k, m in enumerate(modes) if m.label == family]
        for a, b in zip(idx, idx[1:]):
            fa, fb = modes[a].frequency_hz, modes[b].frequency_hz
            if abs(fb - fa) <= DEGENERATE_RTOL * max(fa, fb):
                sa, sb = _symmetric_basis(asm, [modes[a].shape, modes[b].shape], family, mass_normalise)
                modes[a] = replace(modes[a], shape=sa, energy=_label(asm, sa)[1])
                modes[b] = replace(modes[b], shape=sb, energy=_label(asm, sb)[1])
    names = [_pair_name(asm, m.label, m.shape) if m.label in PAIRED_FAMILIES and
             all(d in asm.dofs for d in PAIRED_FAMILIES[m.label]) else m.label for m in modes]
    count: dict[str, int] = {}
    for n in names:
        count[n] = count.get(n, 0) + 1
    seen: dict[str, int] = {}
    for k, n in enumerate(names):
        if count[n] > 1:
            seen[n] = seen.get(n, 0) + 1
            names[k] = f"{n}_{seen[n]}"
    return [replace(m, name=n) for m, n in zip(modes, names)]


def undamped_modes(asm: Assembly) -> list[Mode]:
    """Undamped modes (K phi = w^2 M phi), ascending frequency, labelled by shape and
    uniquely named (:class:`Mode`)."""
    w2, phi = scipy.linalg.eigh(asm.K, asm.M)
    modes = []
    for i in range(len(w2)):
        f = float(np.sqrt(max(w2[i], 0.0)) / (2 * np.pi))
        label, energy = _label(asm, phi[:, i])
        modes.append(Mode(label, f, None, None, phi[:, i], energy))
    return _named(asm, modes, mass_normalise=True)


def damped_modes(asm: Assembly) -> list[Mode]:
    """Damped modes from the state-space eigenproblem; one per conjugate pair (or real root),
    ascending natural frequency, labelled and named like :func:`undamped_modes`."""
    A = state_matrix(asm)
    lam, vec = scipy.linalg.eig(A)
    n = len(asm.dofs)
    order = np.argsort(np.abs(lam))
    modes, used = [], np.zeros(len(lam), bool)
    for i in order:
        if used[i] or lam[i].imag < -1e-12:
            continue
        used[i] = True
        if abs(lam[i].imag) > 1e-12:
            j = np.argmin(np.abs(lam - np.conj(lam[i])) + used * 1e300)
            used[j] = True
        wn = abs(lam[i])
        zeta = float(-lam[i].real / wn) if wn > 0 else None
        shape = vec[:n, i]
        label, energy = _label(asm, shape)
        fd = float(abs(lam[i].imag) / (2 * np.pi)) if abs(lam[i].imag) > 1e-12 else None
        modes.append(Mode(label, float(wn / (2 * np.pi)), fd, zeta, shape, energy))
    return _named(asm, modes, mass_normalise=False)


def frequencies_by_label(modes: list[Mode]) -> dict[str, float]:
    """Frequency per label. Modes sharing a label (the in-phase and anti-phase bogie pairs)
    are reported by the lowest, the in-phase one: the in-service seed's convention. With its
    Table 9 parameters the pair is 6.530 / 6.590 Hz and its Table 8 says 6.53 Hz."""
    groups: dict[str, list[float]] = {}
    for m in modes:
        groups.setdefault(m.label, []).append(m.frequency_hz)
    return {k: float(min(v)) for k, v in groups.items()}


def pole_shifts(p, labels) -> dict[str, float]:
    """Per mode label, the pole natural frequency |lambda| / 2 pi of car ``p`` over its undamped
    frequency (both the lowest of the label); NaN where either analysis has no such mode.
    Non-proportional damping makes it differ from 1 (0.9 % for the Manchester car's carbody
    pitch); proportional damping leaves every pole on its undamped frequency."""
    asm = build_car(p)
    undamped = frequencies_by_label(undamped_modes(asm))
    damped = frequencies_by_label([m for m in damped_modes(asm) if m.damped_frequency_hz is not None])
    return {lbl: damped[lbl] / undamped[lbl] if lbl in damped and lbl in undamped else float("nan")
            for lbl in labels}


# --------------------------------------------------------------------- state space
def state_matrix(asm: Assembly) -> np.ndarray:
    n = len(asm.dofs)
    Minv = np.linalg.inv(asm.M)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ asm.K, -Minv @ asm.C]])


@dataclass(frozen=True)
class Output:
    """A measured quantity of the model: ``kind`` is one of
    'displacement' [m], 'velocity' [m/s], 'acceleration' [m/s^2] at (body, x) vertically,
    or 'pitch_angle' [rad], 'pitch_rate' [rad/s] of a body."""

    name: str
    kind: str
    body: str
    x: float = 0.0

    @property
    def unit(self) -> str:
        """Its SI unit."""
        return OUTPUT_UNITS[self.kind]


#: a model output's SI unit by its kind (:class:`Output`)
OUTPUT_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2", "pitch_angle": "rad",
                "pitch_rate": "rad/s"}


@dataclass(frozen=True)
class StateSpace:
    """x' = A x + B w, y = C x + D w with x = [q; q'], w = [u; u']."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    outputs: tuple[str, ...]
    inputs: tuple[str, ...]


def state_space(asm: Assembly, outputs: list[Output]) -> StateSpace:
    n = len(asm.dofs)
    m = len(asm.inputs)
    Minv = np.linalg.inv(asm.M)
    A = state_matrix(asm)
    B = np.vstack([np.zeros((n, 2 * m)), np.hstack([Minv @ asm.B_k, Minv @ asm.B_c])])
    acc_x = np.hstack([-Minv @ asm.K, -Minv @ asm.C])  # q'' = acc_x x + acc_w w
    acc_w = np.hstack([Minv @ asm.B_k, Minv @ asm.B_c])
    C = np.zeros((len(outputs), 2 * n))
    D = np.zeros((len(outputs), 2 * m))
    for r, o in enumerate(outputs):
        if o.kind in ("pitch_angle", "pitch_rate"):
            g = np.zeros(n)
            g[asm.dof(f"{o.body}_pitch")] = 1.0
        else:
            g = asm.point_row(o.body, o.x)
        if o.kind in ("displacement", "pitch_angle"):
            C[r, :n] = g
        elif o.kind in ("velocity", "pitch_rate"):
            C[r, n:] = g
        elif o.kind == "acceleration":
            C[r] = g @ acc_x
            D[r] = g @ acc_w
        else:
            raise ValueError(f"unknown output kind {o.kind!r} for {o.name}")
    inputs = tuple(asm.inputs) + tuple(f"d{u}" for u in asm.inputs)
    return StateSpace(A, B, C, D, tuple(o.name for o in outputs), inputs)


def output_rows(asm: Assembly, outputs: list[Output]) -> tuple[np.ndarray, np.ndarray]:
    """(rows, power): each output's row over the DOFs (its displacement or pitch angle is
    rows @ q) and the power of i w that makes it a velocity (1) or acceleration (2)."""
    rows = np.zeros((len(outputs), len(asm.dofs)))
    power = np.zeros(len(outputs))
    for r, o in enumerate(outputs):
        if o.kind in ("pitch_angle", "pitch_rate"):
            rows[r, asm.dof(f"{o.body}_pitch")] = 1.0
        else:
            rows[r] = asm.point_row(o.body, o.x)
        power[r] = {"displacement": 0, "pitch_angle": 0, "velocity": 1, "pitch_rate": 1, "acceleration": 2}[o.kind]
    return rows, power


def dynamic_stiffness(K: np.ndarray, M: np.ndarray, C: np.ndarray, B_k: np.ndarray, B_c: np.ndarray,
                      w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(D, F) of an assembly's matrices at angular frequencies ``w``: D(w) q = F(w) u,
    (n_freq, n_dof, n_dof) and (n_freq, n_dof, n_input)."""
    jw = 1j * w[:, None, None]
    return K[None] - (w * w)[:, None, None] * M[None] + jw * C[None], B_k[None] + jw * B_c[None]


def frequency_response(asm: Assembly, outputs: list[Output], frequency: np.ndarray) -> np.ndarray:
    """Complex response of ``outputs`` to unit harmonic rail levels, (n_freq, n_out, n_input):
    y(w) = H(w) u(w) with u the inputs' levels (their rates i w u included)."""
    w = 2 * np.pi * np.asarray(frequency, float)
    Hq = np.linalg.solve(*dynamic_stiffness(asm.K, asm.M, asm.C, asm.B_k, asm.B_c, w))  # (n_f, n_dof, n_in)
    rows, power = output_rows(asm, outputs)
    return (1j * w[:, None, None]) ** power[None, :, None] * (rows @ Hq)


def wheelset_dynamic_stiffness(p: CarParameters, frequency: np.ndarray, wheelset: int) -> np.ndarray:
    """[N/m] The seed's car's dynamic stiffness at wheelset ``wheelset`` (1-4) as its rail
    sees it: the force its contact carries per unit of its vertical displacement at
    ``frequency`` [Hz] (complex), its own inertia and the primary suspension, bogie and
    carbody above it, the other wheelsets held on a rigid rail. A flexible track under it, of
    dynamic stiffness Z_t, passes the rail's level as Z_t / (Z_t + Z_w)."""
    asm = build_car(p, wheelsets="free", k_contact=1.0)
    w = 2 * np.pi * np.asarray(frequency, float)
    D, _ = dynamic_stiffness(asm.K, asm.M, asm.C, asm.B_k, asm.B_c, w)
    j = asm.dof(f"wheelset{wheelset}_z")
    D[:, j, j] -= 1.0  # its own contact is the rail's side
    # the other wheelsets on a rigid rail do not move: their coordinates drop out
    rest = [i for i, d in enumerate(asm.dofs) if i != j and not d.startswith("wheelset")]
    coupled = np.linalg.solve(D[:, rest][:, :, rest], D[:, rest, j][:, :, None])[:, :, 0]
    return D[:, j, j] - np.einsum("fr,fr->f", D[:, j, rest], coupled)


def static_deflection(asm: Assembly, gravity: float = GRAVITY) -> np.ndarray:
    """Static displacement of every DOF [m / rad] under gravity (rails at zero level)."""
    f = np.zeros(len(asm.dofs))
    for b in asm.bodies:
        f[asm.dof(f"{b.name}_z")] = -b.mass * gravity
    return np.linalg.solve(asm.K, f)
