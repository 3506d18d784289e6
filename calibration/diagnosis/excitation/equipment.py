"""The extension ``underfloor_equipment``: a rigid mass on a vertical spring-damper under a
floor point, coupled to the structure's modes through their values at the mount (mass,
mounting frequency, damping, mount x and y), fitted to the training FRFs.

A global scan (mount grid x mounting frequency x mass) with the modes held, made on the
baseline's modes and again on the nominal factors' (a baseline calibrated without the
equipment may have bent its factors to mimic the split mode), then joint least-squares
refinement with the factors and dampings."""
from __future__ import annotations

import numpy as np

from ...models.box import BoxModel
from .basis import Modes, ReducedFRFModel
from .context import Context
from .family import Family, Layout
from .fitting import Fitted, basis_at, extension_start, factor_bounds, fit_best
from ...models.box.mount import mount_impedance

#: mass ratios (to the carbody mass) scanned: 0.5-7 %, around the effects catalogue's range
#: of 1-5 % (docs/methods/truth-simulator.md: the search is set around the generator it is tested on)
MASS_RATIOS = (0.005, 0.01, 0.02, 0.04, 0.07)
#: mass ratios fitted: 0.2-12 %, wider than the scan so that the refinement is not stopped at it
MASS_RANGE = (0.002, 0.12)
#: mounting damping ratio fitted; the scan holds 5 % (:data:`SCAN_DAMPING`)
MOUNT_DAMPING = (0.01, 0.3)
#: the scan's mounting damping ratio
SCAN_DAMPING = 0.05
#: mounting frequencies scanned and fitted, as multiples of the comparison band's low and high
#: ends (5.1-31.5 Hz for 6-30 Hz): a little beyond the band, so that a mount tuned to a mode
#: at the band's edge is inside
MOUNT_FREQUENCY = (0.85, 1.05)
#: [m] along the car, the spacing of the scan's mount points
MOUNT_STEP = 1.5
#: the scan grid's extent as a share of the floor's half length and half width: on the
#: Shinkansen-type carbody the fixed grid it replaced, +-10.5 m along and +-1.2 m across
MOUNT_SPAN = (0.86, 0.71)


def floor_extent(model: BoxModel) -> tuple[float, float, float]:
    """(x_min, x_max, half width) [m] of the floor panels."""
    floor = [pn for pn in model.vehicle.panels if pn.group == "floor"]
    x = [pn.centre[0] + sgn * pn.a / 2 for pn in floor for sgn in (-1, 1)]
    return min(x), max(x), max(pn.b for pn in floor) / 2


def mount_grid(model: BoxModel) -> np.ndarray:
    """Mount points (x, y) [m] scanned: every :data:`MOUNT_STEP` along the car, five lines
    across, over the central :data:`MOUNT_SPAN` of the floor."""
    x0, x1, half = floor_extent(model)
    c, h = (x0 + x1) / 2, MOUNT_SPAN[0] * (x1 - x0) / 2
    xs = c + np.arange(-np.floor(h / MOUNT_STEP), np.floor(h / MOUNT_STEP) + 1) * MOUNT_STEP
    ys = np.linspace(-MOUNT_SPAN[1] * half, MOUNT_SPAN[1] * half, 5)
    return np.array([(x, y) for x in xs for y in ys])


