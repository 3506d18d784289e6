"""A Shinkansen-type test vehicle as an extended box-type model (seed section 3.1).

The seed gives no dimensions, masses or rigidities. Every number below is an assumption
stated here once, chosen to be typical of an aluminium double-skin Shinkansen carbody:

* Shell: 24.5 m long, 3.38 m wide (the Shinkansen body width), floor 1.10 m and roof
  3.55 m above the rail (2.45 m shell height); flat roof (a curved roof is a later term).
  Floor split at x = +-5.0 m into front, middle and rear panels (seed Figure 1a).
* Bogie centres at x = +-8.75 m (17.5 m spacing), wheelbase 2.5 m, axle boxes and air
  springs at y = +-1.0 m, yaw dampers at y = +-1.35 m.
* Smeared rigidities from double-skin extrusions, E = 70 GPa, nu = 0.3:
  membrane A = E t / (1 - nu^2) with t the two skins together, bending
  D = 2 E t_s (h/2)^2 / (1 - nu^2) with skin t_s and panel depth h; ribs along x make the
  x-direction stiffer; side panels lose membrane and shear stiffness to the windows.
* Areal masses include interior and seats (the test car has them, seed section 3.1);
  the car has no underfloor equipment, so eight 1 t iron blocks hang under the floor.
* Stationary on the rails (seed Figure 3): wheelsets held, so the axle springs and
  axle-box supports act between the bogie frames and the ground.

``SEARCH_PARAMETERS`` are the factors PSO searches by default (nominal 1): membrane and
bending rigidity of roof, floor and sides, the ends together, and the joint springs.
``FACTOR_SETS`` names the choices a calibration can make (its file records which):
``grouped`` (those) and ``credible`` (18 factors in ranges stated before any fit).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, replace

import numpy as np

from ...data.errors import InputError
from .assembly import BoxModel, BoxVehicle, Joint, Link, PointMass, RigidBody, StiffnessParameter, assemble
from .extended import extend_vehicle
from .panel import Panel


@dataclass(frozen=True)
class Geometry:
    length: float = 24.5
    width: float = 3.38
    floor_z: float = 1.10
    roof_z: float = 3.55
    floor_split: float = 5.0
    bogie_x: float = 8.75
    semi_wheelbase: float = 1.25
    spring_y: float = 1.0
    damper_y: float = 1.35
    bogie_z: float = 0.65


def _orthotropic(E_t_x, E_t_y, shear_factor, D_x, D_y, nu=0.3):
    """Smeared plate properties: membrane from the effective skin thickness along x and y
    (as E t), bending from the skin-pair stiffness along x and y (as D)."""
    f = 1 / (1 - nu**2)
    A11, A22 = f * E_t_x, f * E_t_y
    A12 = nu * (A11 * A22) ** 0.5
    A66 = shear_factor * (E_t_x * E_t_y) ** 0.5 / (2 * (1 + nu))
    D12 = nu * (D_x * D_y) ** 0.5
    D66 = (1 - nu) / 2 * (D_x * D_y) ** 0.5
    return {"A11": A11, "A22": A22, "A12": A12, "A66": A66, "D11": D_x, "D22": D_y, "D12": D12, "D66": D66}


E_AL = 70e9
# per group: (E t_x, E t_y, shear factor, D_x, D_y) [N/m, N/m, -, N m, N m], areal mass [kg/m^2]
MATERIAL = {
    "roof": (_orthotropic(E_AL * 0.0045, E_AL * 0.0035, 1.0, 4.0e5, 8.0e5), 35.0),
    "floor": (_orthotropic(E_AL * 0.0060, E_AL * 0.0045, 1.0, 5.0e5, 2.0e6), 80.0),
    "side": (_orthotropic(E_AL * 0.0045, E_AL * 0.0035, 0.5, 2.0e5, 3.0e5), 40.0),
    "end": (_orthotropic(E_AL * 0.0050, E_AL * 0.0050, 1.0, 5.0e5, 5.0e5), 60.0),
}
JOINTS = {  # k_t [N/m per m], k_r [N m/rad per m]
    "roof_side": (1.0e9, 3.0e5),
    "floor_side": (1.0e9, 5.0e5),
    "floor_floor": (1.0e9, 1.0e6),
    "end": (1.0e9, 3.0e5),
}
ORDERS = {  # Legendre orders (along e1, along e2) per panel: first 12 elastic modes converged
    # to 0.1 % (scripts/check_box_convergence.py); 2709 DOF with the bogies
    "roof": (16, 6), "side_left": (20, 6), "side_right": (20, 6),
    "floor_front": (14, 8), "floor_middle": (15, 8), "floor_rear": (14, 8),
    "end_front": (5, 5), "end_rear": (5, 5),
}
#: the lowest order change a model can take: every panel keeps an order of 1 or more
LOWEST_ORDER_CHANGE = 1 - min(min(o) for o in ORDERS.values())
BOGIE = dict(mass=2500.0, inertia=(1200.0, 1800.0, 2500.0))
SUSPENSION = {  # per element; [N/m] and [N s/m] along x, y, z; seat size on the floor [m]
    "axle_box": dict(k=(1.0e7, 4.0e6, 1.2e6), c=(0.0, 0.0, 1.5e4)),
    "air_spring": dict(k=(1.8e5, 1.8e5, 4.0e5), c=(0.0, 3.0e4, 2.0e4), patch=(0.6, 0.6)),
    "traction_link": dict(k=(1.0e7, 0.0, 0.0), c=(0.0, 0.0, 0.0), patch=(0.4, 2.0)),  # on the bolster
    "yaw_damper": dict(k=(0.0, 0.0, 0.0), c=(2.0e5, 0.0, 0.0), patch=(0.4, 0.4)),
}
IRON_BLOCKS = tuple((x, y, 1000.0) for x in (-6.0, -2.0, 2.0, 6.0) for y in (-0.9, 0.9))
IRON_BLOCK_FOOTPRINT = (1.0, 1.5)  # [m] hung from two crossbeams between the centre sill and a side sill

SEARCH_PARAMETERS = (
    StiffnessParameter("roof_membrane", "panel", "roof", ("A11", "A22", "A12", "A66"), "roof in-plane rigidity"),
    StiffnessParameter("roof_bending", "panel", "roof", ("D11", "D22", "D12", "D66"), "roof bending rigidity"),
    StiffnessParameter("floor_membrane", "panel", "floor", ("A11", "A22", "A12", "A66"), "floor in-plane rigidity"),
    StiffnessParameter("floor_bending", "panel", "floor", ("D11", "D22", "D12", "D66"), "floor bending rigidity"),
    StiffnessParameter("side_membrane", "panel", "side", ("A11", "A22", "A12"), "side in-plane normal rigidity"),
    StiffnessParameter("side_shear", "panel", "side", ("A66",), "side in-plane shear rigidity"),
    StiffnessParameter("side_bending", "panel", "side", ("D11", "D22", "D12", "D66"), "side bending rigidity"),
    StiffnessParameter("end_rigidity", "panel", "end", ("A11", "A22", "A12", "A66", "D11", "D22", "D12", "D66"),
                       "end panels, membrane and bending"),
    StiffnessParameter("roof_side_k_r", "joint", "roof_side", ("k_r",), "roof-side joint rotational spring"),
    StiffnessParameter("floor_side_k_r", "joint", "floor_side", ("k_r",), "floor-side joint rotational spring"),
    StiffnessParameter("roof_side_k_t", "joint", "roof_side", ("k_t",), "roof-side joint translational spring"),
    StiffnessParameter("floor_side_k_t", "joint", "floor_side", ("k_t",), "floor-side joint translational spring"),
)


#: The grouped factors' search range when no prior is given [-]
GROUPED_RANGE = (0.5, 2.0)

_NORMAL, _BENDING = ("A11", "A22", "A12"), ("D11", "D22", "D12", "D66")
#: (factor, range) of the credible set: each range stated *before* any fit from what is
#: physically credible for an aluminium double-skin carbody: in-plane normal rigidity 0.5-2
#: (material and skin thickness fairly well known), in-plane shear 0.1-2 (window and door
#: openings, the extrusions' shear flexibility), bending 0.25-4 (smeared core depth), the end
#: walls 0.1-4 (gangway openings), joint rotational springs 0.25-20 and translational 0.1-10
#: (artificial, hardly known). Unlike the grouped set, the roof's and the floor's in-plane
#: shear is a factor of its own, hence the names ``*_normal`` (``roof_membrane`` of the grouped
#: set moves A66 too).
CREDIBLE_FACTORS = (
    (StiffnessParameter("roof_normal", "panel", "roof", _NORMAL, "roof in-plane normal rigidity"), (0.5, 2.0)),
    (StiffnessParameter("roof_shear", "panel", "roof", ("A66",), "roof in-plane shear rigidity"), (0.1, 2.0)),
    (StiffnessParameter("roof_bending", "panel", "roof", _BENDING, "roof bending rigidity"), (0.25, 4.0)),
    (StiffnessParameter("floor_normal", "panel", "floor", _NORMAL, "floor in-plane normal rigidity"), (0.5, 2.0)),
    (StiffnessParameter("floor_shear", "panel", "floor", ("A66",), "floor in-plane shear rigidity"), (0.1, 2.0)),
    (StiffnessParameter("floor_bending", "panel", "floor", _BENDING, "floor bending rigidity"), (0.25, 4.0)),
    (StiffnessParameter("side_normal", "panel", "side", _NORMAL, "side in-plane normal rigidity"), (0.5, 2.0)),
    (StiffnessParameter("side_shear", "panel", "side", ("A66",), "side in-plane shear rigidity"), (0.1, 2.0)),
    (StiffnessParameter("side_bending", "panel", "side", _BENDING, "side bending rigidity"), (0.25, 4.0)),
    (StiffnessParameter("end_rigidity", "panel", "end", _NORMAL + ("A66",) + _BENDING,
                        "end panels, membrane and bending"), (0.1, 4.0)),
    (StiffnessParameter("roof_side_k_r", "joint", "roof_side", ("k_r",), "roof-side joint rotational spring"),
     (0.25, 20.0)),
    (StiffnessParameter("floor_side_k_r", "joint", "floor_side", ("k_r",), "floor-side joint rotational spring"),
     (0.25, 20.0)),
    (StiffnessParameter("roof_side_k_t", "joint", "roof_side", ("k_t",), "roof-side joint translational spring"),
     (0.1, 10.0)),
    (StiffnessParameter("floor_side_k_t", "joint", "floor_side", ("k_t",), "floor-side joint translational spring"),
     (0.1, 10.0)),
)
#: ... and the joints it frees only in the polish: the end walls' joints (to roof, floor and
#: sides) and the joints between the three floor panels, in the joint ranges above (a swarm
#: over all 18 factors, 200 x 200, ended at 1.45 % on seed Figure 5, these four on their limits)
POLISH_JOINT_FACTORS = tuple(
    (StiffnessParameter(f"{g}_{k}", "joint", g, (k,), f"{g.replace('_', '-')} joint {text} spring"), limits)
    for g in ("end", "floor_floor")
    for k, text, limits in (("k_r", "rotational", (0.25, 20.0)), ("k_t", "translational", (0.1, 10.0))))


#: The windowed set's factor more: the side walls' in-plane shear over their end strips,
#: beyond the windowed middle (solid wall, or door openings). Range stated before any fit on
#: the check seeds: from a door-weakened strip (0.1) to a solid double skin's shear and its
#: ribs' share, which the smeared nominal (windows included) understates tenfold (10).
SIDE_END_SHEAR_RANGE = (0.1, 10.0)


def side_end_shear(end_zone: float) -> StiffnessParameter:
    """The side walls' in-plane shear over ``end_zone`` [m] at each end."""
    return StiffnessParameter("side_end_shear", "panel", "side", ("A66",),
                              f"side in-plane shear over {end_zone:g} m at each end (beyond the windows)",
                              end_zone=end_zone)


