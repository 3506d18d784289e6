"""The exudyn model of one car (vertical plane, a frame moving with the train).

Exudyn's X is forward, Y up (gravity -Y); a positive exudyn rotation lifts the front, so
the campaign's pitch (front down positive) is minus it. The car is:

* the carbody, an ObjectBeamGeometricallyExact2D mesh (10 elements by default) with the
  mass per length of :class:`~.parameters.CarParameters` and EI from its first free-free
  bending; equipment is a point mass fixed to a beam node, or a body on a spring-damper;
* two bogies (ObjectRigidBody2D, bounce and pitch), four wheelsets (mass points); the
  longitudinal coordinates are held by constraints (no longitudinal dynamics);
* per bogie, the two air springs lumped: the bag's gas spring from the carbody to a
  "pipe-air" coordinate, the reservoir's gas spring with the orifice between that
  coordinate and the bogie, and a linear hydraulic damper beside them;
* per wheelset, a bi-linear primary (spring plus damper) to the bogie, a Hertzian contact
  to the rail, the rail mass on pads on a sleeper mass on ballast.

The track: per wheelset, a rail mass on a pad on a sleeper mass on ballast, with the pad
stiffness modulated at the sleeper-passing wavenumber 2 pi / sleeper spacing. It was chosen
over a periodic rail segment moving with the car because it gives the receptance's two
resonances (sleeper on ballast, rail on pad) and the sleeper-passing excitation with four
coordinates per wheelset, and keeps the model small enough to bench; the price is that the
pinned-pinned resonance and wave propagation along the rail are not represented.

The nonlinear laws are exudyn symbolic user functions (evaluated in C++). The irregularity
under each wheelset and the pad modulation change with time; exudyn 1.13.6's symbolic
vectors cannot be indexed by an expression, so one Python pre-step function per time step
sets eight symbolic variables from precomputed tables (about 2 us per step, measured).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import exudyn as exu
import exudyn.itemInterface as ei
import numpy as np
from exudyn.utilities import CreateSymbolicUserFunction

from .components import hertz_compression
from .parameters import GRAVITY, CarParameters

esym = exu.symbolic
H_BEAM, H_BOGIE, H_WHEEL = 1.6, 0.6, 0.45  # [m] reference heights of the nodes
HOLD_BY_SPRING = True


@dataclass
class CarModel:
    """A built car: the exudyn system, its named coordinates' indices and the inputs."""

    SC: object
    mbs: object
    p: CarParameters
    beam_nodes: list
    bogie_nodes: list
    wheel_nodes: list
    wheel_x: np.ndarray
    inputs: list = field(default_factory=list)  # [r_1..r_4, m_1..m_4] symbolic variables
    keep: list = field(default_factory=list)  # symbolic functions (must stay alive)
    rigid: bool = False  # wheelsets held on a rigid rail
    followers: list = field(default_factory=list)  # (1D node, beam or bogie node it rests on)
    x_coordinates: list = field(default_factory=list)  # ODE2 indices of the held coordinates
    wheel_y: list = field(default_factory=list)  # ODE2 indices of the wheelsets' vertical coordinates
    groups: dict = field(default_factory=dict)  # ODE2 indices of the carbody and bogie motions


def _symbolic(m: CarModel, item, fn):
    uf = CreateSymbolicUserFunction(m.mbs, fn, "springForceUserFunction", item)
    m.mbs.SetObjectParameter(item, "springForceUserFunction", uf)
    m.keep.append(uf)


def _coord(mbs, node, i):
    return mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=node, coordinate=i))


