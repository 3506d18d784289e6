"""The stationary test's vehicle for the independent truth: a Shinkansen-type carbody meshed
in flat shell elements (:mod:`.shell`), with windows cut out of its sides, on two rigid
bogies whose wheelsets stand on the rails.

The seed (section 3.1) describes the vehicle but gives no dimensions, masses or
rigidities. The dimensions and masses below are the typical Shinkansen figures railcal
states for its box model (24.5 m x 3.38 m shell, floor 1.10 m and roof 3.55 m above the
rail, bogies at +-8.75 m, eight 1 t iron blocks under the floor since the test car had no
underfloor equipment); they are restated here as data, not shared as code. The structure
is this module's own: double-skin aluminium extrusions (E = 70 GPa) of stated skins and
depths, a side wall with real window openings (the box model smears them into a softer
plate), rigid corners instead of joint springs, the iron blocks' masses on the floor nodes
under their footprints. Its rigidities were chosen so that the first vertical bending lies
near 10 Hz, the range of Shinkansen carbodies (seed Figure 5 shows the test car's modes;
its values are not in the text we hold).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .shell import Mesher, Section, ShellModel, double_skin

E_AL, NU_AL = 70.0e9, 0.3


def _x_grid(length: float, step: float) -> np.ndarray:
    n = int(round(length / step))
    return np.round(-length / 2 + step * np.arange(n + 1), 6)


@dataclass(frozen=True)
class ShellCar:
    """Dimensions [m], sections, masses [kg] and suspension [N/m, N s/m] of the test car."""

    length: float = 24.5
    width: float = 3.38
    floor_z: float = 1.10
    roof_z: float = 3.55
    step_x: float = 0.35  # element length; the sensor stations (every 2.8 m) and the exciter sit on nodes
    y_lines: tuple = (0.0, 0.4, 0.8, 1.0, 1.2, 1.35)  # floor and roof node lines (mirrored), and the sides
    z_lines: tuple = (1.10, 1.51, 1.93, 2.34, 2.75, 3.15, 3.55)  # side and end node lines
    window_rows: tuple = (2, 3)  # side-wall element rows that are windows (z 1.93-2.75)
    window_x: tuple = (-7.0, 7.0)  # windows between the doors
    window_pitch: int = 3  # elements per window bay: two open, one pier
    sections: dict = field(default_factory=lambda: {
        # skin [m], depth [m], rigidity left across the ribs, core shear [N/m], areal mass [kg/m^2]
        "roof": (0.0020, 0.050, 5.0, 3.0e7, 35.0),  # flat here: its curvature's hoop stiffness as rigidity across
        "floor": (0.0025, 0.070, 4.0, 3.0e7, 80.0),  # cross beams make it stiffer across than along
        "side": (0.0022, 0.045, 0.7, 3.0e7, 40.0),
        "end": (0.0030, 0.050, 1.0, 3.0e7, 60.0),
    })
    iron_blocks: tuple = tuple((x, y, 1000.0) for x in (-6.0, -2.0, 2.0, 6.0) for y in (-0.9, 0.9))
    iron_footprint: tuple = (1.0, 1.5)  # [m] along x, y
    bogie_x: float = 8.75
    semi_wheelbase: float = 1.25
    bogie_z: float = 0.65
    bogie_mass: float = 2500.0
    bogie_inertia: tuple = (1200.0, 1800.0, 2500.0)
    axle_y: float = 1.0
    axle_k: tuple = (1.0e7, 4.0e6, 1.2e6)  # per axle box, x y z
    axle_c: tuple = (0.0, 0.0, 1.5e4)
    spring_y: float = 1.0
    air_k: tuple = (1.6e5, 1.6e5, 3.6e5)  # per air spring
    air_c: tuple = (0.0, 2.5e4, 2.0e4)
    traction_k: float = 1.0e7
    yaw_damper_y: float = 1.35
    yaw_damper_c: float = 2.0e5
    seat_half: float = 0.35  # [m] half-size of the patch a suspension element acts on

    @property
    def y_grid(self) -> np.ndarray:
        half = np.array(sorted(set(self.y_lines) | {self.width / 2}))
        return np.unique(np.round(np.concatenate([-half, half]), 6))

    @property
    def x_grid(self) -> np.ndarray:
        return _x_grid(self.length, self.step_x)

    def section(self, group: str, factors: dict | None = None) -> Section:
        skin, depth, across, shear, areal = self.sections[group]
        s = double_skin(E_AL, NU_AL, skin, depth, across, shear, areal)
        f = factors or {}
        return s.scaled(f.get(f"{group}_membrane", 1.0), f.get(f"{group}_bending", 1.0))

    def is_window(self, x0: float, row: int) -> bool:
        """Is the side-wall element starting at x0 in element row ``row`` a window?"""
        lo, hi = self.window_x
        if row not in self.window_rows or not lo <= x0 < hi - 1e-9:
            return False
        return int(round((x0 - lo) / self.step_x)) % self.window_pitch != self.window_pitch - 1


def region(car: ShellCar, name: str) -> tuple[str, tuple[float, float]]:
    """A panel region the softening effect can act on: its group and x range [m]."""
    half = car.length / 2
    return {"roof": ("roof", (-half, half)), "floor_front": ("floor", (5.0, half)),
            "floor_middle": ("floor", (-5.0, 5.0)), "floor_rear": ("floor", (-half, -5.0))}[name]


def mesh(car: ShellCar, factors: dict | None = None, softened: tuple | None = None,
         bolted: tuple = ()) -> ShellModel:
    """The carbody shell. ``factors``: rigidity factors per ``<group>_membrane`` /
    ``<group>_bending`` (nominal 1); ``softened``: (region name, divisor) dividing that
    region's rigidities; ``bolted``: extra masses (x, y, kg) on the floor, spread over the
    nodes of a 0.7 m square."""
    m = Mesher()
    xs, ys, zs = car.x_grid, car.y_grid, np.asarray(car.z_lines)
    soft_group, soft_x = (None, None) if softened is None else region(car, softened[0])

    def sec(group, x_mid):
        s = car.section(group, factors)
        if group == soft_group and soft_x[0] <= x_mid <= soft_x[1]:
            s = s.scaled(1 / softened[1], 1 / softened[1])
        return s

    ex, ey, ez = np.eye(3)
    for x0, x1 in zip(xs[:-1], xs[1:]):
        xm = 0.5 * (x0 + x1)
        for y0, y1 in zip(ys[:-1], ys[1:]):
            m.rectangle((x0, y0, car.floor_z), ex, ey, x1 - x0, y1 - y0, sec("floor", xm))
            m.rectangle((x0, y0, car.roof_z), ex, ey, x1 - x0, y1 - y0, sec("roof", xm))
        for row, (z0, z1) in enumerate(zip(zs[:-1], zs[1:])):
            if car.is_window(x0, row):
                continue
            for y in (ys[0], ys[-1]):
                m.rectangle((x0, y, z0), ex, ez, x1 - x0, z1 - z0, sec("side", xm))
    for x in (xs[0], xs[-1]):
        for y0, y1 in zip(ys[:-1], ys[1:]):
            for z0, z1 in zip(zs[:-1], zs[1:]):
                m.rectangle((x, y0, z0), ey, ez, y1 - y0, z1 - z0, sec("end", x))
    model = m.model()
    fx, fy = car.iron_footprint
    for x, y, kg in car.iron_blocks:
        _spread(model, car, x, y, kg, fx / 2, fy / 2)
    for x, y, kg in bolted:
        _spread(model, car, x, y, kg, car.seat_half, car.seat_half)
    return model


def _spread(model: ShellModel, car: ShellCar, x: float, y: float, kg: float, hx: float, hy: float):
    ids = floor_patch(model, car, x, y, hx, hy)
    model.mass[ids] += kg / len(ids)


def floor_patch(model: ShellModel, car: ShellCar, x: float, y: float, hx: float | None = None,
                hy: float | None = None) -> np.ndarray:
    """Floor nodes within hx, hy [m] of (x, y) (default: the suspension's seat size)."""
    hx = car.seat_half if hx is None else hx
    hy = car.seat_half if hy is None else hy
    n = model.nodes
    ok = (np.abs(n[:, 2] - car.floor_z) < 1e-6) & (np.abs(n[:, 0] - x) <= hx + 1e-6) & \
         (np.abs(n[:, 1] - y) <= hy + 1e-6)
    ids = np.flatnonzero(ok)
    if ids.size == 0:
        raise ValueError(f"no floor node within {hx}, {hy} m of ({x}, {y})")
    return ids