@dataclass(frozen=True)
class FactorSet:
    """A named choice of stiffness factors with each one's search range. The swarm and the
    CasADi refinement search all but the last ``polish_only`` factors, which stay nominal
    until the full-model polish frees them (``calibrate_box``)."""
    name: str
    parameters: tuple[StiffnessParameter, ...]
    ranges: tuple[tuple[float, float], ...]
    polish_only: int = 0

    @classmethod
    def from_pairs(cls, name: str, pairs, polish_only: int = 0) -> FactorSet:
        """From (factor, range) pairs, as ``CREDIBLE_FACTORS``."""
        return cls(name, tuple(q for q, _ in pairs), tuple(r for _, r in pairs), polish_only)

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(q.name for q in self.parameters)

    @property
    def swarm_parameters(self) -> tuple[StiffnessParameter, ...]:
        return self.parameters[:len(self.parameters) - self.polish_only]

    @property
    def side_end_zone(self) -> float:
        """The end strips' length [m] of a zoned factor (the windowed set's), else 0."""
        return max((q.end_zone for q in self.parameters), default=0.0)


FACTOR_SETS = {
    # the truth simulator's parameters: membrane and bending of roof, floor and sides (the
    # side's shear apart), the ends together, the roof-side and floor-side joints
    "grouped": FactorSet("grouped", SEARCH_PARAMETERS, (GROUPED_RANGE,) * len(SEARCH_PARAMETERS)),
    # in-plane normal, in-plane shear and bending of roof, floor and sides apart, the ends
    # together, every joint; the end-wall and floor-floor joints freed in the polish
    "credible": FactorSet.from_pairs("credible", CREDIBLE_FACTORS + POLISH_JOINT_FACTORS, len(POLISH_JOINT_FACTORS)),
}
DEFAULT_FACTOR_SET = "grouped"
#: A set made per vehicle: the credible factors and the side walls' end strips, whose length
#: the vehicle gives (:func:`factor_set` with ``side_end_zone``). A side wall with windows in
#: its middle only is soft there and stiff beyond, which one smeared plate cannot be.
WINDOWED = "windowed"


