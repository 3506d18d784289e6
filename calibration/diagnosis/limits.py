"""What a diagnosis could have detected: an effect's physical magnitude searched from the
weak end of its range to the strong end for the weakest size whose predicted held-out gain
clears the decision's bar, and the limits in words. Shared by the in-service and the
excitation-test detectability; what each predicts for a size is its own."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

#: standard deviations of the gain's sampling scatter an effect must clear: a detectable
#: effect's expected gain clears the bar with about 95 % probability (one-sided)
Z = 1.645
#: grid points from the weak to the strong end of a magnitude's range before bisection
GRID = 9


@dataclass(frozen=True)
class Magnitude:
    """The physical size of an extension's effect: ``parameter`` [``unit``] from ``weak``
    (the range's end where the effect is weakest) to ``strong``; for a response
    extension the other parameters are held at ``held``. ``signed``: a magnitude of either
    sign (both are checked, the weaker counts). ``log``: the range is searched in log."""

    parameter: str
    unit: str
    weak: float
    strong: float
    held: dict = field(default_factory=dict)
    signed: bool = False
    log: bool = True
    # further values of the held parameters: the limit is found at each, and the weakest is
    # the limit (what the effect's shape will be is not known before it is found)
    across: tuple[dict, ...] = ()

    def at(self, t: float) -> float:
        """The magnitude a fraction ``t`` (0 weak, 1 strong) along the range."""
        if self.log:
            return float(self.weak * (self.strong / self.weak) ** t)
        return float(self.weak + t * (self.strong - self.weak))



@dataclass(frozen=True)
class Limit:
    """One extension's detectable limit: its effect is detected beyond ``detectable_beyond``
    (towards the strong end of its range; None: not detectable within its range or not
    observable), in words ``why``."""

    name: str
    parameter: str
    unit: str
    detectable_beyond: float | None
    observable: bool
    why: str
    stronger: str  # "above" or "below": which side of the limit is the stronger effect
    # the sensors it would take (e.g. "carbody sensors"), when this set cannot name it at any size
    needs: str | None = None
    signed: bool = False  # the limit is on the magnitude of a quantity of either sign

    def to_json(self) -> dict:
        return {"parameter": self.parameter, "unit": self.unit, "detectable_beyond": self.detectable_beyond,
                "observable": self.observable, "why": self.why}

    def words(self) -> str:
        if not self.observable:
            return f"{self.name}: not observable with these sensors"
        if self.detectable_beyond is None and self.needs:
            return f"{self.name}: not observable without {self.needs}"
        if self.detectable_beyond is None:
            return f"{self.name}: not detectable within its range"
        op = ">=" if self.stronger == "above" else "<="
        what = f"|{self.parameter}|" if self.signed else self.parameter
        unit = "" if self.unit == "-" else f" {self.unit}"
        return f"{self.name} {what} {op} {self.detectable_beyond:.3g}{unit}"


@dataclass(frozen=True)
class Detectability:
    """Every extension's limit on this campaign."""

    limits: tuple[Limit, ...]

    def to_json(self) -> dict:
        return {x.name: x.to_json() for x in self.limits}

    def words(self) -> str:
        return "; ".join(x.words() for x in self.limits)


def search(mag: Magnitude, judge: Callable[[float], tuple[float, float]], bar: float):
    """(limit or None, margin at the strong end, observable at the strong end): ``judge(theta)``
    gives (gain less Z sigma, Z sigma-normalised effect) for magnitude theta."""
    ts = np.linspace(0.0, 1.0, GRID)
    if not mag.log:
        ts = ts[1:]  # a linear range starts at no effect
    margins = [judge(mag.at(t))[0] - bar for t in ts]
    strong, signif = judge(mag.strong)
    observable = signif >= 1.0
    if margins[-1] < 0:
        return None, strong, observable
    i = len(ts) - 1  # the weakest grid point from which on every stronger one is detectable
    while i > 0 and margins[i - 1] >= 0:
        i -= 1
    if i == 0 and mag.log:
        return mag.at(ts[0]), strong, observable
    lo, hi = (ts[i - 1] if i > 0 else 0.0), ts[i]
    for _ in range(8):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if judge(mag.at(mid))[0] >= bar else (mid, hi)
    return mag.at(hi), strong, observable


def weakest(mag: Magnitude, found: list) -> int:
    """Index of the weakest of ``found`` ((limit, strong, observable) per held variant): one
    not observable, else one not detectable, else the limit nearest the strong end."""
    def rank(x):
        limit, _, observable = x
        if not observable or limit is None:
            return (0 if not observable else 1, 0.0)
        return (2, limit if mag.strong < mag.weak else -limit)
    return min(range(len(found)), key=lambda i: rank(found[i]))