def build_car(p: CarParameters, *, stiff_carbody: bool = False, rigid_track: bool = False) -> CarModel:
    """Build the exudyn model of car ``p`` at its static equilibrium for a rigid carbody
    (call :func:`settle` for the beam's sag). ``stiff_carbody`` multiplies EI by 1e4;
    ``rigid_track`` holds the wheelsets on a rigid rail (the seed's 2D model)."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    x = np.asarray(p.x_nodes)
    wheel_x = np.array([p.L_v + p.L_b, p.L_v - p.L_b, -p.L_v + p.L_b, -p.L_v - p.L_b])
    m = CarModel(SC, mbs, p, [], [], [], wheel_x, rigid=rigid_track)
    held = []
    ground = mbs.AddNode(ei.NodePointGround(referenceCoordinates=[0, 0, 0]))
    mg = _coord(mbs, ground, 0)
    zero = esym.Real(0.0)
    m.keep.append(zero)

    def hold(node, i):
        if HOLD_BY_SPRING and i == 0:
            mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[mg, _coord(mbs, node, i)],
                                                                   stiffness=1e9, damping=1e6))
        else:
            mbs.AddObject(ei.CoordinateConstraint(markerNumbers=[mg, _coord(mbs, node, i)]))
        held.append((node, i))

    # carbody beam
    EI = p.EI * (1e4 if stiff_carbody else 1.0)
    m.beam_nodes = add_beam(mbs, x, p.mu, EI, p.bending_damping_ratio, gravity=True)
    i_centre = int(np.argmin(np.abs(x)))
    hold(m.beam_nodes[i_centre], 0)

    def node_at(xe):
        return m.beam_nodes[int(np.argmin(np.abs(x - xe)))]

    for name, mass, xe, mount_hz, zeta in p.equipment:
        nb = node_at(xe)
        if mount_hz is None:  # fixed to the floor: a point mass on the beam node
            o = mbs.AddObject(ei.MassPoint2D(nodeNumber=nb, mass=mass))
            mbs.AddLoad(ei.LoadMassProportional(markerNumber=mbs.AddMarker(ei.MarkerBodyMass(bodyNumber=o)),
                                                loadVector=[0, -GRAVITY, 0]))
        else:
            ne_ = mbs.AddNode(ei.Node1D(referenceCoordinates=[0.0]))
            m.followers.append((ne_, nb))
            mbs.AddObject(ei.ObjectMass1D(nodeNumber=ne_, mass=mass))
            me = _coord(mbs, ne_, 0)
            mbs.AddLoad(ei.LoadCoordinate(markerNumber=me, load=-mass * GRAVITY))
            k = mass * (2 * np.pi * mount_hz) ** 2
            mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(
                markerNumbers=[_coord(mbs, nb, 1), me], stiffness=k, damping=2 * zeta * np.sqrt(k * mass),
                offset=mass * GRAVITY / k))

    loads = p.bogie_loads()
    G = p.hertz_G()
    t = p.track
    for ib, xb in enumerate((p.L_v, -p.L_v)):
        nb = mbs.AddNode(ei.NodeRigidBody2D(referenceCoordinates=[xb, H_BOGIE, 0.0]))
        m.bogie_nodes.append(nb)
        ob = mbs.AddObject(ei.ObjectRigidBody2D(nodeNumber=nb, mass=p.m_b[ib], inertia=p.J_b))
        mbs.AddLoad(ei.LoadMassProportional(markerNumber=mbs.AddMarker(ei.MarkerBodyMass(bodyNumber=ob)),
                                            loadVector=[0, -GRAVITY, 0]))
        hold(nb, 0)
        # air springs: bag [carbody y -> pipe air], reservoir + orifice [pipe air -> bogie y]
        a = p.air
        p0 = p.air_pressure(ib)
        npipe = mbs.AddNode(ei.Node1D(referenceCoordinates=[0.0]))
        m.followers.append((npipe, nb))
        mbs.AddObject(ei.ObjectMass1D(nodeNumber=npipe, mass=a.m_pipe))
        mp = _coord(mbs, npipe, 0)
        mc = _coord(mbs, node_at(xb), 1)
        mby = _coord(mbs, nb, 1)
        bag = mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[mc, mp]))
        res = mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[mp, mby]))
        _symbolic(m, bag, _gas_law(p0, a.v_bag, a.area, a.n, 0.0, 0.0))
        _symbolic(m, res, _gas_law(p0, a.v_res, a.area, a.n, a.c_quadratic, a.c_linear))
        damper = mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[mc, mby], stiffness=0.0,
                                                                        damping=p.c_s))
        if p.secondary_friction > 0:
            _symbolic(m, damper, _friction_damper(p.c_s, p.secondary_friction))
        f_primary = (loads[ib] + p.m_b[ib] * GRAVITY) / 2
        for jw, dx in enumerate((p.L_b, -p.L_b)):
            j = 2 * ib + jw
            nw = mbs.AddNode(ei.NodePoint2D(referenceCoordinates=[xb + dx, H_WHEEL]))
            m.wheel_nodes.append(nw)
            ow = mbs.AddObject(ei.MassPoint2D(nodeNumber=nw, mass=p.m_w))
            mbs.AddLoad(ei.LoadMassProportional(markerNumber=mbs.AddMarker(ei.MarkerBodyMass(bodyNumber=ow)),
                                                loadVector=[0, -GRAVITY, 0]))
            hold(nw, 0)
            prim = mbs.AddObject(ei.ObjectConnectorSpringDamper(
                markerNumbers=[mbs.AddMarker(ei.MarkerNodePosition(nodeNumber=nw)),
                               mbs.AddMarker(ei.MarkerBodyPosition(bodyNumber=ob, localPosition=[dx, 0, 0]))],
                referenceLength=H_BOGIE - H_WHEEL, stiffness=p.k_p, damping=p.c_p))
            _symbolic(m, prim, _primary(f_primary, p.c_p, p.c_p * p.c_p_high_ratio, p.v_knee))
            mwy = _coord(mbs, nw, 1)
            if rigid_track:
                hold(nw, 1)
                continue
            f_contact = f_primary + p.m_w * GRAVITY
            r = esym.Real(f"r{j}", 0.0)
            mod = esym.Real(f"m{j}", 0.0)
            m.inputs.extend([r, mod])
            nr = mbs.AddNode(ei.Node1D(referenceCoordinates=[0.0]))
            mbs.AddObject(ei.ObjectMass1D(nodeNumber=nr, mass=t.m_r))
            ns = mbs.AddNode(ei.Node1D(referenceCoordinates=[0.0]))
            mbs.AddObject(ei.ObjectMass1D(nodeNumber=ns, mass=t.m_s))
            mr, ms = _coord(mbs, nr, 0), _coord(mbs, ns, 0)
            mbs.AddLoad(ei.LoadCoordinate(markerNumber=mr, load=-t.m_r * GRAVITY))
            mbs.AddLoad(ei.LoadCoordinate(markerNumber=ms, load=-t.m_s * GRAVITY))
            contact = mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[mr, mwy]))
            _symbolic(m, contact, _hertz(hertz_compression(f_contact, G), G, r))
            f_pad = f_contact + t.m_r * GRAVITY
            pad = mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(markerNumbers=[ms, mr]))
            _symbolic(m, pad, _pad(f_pad / t.k_pad, t.k_pad, t.c_pad, t.modulation, mod))
            f_ballast = f_pad + t.m_s * GRAVITY
            mbs.AddObject(ei.ObjectConnectorCoordinateSpringDamper(
                markerNumbers=[mg, ms], stiffness=t.k_b, damping=t.c_b, offset=f_ballast / t.k_b))
    # the inputs in the order r_1..r_4, m_1..m_4
    m.inputs = m.inputs[0::2] + m.inputs[1::2]
    mbs.Assemble()
    m.x_coordinates = [int(mbs.GetNodeODE2Index(n)) + i for n, i in held]
    m.groups = {"carbody_y": [int(mbs.GetNodeODE2Index(n)) + 1 for n in m.beam_nodes],
                "bogie_y": [int(mbs.GetNodeODE2Index(n)) + 1 for n in m.bogie_nodes],
                "bogie_pitch": [int(mbs.GetNodeODE2Index(n)) + 2 for n in m.bogie_nodes]}
    m.wheel_y = [int(mbs.GetNodeODE2Index(n)) + 1 for n in m.wheel_nodes]
    return m


def add_beam(mbs, x, mu, EI: float, damping_ratio: float, *, gravity: bool) -> list:
    """Carbody beam: geometrically exact 2D elements between nodes at ``x`` [m], mass per
    length ``mu`` [kg/m] per element, bending stiffness EI [N m^2], Kelvin-Voigt bending
    damping giving ``damping_ratio`` at 10 Hz; axial and shear stiffness high enough
    (1e11 N) to leave the bending modes as Euler-Bernoulli's. Returns the nodes."""
    w1 = 2 * np.pi * 10.0
    nodes = [mbs.AddNode(ei.NodeRigidBody2D(referenceCoordinates=[float(xi), H_BEAM, 0.0])) for xi in x]
    for i, mu_i in enumerate(mu):
        b = mbs.AddObject(ei.ObjectBeamGeometricallyExact2D(
            nodeNumbers=[nodes[i], nodes[i + 1]], length=float(x[i + 1] - x[i]), massPerLength=float(mu_i),
            crossSectionInertia=float(mu_i) * 0.25, bendingStiffness=EI, axialStiffness=1e11, shearStiffness=1e11,
            bendingDamping=2 * damping_ratio / w1 * EI))
        if gravity:
            mbs.AddLoad(ei.LoadMassProportional(markerNumber=mbs.AddMarker(ei.MarkerBodyMass(bodyNumber=b)),
                                                loadVector=[0, -GRAVITY, 0]))
    return nodes