def windowed_factor_set(side_end_zone: float) -> FactorSet:
    """The credible set and the side walls' shear over ``side_end_zone`` [m] at each end;
    InputError (a ValueError) naming a calibration file's key ``side_end_zone_m`` for a
    length that is not a number in (0, half the carbody's length)."""
    half = Geometry().length / 2
    if isinstance(side_end_zone, bool) or not isinstance(side_end_zone, (int, float)) \
            or not 0 < side_end_zone < half:
        raise InputError(f"the side walls' end strips must be a length [m] in (0, {half:g}), got {side_end_zone!r}",
                         key="side_end_zone_m")
    return FactorSet.from_pairs(WINDOWED, CREDIBLE_FACTORS + ((side_end_shear(side_end_zone), SIDE_END_SHEAR_RANGE),)
                                + POLISH_JOINT_FACTORS, len(POLISH_JOINT_FACTORS))


#: The orthotropic set: the windowed set with the cross-direction rigidity of the roof, the
#: floor and the sides a factor of its own. MATERIAL's ratios of cross-direction to lengthwise
#: rigidity are guesses (an extrusion's ribs, cross beams and the roof's curvature set them),
#: and one factor on all four rigidities of a group keeps the guess.
ORTHOTROPIC = "orthotropic"
#: The cross-direction factors' range, stated before any fit: an order of magnitude stiffer
#: (cross beams, ribs across) down to 0.4, where the coupling term nu sqrt(D11 D22), which
#: stays with the lengthwise factor, keeps every plate positive definite over the set's
#: ranges (:func:`indefinite_plates`; the lengthwise ranges' tops are 4 and 2).
ACROSS_RANGE = (0.4, 10.0)
#: The split: (a windowed factor, its lengthwise and coupling terms, its cross-direction term)
ACROSS_SPLITS = tuple((f"{g}_{kind}", along, across) for g in ("roof", "floor", "side")
                      for kind, along, across in (("bending", ("D11", "D12", "D66"), "D22"),
                                                  ("normal", ("A11", "A12"), "A22")))