def equipment_scan(ctx: Context, modes: Modes, zeta: np.ndarray, red: ReducedFRFModel) -> list[tuple]:
    """(error, mount point, mass ratio, mounting frequency [Hz]) of the scan on ``modes``
    (held, with dampings ``zeta``; every third line), best first: every mount point of
    :func:`mount_grid` at the middle mass ratio, then every ratio at the eight best
    points, each at its best mounting frequency (2 % steps over the band)."""
    s = ctx.settings
    meas = ctx.meas.every(3)
    f = meas.frequency
    w = 2 * np.pi * f[:, None]
    Zi = 1.0 / (modes.omega**2 - w**2 + 2j * zeta * modes.omega * w)  # (n_f, r)
    G_se = (modes.exciter_shape * Zi) @ modes.sensor_shapes.T
    points = mount_grid(ctx.model)
    A = red.mount_rows(points) @ modes.Y  # (n_pts, r)
    fe = np.exp(np.arange(np.log(MOUNT_FREQUENCY[0] * s.band[0]), np.log(MOUNT_FREQUENCY[1] * s.band[1]),
                          np.log(1.02)))
    scale = 1.0 / np.sqrt(2 * (meas.sigma2 + s.floor**2))

    def scan(j, ratios):
        """(error, ratio, mounting frequency) at the best frequency for each mass ratio."""
        a = A[j]
        G_sm = (a * Zi) @ modes.sensor_shapes.T
        G_me = Zi @ (a * modes.exciter_shape)
        G_mm = Zi @ (a * a)
        out = []
        for ratio in ratios:
            kappa = mount_impedance(w[:, 0], ratio * ctx.carbody_mass, fe[:, None], SCAN_DAMPING)  # (n_fe, n_f)
            U = G_se[None] - (kappa * G_me / (1 + kappa * G_mm))[:, :, None] * G_sm[None]
            q = np.log(-w**2 * U / meas.H)
            err = np.sum((q.real**2 + q.imag**2) * scale**2, axis=(1, 2)) / f.size
            i = int(np.argmin(err))
            out.append((float(err[i]), ratio, float(fe[i])))
        return out

    first = sorted((scan(j, (MASS_RATIOS[len(MASS_RATIOS) // 2],))[0][0], j) for j in range(len(points)))
    best = [(e, points[j], r, h) for _, j in first[:8] for e, r, h in scan(j, MASS_RATIOS)]
    best.sort(key=lambda r: r[0])
    return best


def distinct(candidates: list[tuple], n: int) -> list[tuple]:
    """The first ``n`` candidates (error, point, ratio, frequency) that differ from every
    one taken before by more than 5 % in mounting frequency or 3 m in mount point."""
    chosen = []
    for c in candidates:
        if all(abs(c[3] / d[3] - 1) > 0.05 or np.hypot(*(c[1] - d[1])) > 3.0 for d in chosen):
            chosen.append(c)
        if len(chosen) == n:
            break
    return chosen


def fit_equipment(ctx: Context, base: Fitted) -> list[Fitted]:
    """Scan (:func:`equipment_scan`) on the baseline's modes and dampings, and again on the
    nominal factors' modes; refine the best ``settings.starts`` distinct candidates of the
    first and the best of the second, each jointly with its factor set (briefly; the best
    fully, dampings free too). Returns the fits, best first."""
    s = ctx.settings
    p_b, z_b, _ = base.layout.split(base.x)
    p_nom = ctx.nominal
    floor_x0, floor_x1, half = floor_extent(ctx.model)
    f_lo, f_hi = MOUNT_FREQUENCY[0] * s.band[0], MOUNT_FREQUENCY[1] * s.band[1]
    lay_p = Layout(len(p_b), 0, None)
    red_nom = basis_at(ctx, lay_p, np.log(p_nom), None)
    fam_nom = Family.make(red_nom, base.family.slots, base.layout, ctx.default_zeta)
    modes_nom, zeta_nom, _, _ = fam_nom.parts(np.concatenate([np.log(p_nom), np.log(z_b)]))
    sets = []
    for which, p0, modes_zeta, red, n in (("baseline", p_b, base.modes(), base.family.red, s.starts),
                                          ("nominal", p_nom, (modes_nom, zeta_nom), red_nom, 1)):
        found = equipment_scan(ctx, *modes_zeta, red)
        ctx.say(f"underfloor equipment scan on the {which} factors: " + ", ".join(
            f"({pt[0]:g}, {pt[1]:g}) m, {r:g}, {h:.2f} Hz: {e:.0f}" for e, pt, r, h in found[:3]))
        sets += [(p0, c) for c in distinct(found, n)]
    out = []
    for p0, (e, pt, r, h) in sets:
        lay0 = Layout(len(p_b), 0, "equipment")
        head = np.log(p0)
        x_ext = np.array([np.log(r * ctx.carbody_mass), np.log(h), np.log(SCAN_DAMPING), pt[0], pt[1]])
        red = basis_at(ctx, lay0, np.concatenate([head, x_ext]), None)
        slots, z = extension_start(ctx, base, lay0, red, head)
        lay = Layout(len(p_b), slots.n, "equipment")
        lo, hi = factor_bounds(ctx, slots.n)
        lo = np.concatenate([lo, np.log([MASS_RANGE[0] * ctx.carbody_mass, f_lo, MOUNT_DAMPING[0]]),
                             [floor_x0, -half]])
        hi = np.concatenate([hi, np.log([MASS_RANGE[1] * ctx.carbody_mass, f_hi, MOUNT_DAMPING[1]]),
                             [floor_x1, half]])
        x0 = np.concatenate([head, np.log(z), x_ext])
        out.append(("underfloor_equipment", lay, slots, x0, lo, hi, None, red))
    return fit_best(ctx, out)