def free_beam_frequencies(x, mu, EI: float, count: int = 3) -> np.ndarray:
    """The first ``count`` free-free bending frequencies [Hz] of the carbody beam alone
    (the rigid-body modes and the axial and shear modes left out)."""
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    add_beam(mbs, x, mu, EI, 0.0, gravity=False)
    mbs.Assemble()
    ss = exu.SimulationSettings()
    f = np.asarray(mbs.ComputeODE2Eigenvalues(ss, convert2Frequencies=True)[0])
    return np.sort(f[f > 0.5])[:count]  # rigid-body modes sit at zero


# ------------------------------------------------------------ symbolic force laws
# Coordinate spring-dampers: u = q(marker 1) - q(marker 0), the returned force f acts as +f on
# marker 0 and -f on marker 1 (a linear spring returns k u).
def _gas_law(p0, volume, area, n, c_q, c_l):
    """Gas spring compressed by u (marker 0 above marker 1 moving together) plus orifice damping."""
    def f(mbs, t, itemNumber, u, v, k, d, offset):
        ratio = volume / (volume - area * u)
        force = (p0 * esym.pow(ratio, n) - 101_325.0) * area
        if c_q > 0 or c_l > 0:
            force = force + c_q * v * esym.abs(v) + c_l * v
        return force
    return f