ZONED = (WINDOWED, ORTHOTROPIC)
#: How far above its limit (:func:`across_limits`) a cross-direction factor over its lengthwise
#: one must stay: the set's own ranges keep 1.11 (0.4 / 4 over 0.09), and at the limit itself
#: the plate's stiffness has a zero energy direction.
DEFINITE_MARGIN = 1.1


@functools.cache
def across_limits() -> dict[str, tuple[str, float]]:
    """{``<factor>_across``: (``<factor>_along``, the ratio across / along at which the plate
    turns indefinite)}: with ``along`` on x11 and x12 and ``across`` on x22 the plate needs
    across / along > x12^2 / (x11 x22) (nu^2 for MATERIAL's plates)."""
    out = {}
    for name, along, across in ACROSS_SPLITS:
        rig = MATERIAL[name.split("_")[0]][0]
        xx, xy = along[0], along[1]
        out[f"{name}_across"] = (f"{name}_along", rig[xy] ** 2 / (rig[xx] * rig[across]))
    return out


def across_partner(name: str) -> tuple[str, float] | None:
    """For a cross-direction factor (:func:`across_limits`; the name may carry a panel copy's
    suffix ``@panel``) its lengthwise partner's name, with the same suffix, and the limiting
    ratio; None for any other factor."""
    base, at, suffix = name.partition("@")
    limit = across_limits().get(base)
    return None if limit is None else (limit[0] + at + suffix, limit[1])


