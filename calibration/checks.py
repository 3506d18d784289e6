"""Checks that a settings dataclass runs on itself in ``__post_init__``: each raises a
ValueError that names the class, the field and what was expected."""
from __future__ import annotations

import math


def _fail(obj, name: str, what: str, value) -> None:
    raise ValueError(f"{type(obj).__name__}.{name} must be {what}, got {value!r}")


def positive(obj, *names: str) -> None:
    """Each field is a finite number > 0."""
    for n in names:
        v = getattr(obj, n)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            _fail(obj, n, "a finite number > 0", v)


def above(obj, *names: str, bound: float) -> None:
    """Each field is a finite number > ``bound``."""
    for n in names:
        v = getattr(obj, n)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v > bound):
            _fail(obj, n, f"a finite number > {bound:g}", v)


def non_negative(obj, *names: str) -> None:
    """Each field is a finite number >= 0."""
    for n in names:
        v = getattr(obj, n)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
            _fail(obj, n, "a finite number >= 0", v)


def fraction(obj, *names: str, closed: bool = False) -> None:
    """Each field lies in [0, 1) (``closed``: [0, 1])."""
    for n in names:
        v = getattr(obj, n)
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and (0 <= v <= 1 if closed else 0 <= v < 1)
        if not ok:
            _fail(obj, n, "in [0, 1]" if closed else "in [0, 1)", v)


def increasing(obj, *names: str, low: float = -math.inf) -> None:
    """Each field is a pair (low, high) of finite numbers with ``low`` <= low < high."""
    for n in names:
        v = getattr(obj, n)
        try:
            a, b = (float(x) for x in v)
        except (TypeError, ValueError):
            _fail(obj, n, "a pair (low, high)", v)
        if not (math.isfinite(a) and math.isfinite(b) and low <= a < b):
            _fail(obj, n, f"a pair with {low:g} <= low < high" if math.isfinite(low) else "a pair with low < high", v)


def whole(obj, *names: str, minimum: int = 1) -> None:
    """Each field is an integer >= ``minimum``."""
    for n in names:
        v = getattr(obj, n)
        if isinstance(v, bool) or not isinstance(v, int) or v < minimum:
            _fail(obj, n, f"an integer >= {minimum}", v)
