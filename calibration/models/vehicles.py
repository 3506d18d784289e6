"""Vehicles railcal knows, with the source of every number.

INTERCITY_TRAILER is the in-service seed's Hyundai-Rotem 22000 trailer car
(Quirke et al., seed file ``irish-rail-2d-calibration-fdd-ce.txt``):

* m_v, J_v, m_b, J_b, k_p, k_s: Table 7 initial means (manufacturer's values, Tables 5-6).
* L_v, L_b: not stated in the seed. Table 9 gives ten calibrated parameter sets and
  Table 8 the frequencies each reproduces (carbody bounce/pitch, bogie bounce/pitch);
  :func:`infer_seed_geometry` finds the L_v, L_b for which the 6-DOF model with those
  parameter sets reproduces Table 8 best (least squares in relative frequency over all
  forty numbers; bogie bounce is the in-phase, lower mode of the pair, as the seed reports
  it). Table 8 is rounded to 0.01 Hz, so the result is uncertain by about
  +-0.5 % (bogie pitch: 0.005/4.31 -> L_b +-0.12 %, carbody pitch 0.005/2.19 -> L_v
  +-0.23 %). The values below are that optimum rounded to 1 cm; a test re-runs the
  inference and checks them.
* m_w: not in the seed (it does not enter the 6-DOF model); 1400 kg is a typical
  trailer wheelset with brake discs (assumption).
* c_p, c_s: the seed's Table 6 quotes 29 400 N s/m (primary) and 45 000 N s/m
  (secondary, from literature) without saying per what, and never uses damping.
  Taken per wheelset / per bogie with the Table 7 stiffnesses they give bogie bounce a
  damping ratio of 0.39 and carbody pitch 0.33 (``railcal modes``), more than a
  primary damper of an intercity trailer delivers and too much for any output-only
  method to find a frequency in. We assume c_p = 12 000 N s/m per wheelset and
  c_s = 20 000 N s/m per bogie (damping ratios 0.07 carbody bounce, 0.14 carbody pitch,
  0.16 bogie bounce, 0.10 bogie pitch).

MANCHESTER_BENCHMARK is the coach of Iwnicki, "Manchester benchmarks for rail vehicle
simulation", Vehicle System Dynamics 30 (1998) 295-313, as reduced to 2D in Cantero's
TTB-2D (SoftwareX 20, 2022, file TrainProp_Manchester_BenchMark.m): per-corner primary
1.2e6 N/m and 4 kN s/m, per-corner secondary 430 kN/m and 20 kN s/m, doubled for the
2D model's per-wheelset and per-bogie elements; bogie centres 2 x 9.5 m, wheelbase
2 x 1.28 m. The in-service seed's Table 2 lists its 2D frequencies as 1.07, 1.28, 7.47
and 11.68 Hz.

The box-type vehicle (the RTRI seed's Shinkansen-type car, :mod:`calibration.models.box`)
is assembled by :func:`calibration.models.box.assemble`; :func:`box_modes` gives its
labelled modes (``railcal modes --model box``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from .car2d import build_car, frequencies_by_label, undamped_modes
from .parameters import CarParameters

# Seed Table 9 (calibrated parameters per run) and Table 8 (frequencies each reproduces).
SEED_TABLE9 = np.array([
    # m_v,   J_v,    m_b,  J_b,   k_p,     k_s
    [36851, 563743, 3905, 9996, 2771415, 998708],
    [36852, 564818, 3899, 9972, 2765009, 1001119],
    [36851, 555866, 3921, 10075, 2793281, 982377],
    [36852, 563712, 3925, 10057, 2788522, 997787],
    [36851, 552341, 3936, 10130, 2808581, 976691],
    [36853, 566315, 3922, 10039, 2783245, 1002765],
    [36853, 567182, 3909, 9991, 2770168, 1005658],
    [36851, 552355, 3926, 10106, 2801895, 973514],
    [36852, 567039, 3905, 9981, 2767279, 1005466],
    [36851, 556992, 3923, 10077, 2793843, 983675],
], dtype=float)
SEED_TABLE8 = np.array([  # carbody bounce, carbody pitch, bogie bounce, bogie pitch [Hz]
    [1.08, 2.19, 6.53, 4.31], [1.08, 2.19, 6.53, 4.31], [1.07, 2.19, 6.53, 4.31],
    [1.08, 2.19, 6.53, 4.31], [1.07, 2.19, 6.53, 4.31], [1.08, 2.19, 6.53, 4.31],
    [1.08, 2.19, 6.53, 4.31], [1.07, 2.19, 6.53, 4.31], [1.08, 2.19, 6.53, 4.31],
    [1.07, 2.19, 6.53, 4.31],
])
RIGID_LABELS = ("carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch")

# Seed Table 7 ranges (J_v, J_b have none in the seed: +-30 % is our assumption).
SEED_PRIOR_RANGES = {
    "m_v": (36850.0, 40644.0),
    "J_v": (611000.0 * 0.7, 611000.0 * 1.3),
    "m_b": (2778.0, 3859.0),
    "J_b": (3500.0 * 0.7, 3500.0 * 1.3),
    "k_p": (2600000.0, 3550000.0),
    "k_s": (540000.0, 1080000.0),
}


def rigid_frequencies(p: CarParameters) -> dict[str, float]:
    """Undamped frequencies [Hz] of the 6-DOF car by label."""
    return frequencies_by_label(undamped_modes(build_car(p)))


def infer_seed_geometry(x0=(8.0, 1.25)) -> tuple[float, float, float]:
    """L_v, L_b [m] that make seed Table 9 reproduce Table 8; returns (L_v, L_b, rms_rel_error)."""

    def residual(x):
        res = []
        for row, f_target in zip(SEED_TABLE9, SEED_TABLE8):
            m_v, J_v, m_b, J_b, k_p, k_s = row
            p = CarParameters(m_v=m_v, J_v=J_v, m_b=m_b, J_b=J_b, m_w=1400.0, k_p=k_p, c_p=0.0,
                              k_s=k_s, c_s=0.0, L_v=x[0], L_b=x[1])
            f = rigid_frequencies(p)
            res += [f[lbl] / ft - 1.0 for lbl, ft in zip(RIGID_LABELS, f_target)]
        return np.array(res)

    sol = scipy.optimize.least_squares(residual, x0, bounds=([3.0, 0.5], [15.0, 2.5]), xtol=1e-12)
    return float(sol.x[0]), float(sol.x[1]), float(np.sqrt(np.mean(sol.fun**2)))


INTERCITY_TRAILER = CarParameters(
    m_v=38747.0, J_v=611000.0, m_b=3087.0, J_b=3500.0, m_w=1400.0,
    k_p=2840000.0, c_p=12000.0, k_s=720000.0, c_s=20000.0,
    L_v=8.03, L_b=1.15,  # infer_seed_geometry(): 8.032, 1.150 (rms 0.14 % over Table 8)
)


MANCHESTER_BENCHMARK = CarParameters(
    m_v=32000.0, J_v=1.97e6, m_b=2615.0, J_b=1476.0, m_w=1813.0,
    k_p=2 * 1.2e6, c_p=2 * 4.0e3, k_s=2 * 430.0e3, c_s=2 * 20.0e3,
    L_v=9.5, L_b=1.28,
)
SEED_TABLE2_MANCHESTER = {"carbody_bounce": 1.07, "carbody_pitch": 1.28, "bogie_bounce": 7.47, "bogie_pitch": 11.68}

VEHICLES = {"intercity": INTERCITY_TRAILER, "manchester": MANCHESTER_BENCHMARK}


# --------------------------------------------------------------------- the box-type vehicle
BOX_MODES_MAX_HZ = 25.0  # [Hz] suspension modes and the carbody's first elastic modes
_RIGID_NAMES = {"x": "longitudinal", "y": "lateral", "z": "bounce", "roll": "roll", "pitch": "pitch", "yaw": "yaw"}
BOX_RIGID_SHARE = 0.9  # a carbody moving at least this rigidly (by the fit's energy) is on its suspension
BOX_MIN_TYPE_MAC = 0.5  # an elastic mode below this MAC with every mode type is "carbody_elastic"


@dataclass(frozen=True)
class BoxMode:
    """One mode of the box-type vehicle: ``label`` unique within the analysis, ``family``
    its kind: ``carbody_<bounce|pitch|roll|lateral|yaw|longitudinal>`` on the suspension,
    ``bogie_<motion>`` with ``_in_phase`` / ``_anti_phase`` members (or ``bogie1_...``
    alone), or a carbody mode type of :data:`calibration.models.box.mode_types.MODE_TYPES`
    (largest MAC of the floor's vertical motion with the type's pattern). Repeats get
    ``_1``, ``_2``, ... in frequency order. ``damping_ratio``: the suspension dampers' modal
    share (coupling between modes neglected); None for elastic modes, whose structural
    damping the model does not hold."""

    label: str
    family: str
    frequency_hz: float  # [Hz] undamped
    damping_ratio: float | None
    kind: str  # "carbody_rigid", "bogie" or "elastic"


def _floor_and_roof_points(geometry):
    L, W = geometry.length, geometry.width
    floor = [(x, y, geometry.floor_z) for x in np.linspace(-0.45 * L, 0.45 * L, 9) for y in (-0.4 * W, 0.0, 0.4 * W)]
    roof = [(x, y, geometry.roof_z) for x in np.linspace(-0.45 * L, 0.45 * L, 5) for y in (-0.4 * W, 0.4 * W)]
    return floor, roof


def _unique(names: list[str]) -> list[str]:
    count = {n: names.count(n) for n in names}
    seen: dict[str, int] = {}
    out = []
    for n in names:
        if count[n] > 1:
            seen[n] = seen.get(n, 0) + 1
            n = f"{n}_{seen[n]}"
        out.append(n)
    return out


def box_modes(model, parameters, *, max_hz: float = BOX_MODES_MAX_HZ) -> list[BoxMode]:
    """Undamped modes below ``max_hz`` [Hz] of the assembled box-type vehicle ``model``
    (:func:`calibration.models.box.assemble`) at stiffness factors ``parameters`` ({name:
    factor}, missing ones 1), ascending, each labelled by its shape (:class:`BoxMode`)."""
    import types

    from .box.assembly import RIGID_DOFS
    from .box.fit import carbody_mass_matrix
    from .box.mode_types import MODE_TYPES, template
    from .box.parametric_basis import full_modes
    from .box.shinkansen import Geometry, floor_panel

    if not max_hz > 0:
        raise ValueError(f"max_hz = {max_hz}; must be > 0")
    p = np.array([float(parameters.get(n, 1.0)) for n in model.names])
    n = min(40, model.n_dof - 2)
    while True:
        f, X = full_modes(model, p, n)
        if f[-1] > max_hz or n >= model.n_dof - 2:
            break
        n = min(2 * n, model.n_dof - 2)
    keep = f < max_hz
    f, X = f[keep], X[:, keep]
    geometry = Geometry()
    floor, roof = _floor_and_roof_points(geometry)
    D = np.vstack([model.displacement(floor_panel(x, geometry), (x, y, z)) for x, y, z in floor]
                  + [model.displacement("roof", pt) for pt in roof])  # (3 n_points, n_dof)
    R = np.vstack([np.hstack([np.eye(3), -np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])])
                   for x, y, z in floor + roof])  # rigid motion (translation, rotation) at the points
    floor_z = D[2:3 * len(floor):3]
    sensors = [types.SimpleNamespace(position=pt) for pt in floor]
    patterns = {t: template(t, sensors, geometry.length, geometry.width) for t in MODE_TYPES}
    bogie_share = 1.0 - np.einsum("ij,ij->j", X, carbody_mass_matrix(model) @ X)
    bogies = model.vehicle.bodies[:2]
    common = [d for d in RIGID_DOFS if all(d not in rb.fixed for rb in bogies)]

    def bogie_motion(x):
        """The bogies' dominant common rigid DOF and the index of that DOF in each bogie's x."""
        idx = [[model.dof_slices[rb.name].start + [d for d in RIGID_DOFS if d not in rb.fixed].index(d)
                for rb in bogies] for d in common]
        e = [sum(model.M[i, i] * x[i] ** 2 for i in ii) for ii in idx]
        k = int(np.argmax(e))
        return common[k], idx[k]

    # A degenerate bogie pair (the bogies' pitch does not reach the carbody) has any basis of
    # its eigenspace as modes; the solver's is round-off. Recombine it into the in-phase
    # and the anti-phase member, M-normalised.
    for k in range(f.size - 1):
        if (len(bogies) == 2 and min(bogie_share[k], bogie_share[k + 1]) > 0.5
                and abs(f[k + 1] - f[k]) <= 1e-6 * f[k + 1]):
            _, (i1, i2) = bogie_motion(X[:, k])
            pair = X[:, [k, k + 1]].copy()
            Q = pair[[i1, i2]]
            if np.linalg.cond(Q) < 1e8:
                for col, target in ((k, (1.0, 1.0)), (k + 1, (1.0, -1.0))):
                    v = pair @ np.linalg.solve(Q, np.array(target))
                    X[:, col] = v / np.sqrt(v @ (model.M @ v))
    zeta = np.einsum("ij,ij->j", X, model.C @ X) / (2 * 2 * np.pi * np.maximum(f, 1e-12))
    families, kinds = [], []
    for k in range(f.size):
        x = X[:, k]
        if bogie_share[k] > 0.5 and len(bogies) == 2:
            d, (i1, i2) = bogie_motion(x)
            a1, a2 = x[i1], x[i2]
            motion = _RIGID_NAMES[d]
            if min(abs(a1), abs(a2)) < (1 / 3) * max(abs(a1), abs(a2)):
                families.append((f"bogie_{motion}", f"bogie{1 if abs(a1) >= abs(a2) else 2}_{motion}"))
            else:
                families.append((f"bogie_{motion}", f"bogie_{motion}_{'in_phase' if a1 * a2 > 0 else 'anti_phase'}"))
            kinds.append("bogie")
            continue
        d = D @ x
        theta = np.linalg.lstsq(R, d, rcond=None)[0]
        if np.sum((R @ theta) ** 2) >= BOX_RIGID_SHARE * np.sum(d ** 2):
            energy = [np.sum((R[:, j] * theta[j]) ** 2) for j in range(6)]
            family = f"carbody_{_RIGID_NAMES[RIGID_DOFS[int(np.argmax(energy))]]}"
            families.append((family, family))
            kinds.append("carbody_rigid")
            continue
        w = floor_z @ x
        mac = {t: float((pat @ w) ** 2 / ((pat @ pat) * (w @ w))) if w @ w > 0 else 0.0
               for t, pat in patterns.items()}
        best = max(mac, key=mac.get)
        family = best if mac[best] >= BOX_MIN_TYPE_MAC else "carbody_elastic"
        families.append((family, family))
        kinds.append("elastic")
    labels = _unique([name for _, name in families])
    return [BoxMode(lb, fam, float(f[k]), None if kinds[k] == "elastic" else float(zeta[k]), kinds[k])
            for k, (lb, (fam, _)) in enumerate(zip(labels, families))]