def _hertz(delta0, G, r):
    """Two wheels' contact, Hertz's law linearised at the static load: stiffness
    1.5 F0 / delta0 on the compression delta0 + r - u, no force when the wheels lift off."""
    k_lin = 1.5 * 2.0 * (delta0 / G) ** 1.5 / delta0

    def f(mbs, t, itemNumber, u, v, k, d, offset):
        return -k_lin * esym.max(delta0 + r - u, esym.Real(0.0))
    return f


def _pad(delta0, k_pad, c_pad, eps, mod):
    """Rail pad of stiffness k_pad (1 + eps mod) compressed by delta0 - u."""
    def f(mbs, t, itemNumber, u, v, k, d, offset):
        return -k_pad * (1.0 + eps * mod) * (delta0 - u) + c_pad * v
    return f


#: relative speed [m/s] under which the dry friction is regularised (linear through zero):
#: small against the secondary's relative velocities (10-30 mm/s rms on the bench's lines)
FRICTION_VELOCITY = 1.0e-3


def _friction_damper(c, friction):
    """Viscous damper ``c`` and dry friction ``friction`` [N], F tanh(v / FRICTION_VELOCITY)."""
    def f(mbs, t, itemNumber, u, v, k, d, offset):
        return c * v + friction * esym.tanh(v / FRICTION_VELOCITY)
    return f


def _primary(f0, c_low, c_high, v_knee):
    """Primary spring (preload f0 in compression) and bi-linear damper; tension positive."""
    def f(mbs, t, itemNumber, deltaL, deltaL_t, stiffness, damping, force):
        a = esym.abs(deltaL_t)
        fd = esym.IfThenElse(a < v_knee, c_low * deltaL_t,
                             esym.sign(deltaL_t) * (c_low * v_knee + c_high * (a - v_knee)))
        return stiffness * deltaL - f0 + fd
    return f
