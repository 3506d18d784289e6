"""The project's own continuous-time answer for what an FMU must output: the Python model
(``calibration.models``) driven exactly (first-order hold on a fine grid) over a track.

Used by the tests and ``scripts/bench_fmu.py`` to judge the FMUs; it shares nothing with
the C code but the variable list's names.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.signal

from calibration.models.car2d import (GRAVITY, CarExtras, Output, build_car, state_space, static_deflection,
                                      wheel_level_gain, wheelset_positions)
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
                  start: float = 0.0, substeps: int = 20, extras: CarExtras | None = None) -> dict[str, np.ndarray]:
    """Every output of the car FMU ``spec`` at the times ``t`` (uniform), from the car model
    (with ``extras``, an extended one) started in static equilibrium, inputs evaluated
    ``substeps`` times per interval of t."""
    t = np.asarray(t, float)
    dt = (t[1] - t[0]) / substeps
    tf = t[0] + dt * np.arange((len(t) - 1) * substeps + 1)
    z, dz, ddz, _ = rail_inputs(p, profile, speed, tf, start)
    asm = build_car(p, extras=extras)
    xw = wheelset_positions(p)
    free = "wheelset1_z" in asm.dofs  # wheelsets on a flexible track
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
            outs += [Output(f"{v.name}:bogie:{q}", q, f"bogie{1 + wheel // 2}", xw[wheel])
                     for q in ("displacement", "velocity")]
            if free:
                outs += [Output(f"{v.name}:wheelset:{q}", q, f"wheelset{wheel + 1}", xw[wheel])
                         for q in ("displacement", "velocity", "acceleration")]
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
        if free:  # the wheelset's own level, its static deflection and its acceleration
            gw = asm.point_row(f"wheelset{wheel + 1}", xw[wheel])
            w, dw, ddw = (y[:, col[f"{v.name}:wheelset:{q}"]] for q in ("displacement", "velocity", "acceleration"))
            above = wheel_level_gain(p, extras or CarExtras())  # its coordinate is the wheelset's and track's centre
            w, dw, ddw = w + above * z[:, wheel], dw + above * dz[:, wheel], ddw + above * ddz[:, wheel]
            g = g - gw
        else:
            w, dw, ddw = z[:, wheel], dz[:, wheel], ddz[:, wheel]
        primary = -p.k_p * (y[:, col[f"{v.name}:bogie:displacement"]] + g @ q_static - w) \
            - p.c_p * (y[:, col[f"{v.name}:bogie:velocity"]] - dw)
        result[v.name] = primary + p.m_w * (GRAVITY + ddw)
    return result


def smooth_profile(length: float, seed: int, *, dx: float = 0.25, min_wavelength: float = 3.0,
                   max_wavelength: float = 70.0) -> tuple[np.ndarray, np.ndarray, Profile]:
    """A synthetic vertical track profile (German low-disturbance PSD, ``min_wavelength``-
    ``max_wavelength`` band) on a grid, and its cubic-spline interpolant with derivatives."""
    from calibration.models.track_irregularity import german_vertical_psd, synthesise_profile

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
    """Floor accelerations (n_t, n_sensors) [m/s^2] of the reduced box vehicle
    (:class:`calibration.models.box.vehicle_reduction.ReducedVehicle`) at the uniform times ``t`` [s],
    over the track at ``speed`` [m/s] (carbody centre at track distance ``start`` [m] at
    t = 0) with the exciter force ``force`` [N] (given at ``t``, linear in between), started
    in static equilibrium; the rails are evaluated ``substeps`` times per interval of t and
    held linear in between (first-order hold on that fine grid, stepped exactly).

    Only the output samples' states are formed: with a = exp(lambda h) per mode of the state
    matrix and phi1, phi2 the first-order-hold integrals over a sub-step h
    (:mod:`calibration.models.simulate`), the exact recursion over the S = ``substeps``
    sub-steps of one output interval is

        eta[k+1] = a^S eta[k] + sum_{j=0..S} c_j p[k S + j],
        c_0 = a^(S-1) (phi1 - phi2),  c_j = a^(S-1-j) (phi1 - phi2) + a^(S-j) phi2,  c_S = phi2,

    p = (V^-1 B) w the modal inputs on the fine grid, so each output interval's S + 1 input
    samples map to its modal force in one real matrix product, and the recursion runs at
    the output rate (the fine grid's states are never formed)."""
    t = np.asarray(t, float)
    force = np.asarray(force, float)
    if t.ndim != 1 or t.size < 2 or force.shape != t.shape:
        raise ValueError(f"t and force: expected equal 1-D arrays of >= 2 samples, got {t.shape} and {force.shape}")
    S = int(substeps)
    if S < 1:
        raise ValueError(f"substeps = {substeps}; must be >= 1")
    dt = (t[1] - t[0]) / S
    n_t = t.size
    tf = t[0] + dt * np.arange((n_t - 1) * S + 1)
    s = start + speed * tf[:, None] + reduced.wheelset_x[None, :]
    z, slope, _, _ = profile(s)
    w = np.hstack([z, speed * slope, np.interp(tf, t, force)[:, None]])  # (n_fine, 9)
    ss = reduced.state_space(zeta)
    levels = np.array([True] * 4 + [False] * 4 + [True])  # rail levels and the force; not the rates
    x0 = -np.linalg.solve(ss.A, ss.B @ np.where(levels, w[0], 0.0))  # static equilibrium, as the FMU starts
    sim = ModalSimulator(ss, dt, x0=x0)  # the modal decomposition and the sub-step's phi1, phi2
    a, d1, phi2 = sim.a, sim.phi1 - sim.phi2, sim.phi2
    powers = a[None, :] ** np.arange(S + 1)[:, None]  # a^0 .. a^S, (S + 1, n_modes)
    c = np.zeros((S + 1, a.size), complex)
    c[:S] += powers[S - 1::-1] * d1  # a^(S-1-j) (phi1 - phi2), j = 0 .. S-1
    c[1:] += powers[S - 1::-1] * phi2  # a^(S-j) phi2, j = 1 .. S
    Bm = sim.Vinv_B.T  # (n_inputs, n_modes)
    # f_k = sum_j c_j (B_m^T w[k S + j]) = W_k @ F, W_k the interval's inputs (n_inputs, S + 1)
    # flattened, F[(m, j), i] = Bm[m, i] c[j, i]; W real, so F's real and imaginary parts apart
    W = np.lib.stride_tricks.sliding_window_view(w, S + 1, axis=0)[::S].reshape(n_t - 1, -1)
    F = (Bm[:, None, :] * c[None, :, :]).reshape(W.shape[1], a.size)
    f = W @ F.real + 1j * (W @ F.imag)  # (n_t - 1, n_modes)
    eta = np.empty((n_t, a.size), complex)  # eta[0] the initial state, then eta[k+1] = a^S eta[k] + f[k]
    for i in range(a.size):
        eta[:, i] = scipy.signal.lfilter([1.0], [1.0, -powers[S, i]], np.concatenate([[sim.eta[i]], f[:, i]]))
    return (eta @ sim.CV.T).real + w[::S] @ ss.D.T