def indefinite_plates(low: dict[str, float], high: dict[str, float], margin: float = DEFINITE_MARGIN) -> list[str]:
    """Where factor ranges (``low``, ``high``: {name: value}; a point if equal) reach a plate
    that is not safely positive definite (:data:`DEFINITE_MARGIN`): for each split pair both
    name, the pair with the lowest across over the highest along, in words."""
    out = []
    for name, lo in low.items():
        partner = across_partner(name)
        top = None if partner is None else high.get(partner[0])
        if top is not None and not lo > margin * partner[1] * top:
            out.append(f"{name} {lo:g} over {partner[0]} {top:g} is {lo / top:.3g}, at or below "
                       f"{margin:g} x {partner[1]:.3g} (where the plate's stiffness loses definiteness)")
    return out


def orthotropic_factor_set(side_end_zone: float) -> FactorSet:
    """The windowed set (:func:`windowed_factor_set`) with each factor of
    :data:`ACROSS_SPLITS` split in two: ``<factor>_along`` takes the lengthwise and coupling
    rigidities in the factor's range, ``<factor>_across`` the cross-direction one in
    :data:`ACROSS_RANGE` (a name means the same rigidities in every set)."""
    ws = windowed_factor_set(side_end_zone)
    split = {name: (along, across) for name, along, across in ACROSS_SPLITS}
    pairs = []
    for q, r in zip(ws.parameters, ws.ranges):
        if q.name not in split:
            pairs.append((q, r))
            continue
        along, across = split[q.name]
        pairs.append((replace(q, name=f"{q.name}_along", terms=along,
                              description=f"{q.description}, lengthwise and coupling"), r))
        pairs.append((StiffnessParameter(f"{q.name}_across", "panel", q.group, (across,),
                                         f"{q.description}, across"), ACROSS_RANGE))
    return FactorSet.from_pairs(ORTHOTROPIC, pairs, ws.polish_only)


