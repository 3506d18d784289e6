"""The rail level along the track for the exudyn references (:mod:`reference_models.car2d`,
:mod:`reference_models.box`): a track table passed at constant speed.

The rail input is a natural cubic spline through the table (as the FMUs interpolate their
track file). exudyn evaluates it in C++ as a symbolic user function: a balanced binary tree
of ``IfThenElse`` over the spline intervals with the interval's cubic at each leaf, so one
evaluation costs ~log2(intervals) comparisons and no Python runs during time integration.
"""
from __future__ import annotations

from dataclasses import dataclass

import exudyn as exu
import numpy as np
import scipy.interpolate
from exudyn.advancedUtilities import CreateSymbolicUserFunction

from calibration.models.car2d import wheelset_positions
from calibration.models.parameters import CarParameters


@dataclass(frozen=True, eq=False)
class RailInput:
    """The rail level along the track, passed at constant speed.

    Attributes
    ----------
    distance : array  [m] track distances of the table, strictly increasing (>= 3 points).
    level : array  [m] rail level at ``distance``; interpolated by a natural cubic spline.
    speed : float  [m/s] vehicle speed, > 0.
    start : float  [m] track distance of the carbody centre at t = 0.
    """

    distance: np.ndarray
    level: np.ndarray
    speed: float
    start: float = 0.0

    def __post_init__(self) -> None:
        s = np.array(self.distance, dtype=float)
        z = np.array(self.level, dtype=float)
        if s.ndim != 1 or z.shape != s.shape:
            raise ValueError(f"RailInput: distance {s.shape} and level {z.shape} must be 1-D of equal length")
        if len(s) < 3:
            raise ValueError(f"RailInput: the track table needs at least 3 points, has {len(s)}")
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(z))):
            raise ValueError("RailInput: distance and level must be finite")
        if np.any(np.diff(s) <= 0):
            k = int(np.argmax(np.diff(s) <= 0))
            raise ValueError(f"RailInput: distance must increase strictly; row {k + 1} ({s[k + 1]} m) "
                             f"follows {s[k]} m")
        if not (np.isfinite(self.speed) and self.speed > 0):
            raise ValueError(f"RailInput: speed = {self.speed} m/s; must be > 0")
        if not np.isfinite(self.start):
            raise ValueError(f"RailInput: start = {self.start} m is not finite")
        s.flags.writeable = z.flags.writeable = False
        object.__setattr__(self, "distance", s)
        object.__setattr__(self, "level", z)
        object.__setattr__(self, "speed", float(self.speed))
        object.__setattr__(self, "start", float(self.start))

    def spline(self) -> scipy.interpolate.CubicSpline:
        """Rail level [m] over track distance [m]: the natural cubic spline of the table."""
        return scipy.interpolate.CubicSpline(self.distance, self.level, bc_type="natural")

    def under_wheelsets(self, p: CarParameters, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rail level [m] and its rate [m/s] under wheelsets 1-4 at times ``t`` [s], each (n_t, 4)."""
        s = self.start + self.speed * np.asarray(t, float)[:, None] + wheelset_positions(p)[None, :]
        spline = self.spline()
        return spline(s), self.speed * spline(s, 1)

    def time_on_track(self, p: CarParameters) -> float:
        """Time [s] until the leading wheelset passes the end of the table."""
        return float((self.distance[-1] - self.start - wheelset_positions(p).max()) / self.speed)

    def check_covers(self, p: CarParameters, duration: float) -> None:
        """Raise ValueError unless every wheelset stays on the table for ``duration`` [s]."""
        xw = wheelset_positions(p)
        first, last = self.start + xw.min(), self.start + self.speed * duration + xw.max()
        if first < self.distance[0] or last > self.distance[-1]:
            raise ValueError(f"RailInput: the wheelsets run over track distances {first:.2f}-{last:.2f} m in "
                             f"{duration} s, but the table covers only {self.distance[0]:.2f}-"
                             f"{self.distance[-1]:.2f} m")


def _piecewise_tree(x, breaks: np.ndarray, coefs: np.ndarray, lo: int, hi: int):
    """Symbolic value at ``x`` of the piecewise polynomial (scipy PPoly layout: ``coefs[k, i]``
    multiplies (x - breaks[i])**(order - k)) over intervals lo..hi-1, as a balanced tree of
    IfThenElse; intervals outside the table extend the first/last polynomial."""
    if hi - lo == 1:
        u = x - float(breaks[lo])
        value = float(coefs[0, lo])
        for c in coefs[1:, lo]:
            value = value * u + float(c)
        return value
    mid = (lo + hi) // 2
    return exu.symbolic.IfThenElse(x < float(breaks[mid]), _piecewise_tree(x, breaks, coefs, lo, mid),
                                   _piecewise_tree(x, breaks, coefs, mid, hi))


def rail_functions(rail: RailInput, x_wheelset: float):
    """Python offset functions (level [m], rate [m/s] vs time) of a wheelset at vehicle-frame
    ``x_wheelset``, written in exudyn symbolic arithmetic so they convert to C++ expressions."""
    spline = rail.spline()
    slope = spline.derivative()
    s0, v = rail.start + x_wheelset, rail.speed

    def level(mbs, t, itemNumber, lOffset):
        return _piecewise_tree(s0 + v * t, spline.x, spline.c, 0, spline.c.shape[1])

    def rate(mbs, t, itemNumber, lOffset):
        return v * _piecewise_tree(s0 + v * t, slope.x, slope.c, 0, slope.c.shape[1])

    return level, rate


def drive_rail_constraints(mbs, rail: RailInput, constraints, wheelset_x) -> list:
    """Give each wheelset's rail-level constraint the track's level and rate as symbolic user
    functions (after ``mbs.Assemble()``, exudyn's recipe) and assemble again. Returns the
    functions, which must outlive the system."""
    keep = []
    for con, x in zip(constraints, wheelset_x):
        level, rate = rail_functions(rail, float(x))
        uf = CreateSymbolicUserFunction(mbs, level, "offsetUserFunction", con)
        uf_t = CreateSymbolicUserFunction(mbs, rate, "offsetUserFunction_t", con)
        mbs.SetObjectParameter(con, "offsetUserFunction", uf)
        mbs.SetObjectParameter(con, "offsetUserFunction_t", uf_t)
        keep += [uf, uf_t]
    mbs.Assemble()
    return keep
