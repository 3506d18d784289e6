"""The project's own continuous-time answer for what an FMU must output: the Python model
(``calibration.models``) driven exactly (first-order hold on a fine grid) over a track.

Used by the tests and ``scripts/bench_fmu.py`` to judge the FMUs; it shares nothing with
the C code but the variable list's names.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

from calibration.models.car2d import (GRAVITY, Output, build_car, state_space, static_deflection,
                                      wheelset_positions)
from calibration.models.parameters import CarParameters
from calibration.models.simulate import ModalSimulator

from .variables import CAR_BODIES, OUT_ACC, OUT_CONTACT, OUT_PITCH_RATE, ModelSpec

# level [m], slope [-], curvature [1/m] and its derivative [1/m^2] at track distances s [m]
Profile = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]


def rail_inputs(p: CarParameters, profile: Profile, speed: float, t: np.ndarray, start: float = 0.0):
    """Rail level z_j and its first three time derivatives under wheelsets 1-4, each (n_t, 4),
    for the car's centre at ``start + speed t``."""
    s = start + speed * np.asarray(t, float)[:, None] + wheelset_positions(p)[None, :]
    z, slope, curv, dcurv = profile(s)
    return z, speed * slope, speed**2 * curv, speed**3 * dcurv


def car_reference(spec: ModelSpec, p: CarParameters, profile: Profile, speed: float, t: np.ndarray, *,
                  start: float = 0.0, substeps: int = 20) -> dict[str, np.ndarray]:
    """Every output of the car FMU ``spec`` at the times ``t`` (uniform), from the car model
    started in static equilibrium, inputs evaluated ``substeps`` times per interval of t."""
    t = np.asarray(t, float)
    dt = (t[1] - t[0]) / substeps
    tf = t[0] + dt * np.arange((len(t) - 1) * substeps + 1)
    z, dz, ddz, _ = rail_inputs(p, profile, speed, tf, start)
    asm = build_car(p)
    xw = wheelset_positions(p)
    outs = []
    for v in spec.outputs:
        kind, body, dx, wheel = v.output
        if kind == OUT_ACC:
            b = CAR_BODIES[body]
            x0 = next(bb.x for bb in asm.bodies if bb.name == b)
            outs.append(Output(v.name, "acceleration", b, x0 + dx))
        elif kind == OUT_PITCH_RATE:
            outs.append(Output(v.name, "pitch_rate", CAR_BODIES[body]))
        elif kind == OUT_CONTACT:
            bogie = f"bogie{1 + wheel // 2}"
            outs.append(Output(f"{v.name}:disp", "displacement", bogie, xw[wheel]))
            outs.append(Output(f"{v.name}:vel", "velocity", bogie, xw[wheel]))
        else:
            raise ValueError(f"{v.name}: unknown output kind {kind}")
    ss = state_space(asm, outs)
    y = ModalSimulator(ss, dt, x0="static").step_chunk(np.hstack([z, dz]))[::substeps]
    z, dz, ddz = z[::substeps], dz[::substeps], ddz[::substeps]
    col = {name: k for k, name in enumerate(ss.outputs)}
    q_static = static_deflection(asm)
    result = {}
    for v in spec.outputs:
        kind, _, _, wheel = v.output
        if kind != OUT_CONTACT:
            result[v.name] = y[:, col[v.name]]
            continue
        g = asm.point_row(f"bogie{1 + wheel // 2}", xw[wheel])
        primary = -p.k_p * (y[:, col[f"{v.name}:disp"]] + g @ q_static - z[:, wheel]) \
            - p.c_p * (y[:, col[f"{v.name}:vel"]] - dz[:, wheel])
        result[v.name] = primary + p.m_w * (GRAVITY + ddz[:, wheel])
    return result


def smooth_profile(length: float, seed: int, *, dx: float = 0.25, min_wavelength: float = 3.0,
                   max_wavelength: float = 70.0) -> tuple[np.ndarray, np.ndarray, Profile]:
    """A synthetic vertical track profile (German low-disturbance PSD, ``min_wavelength``-
    ``max_wavelength`` band) on a grid, and its cubic-spline interpolant with derivatives."""
    from calibration.truth.track import german_vertical_psd, synthesise_profile

    s, z = synthesise_profile(german_vertical_psd, length, dx, np.random.default_rng(seed),
                              min_wavelength=min_wavelength, max_wavelength=max_wavelength)
    return s, z, spline_profile(s, z)


def spline_profile(distance, level) -> Profile:
    """The track (distance, level) [m] as the FMUs and the exudyn references read a track file:
    the natural cubic spline through its points, with its first three derivatives."""
    import scipy.interpolate

    spline = scipy.interpolate.CubicSpline(distance, level, bc_type="natural")

    def profile(x):
        return spline(x), spline(x, 1), spline(x, 2), spline(x, 3)

    return profile


def nrmse(y: np.ndarray, ref: np.ndarray) -> float:
    """||y - ref|| / ||ref - mean(ref)||."""
    ref = np.asarray(ref, float)
    return float(np.linalg.norm(np.asarray(y) - ref) / np.linalg.norm(ref - ref.mean()))


def box_reference(reduced, zeta: float, profile: Profile, speed: float, t: np.ndarray, force: np.ndarray, *,
                  start: float = 0.0, substeps: int = 20) -> np.ndarray:
    """Floor accelerations (n_t, n_sensors) of the reduced box vehicle
    (:class:`calibration.models.box.reduction.ReducedVehicle`) at the uniform times ``t``,
    over the track at ``speed`` with the exciter force ``force`` (given at ``t``, linear in
    between), started in static equilibrium; the rails are evaluated ``substeps`` times per
    interval of t."""
    t = np.asarray(t, float)
    dt = (t[1] - t[0]) / substeps
    tf = t[0] + dt * np.arange((len(t) - 1) * substeps + 1)
    s = start + speed * tf[:, None] + reduced.wheelset_x[None, :]
    z, slope, _, _ = profile(s)
    w = np.hstack([z, speed * slope, np.interp(tf, t, force)[:, None]])
    ss = reduced.state_space(zeta)
    levels = np.array([True] * 4 + [False] * 4 + [True])  # rail levels and the force; not the rates
    x0 = -np.linalg.solve(ss.A, ss.B @ np.where(levels, w[0], 0.0))  # static equilibrium, as the FMU starts
    return ModalSimulator(ss, dt, x0=x0).step_chunk(w)[::substeps]