def factor_set(name: str | None, side_end_zone: float | None = None) -> FactorSet:
    """The factor set ``name`` (None: the grouped default, as calibration files written
    before factor sets existed); the windowed and orthotropic sets with their
    ``side_end_zone`` [m]. ValueError naming the known sets otherwise, or for a zoned set
    without its zone."""
    if name in ZONED:
        if side_end_zone is None:
            raise ValueError(f"the {name} factor set needs the length of the side walls' end strips "
                             "(a campaign's [vehicle] windowed_length)")
        return windowed_factor_set(side_end_zone) if name == WINDOWED else orthotropic_factor_set(side_end_zone)
    try:
        return FACTOR_SETS[DEFAULT_FACTOR_SET if name is None else name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown box factor set {name!r}; known: {', '.join((*FACTOR_SETS, *ZONED))}") from None


def side_end_zone_of(windowed_length: float, geometry: Geometry = Geometry()) -> float:
    """The end strips' length [m] beyond a centred windowed middle ``windowed_length`` [m]
    long, on the box model's carbody."""
    return (geometry.length - windowed_length) / 2


def floor_panel(x: float, geometry: Geometry = Geometry()) -> str:
    """The floor panel holding the point at ``x`` [m] (split at +-``floor_split``)."""
    xs = geometry.floor_split
    return "floor_front" if x > xs else "floor_rear" if x < -xs else "floor_middle"


def shinkansen_vehicle(geometry: Geometry = Geometry(), orders: dict | None = None,
                       order_increase: int = 0, parameters=SEARCH_PARAMETERS) -> BoxVehicle:
    """The assumed Shinkansen-type test vehicle; ``orders`` overrides panel orders,
    ``order_increase`` adds to every order (convergence studies)."""
    g = geometry
    o = dict(ORDERS, **(orders or {}))
    o = {k: (v[0] + order_increase, v[1] + order_increase) for k, v in o.items()}
    L, W, zf, zr = g.length, g.width, g.floor_z, g.roof_z
    H, xs = zr - zf, g.floor_split
    X, Y, Z, mX, mY = (1, 0, 0), (0, 1, 0), (0, 0, 1), (-1, 0, 0), (0, -1, 0)

    def panel(name, group, centre, e1, e2, a, b):
        rig, rho = MATERIAL[group]
        return Panel(name, group, centre, e1, e2, a, b, o[name], rho, rig)

    front_len = L / 2 - xs
    panels = (
        panel("roof", "roof", (0, 0, zr), X, Y, L, W),
        panel("floor_front", "floor", (xs + front_len / 2, 0, zf), X, Y, front_len, W),
        panel("floor_middle", "floor", (0, 0, zf), X, Y, 2 * xs, W),
        panel("floor_rear", "floor", (-xs - front_len / 2, 0, zf), X, Y, front_len, W),
        panel("side_left", "side", (0, W / 2, zf + H / 2), X, Z, L, H),
        panel("side_right", "side", (0, -W / 2, zf + H / 2), X, Z, L, H),
        panel("end_front", "end", (L / 2, 0, zf + H / 2), Y, Z, W, H),
        panel("end_rear", "end", (-L / 2, 0, zf + H / 2), mY, Z, W, H),
    )
    del mX
    joints = []

    def joint(group, a, b, p0, p1):
        kt, kr = JOINTS[group]
        joints.append(Joint(group, a, b, p0, p1, kt, kr))

    for side, y in (("side_left", W / 2), ("side_right", -W / 2)):
        joint("roof_side", "roof", side, (-L / 2, y, zr), (L / 2, y, zr))
        joint("floor_side", "floor_rear", side, (-L / 2, y, zf), (-xs, y, zf))
        joint("floor_side", "floor_middle", side, (-xs, y, zf), (xs, y, zf))
        joint("floor_side", "floor_front", side, (xs, y, zf), (L / 2, y, zf))
    joint("floor_floor", "floor_rear", "floor_middle", (-xs, -W / 2, zf), (-xs, W / 2, zf))
    joint("floor_floor", "floor_middle", "floor_front", (xs, -W / 2, zf), (xs, W / 2, zf))
    for end, x, floor in (("end_front", L / 2, "floor_front"), ("end_rear", -L / 2, "floor_rear")):
        joint("end", end, "roof", (x, -W / 2, zr), (x, W / 2, zr))
        joint("end", end, floor, (x, -W / 2, zf), (x, W / 2, zf))
        joint("end", end, "side_left", (x, W / 2, zf), (x, W / 2, zr))
        joint("end", end, "side_right", (x, -W / 2, zf), (x, -W / 2, zr))

    bodies, links = [], []
    for i, xb in ((1, g.bogie_x), (2, -g.bogie_x)):
        name = f"bogie{i}"
        floor = "floor_front" if xb > 0 else "floor_rear"
        bodies.append(RigidBody(name, BOGIE["mass"], BOGIE["inertia"], (xb, 0.0, g.bogie_z)))
        for dx in (g.semi_wheelbase, -g.semi_wheelbase):
            for y in (g.spring_y, -g.spring_y):
                p = (xb + dx, y, g.bogie_z)
                links.append(Link(f"{name}_axle_box_{dx:+.2f}_{y:+.1f}", "axle_box", "ground", p, name, p,
                                  **SUSPENSION["axle_box"]))
        for y in (g.spring_y, -g.spring_y):
            links.append(Link(f"{name}_air_spring_{y:+.1f}", "air_spring", floor, (xb, y, zf), name,
                              (xb, y, g.bogie_z), **SUSPENSION["air_spring"]))
        links.append(Link(f"{name}_traction_link", "traction_link", floor, (xb, 0.0, zf), name,
                          (xb, 0.0, g.bogie_z), **SUSPENSION["traction_link"]))
        for y in (g.damper_y, -g.damper_y):
            links.append(Link(f"{name}_yaw_damper_{y:+.2f}", "yaw_damper", floor, (xb, y, zf), name,
                              (xb, y, g.bogie_z), **SUSPENSION["yaw_damper"]))

    masses = tuple(PointMass(f"iron_block_{x:+.0f}_{y:+.1f}", floor_panel(x, g), (x, y, zf), m, IRON_BLOCK_FOOTPRINT)
                   for x, y, m in IRON_BLOCKS)
    return BoxVehicle(tuple(panels), tuple(joints), tuple(bodies), tuple(links), masses, tuple(parameters))


def free_carbody(vehicle: BoxVehicle) -> BoxVehicle:
    """The carbody alone, free in space (no bogies, no suspension): six rigid modes."""
    return replace(vehicle, bodies=(), links=())


def order_change_of(vehicle: BoxVehicle) -> int | None:
    """The ``order_change`` this vehicle's panels were built with (every order the same step
    from :data:`ORDERS`), or None when they were not built that way."""
    steps = {o - n for pn in vehicle.panels if pn.name in ORDERS for o, n in zip(pn.order, ORDERS[pn.name])}
    return steps.pop() if len(steps) == 1 and len(vehicle.panels) == len(ORDERS) else None


def shinkansen_model(order_change: int = 0) -> BoxModel:
    """The assumed Shinkansen-type vehicle, assembled; ``order_change`` is added to every
    panel order (negative: a coarse, fast model for tests)."""
    return assemble(shinkansen_vehicle(order_increase=order_change))


def calibrated_box_model(calibration: dict):
    """The box model a calibration file describes and its factors: (model, {name: factor}),
    the model assembled from the file's ``factor_set`` (files without one: grouped) at its
    panel orders plus ``order_change`` (files without one: 0), every factor it does not name
    nominal, with the file's ``extension`` built in (a diagnosis's extended model:
    :mod:`.extended`). InputError for an unknown set or factor, a factor that is not a positive
    number, or an ``order_change`` that is not an integer."""
    name, zone = calibration.get("factor_set"), calibration.get("side_end_zone_m")
    if (zone is None) != (name not in ZONED):
        raise InputError(f"'side_end_zone_m' goes with factor_set {' or '.join(map(repr, ZONED))} and only with them "
                         f"(factor_set {name!r}, side_end_zone_m {zone!r})", key="side_end_zone_m")
    try:
        factors = factor_set(name, side_end_zone=zone)
    except InputError:  # the end strips' length, named by its own key
        raise
    except ValueError as e:
        raise InputError(str(e), key="factor_set") from None
    params = calibration.get("parameters", {})
    if not isinstance(params, dict):
        raise InputError(f"'parameters' must map names to values, got {type(params).__name__}", key="parameters")
    unknown = sorted(set(params) - set(factors.names))
    if unknown:
        raise InputError(f"box parameter(s) {', '.join(unknown)} unknown to the {factors.name} factor set; known: "
                         f"{', '.join(factors.names)}", key="parameters")
    bad = [n for n, x in params.items()
           if isinstance(x, bool) or not (isinstance(x, (int, float)) and np.isfinite(x) and x > 0)]
    if bad:
        raise InputError(f"box parameter(s) {', '.join(bad)} must be positive numbers", key="parameters")
    order_change = calibration.get("order_change", 0)
    if isinstance(order_change, bool) or not isinstance(order_change, int) or order_change < LOWEST_ORDER_CHANGE:
        raise InputError(f"'order_change' must be an integer >= {LOWEST_ORDER_CHANGE} (every panel order >= 1), got "
                         f"{order_change!r}", key="order_change")
    values = {n: float(params.get(n, 1.0)) for n in factors.names}
    indefinite = indefinite_plates(values, values)
    if indefinite:
        raise InputError("box parameters give a plate that is not positive definite: " + "; ".join(indefinite),
                         key="parameters")
    vehicle = shinkansen_vehicle(order_increase=order_change, parameters=factors.parameters)
    model = assemble(extend_vehicle(vehicle, calibration))
    return model, {n: values[n] for n in model.names}
