"""How sure a finding is: its held-out gain with a 95 % interval, and a word for it.

A gain is 1 - sum(r_after) / sum(r_before) over units of held-out data whose residuals add:
the in-service diagnosis's (run, speed bin) cells, the excitation test's channels. A
bootstrap over the units (``BOOTSTRAP`` draws from a fixed seed) gives the gain's 95 %
interval without assuming a distribution, from the data the decision judged.

The word follows from the interval and the decision's bar (its minimum gain plus the
penalty for the extension's parameters):

* **high**: the interval's lower end clears the bar, and no other hypothesis that passed
  has a gain inside the interval;
* **moderate**: the gain clears the bar but the interval reaches below it, or a runner-up
  gains about as much;
* **low**: fewer than ``MIN_UNITS`` held-out units, too few to resample.

A caller may lower the word for reasons outside the gain: the excitation test's cause fitted
to the edge of its search is at most ``moderate`` (``excitation.decision.confidences``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: bootstrap draws of the held-out units
BOOTSTRAP = 2000
#: fewer held-out units than this give no interval (and the word "low")
MIN_UNITS = 4


@dataclass(frozen=True)
class Confidence:
    """A finding's held-out gain, its 95 % interval (None: not resampled) over ``units``
    held-out units (``unit``: what they are, e.g. cells or channels), and the word for it,
    with the reason."""

    gain: float
    interval: tuple[float, float] | None
    units: int
    word: str
    why: str
    unit: str = "cells"

    def to_json(self) -> dict:
        return {"gain": self.gain, "interval_95": None if self.interval is None else list(self.interval),
                f"heldout_{self.unit}": self.units, "confidence": self.word, "why": self.why}

    def interval_words(self) -> str:
        """`` (95 % interval a to b over n held-out units)``, or nothing without an interval."""
        if self.interval is None:
            return ""
        return f" (95 % interval {self.interval[0]:.0%} to {self.interval[1]:.0%} over {self.units} held-out " \
               f"{self.unit})"


def from_units(r0, r1, bar: float, rivals: list[float], unit: str = "cells") -> Confidence:
    """The confidence of a gain from the held-out units' residuals before (``r0``) and after
    (``r1``); ``bar``: the raw gain the decision asks for; ``rivals``: the gains of the other
    hypotheses that passed (see the module's description)."""
    r0, r1 = np.asarray(r0, float), np.asarray(r1, float)
    gain = float(1.0 - r1.sum() / max(r0.sum(), 1e-300))
    if r0.size < MIN_UNITS:
        return Confidence(gain, None, r0.size, "low", f"{r0.size} held-out {unit}, too few to resample", unit)
    rng = np.random.default_rng(0)
    draws = rng.integers(0, r0.size, size=(BOOTSTRAP, r0.size))
    boot = 1.0 - r1[draws].sum(axis=1) / np.maximum(r0[draws].sum(axis=1), 1e-300)
    lo, hi = (float(x) for x in np.percentile(boot, [2.5, 97.5]))
    close = [g for g in rivals if lo <= g]
    if lo >= bar and not close:
        word, why = "high", f"the interval's lower end {lo:.0%} clears the bar {bar:.0%}"
    elif lo < bar:
        word, why = "moderate", f"the interval reaches {lo:.0%}, below the bar {bar:.0%}"
    else:
        word, why = "moderate", f"a runner-up gains {max(close):.0%}, inside the interval"
    return Confidence(gain, (lo, hi), r0.size, word, why, unit)
