"""How sure a finding is: its held-out gain with a 95 % interval, and a word for it.

The held-out gain of a response extension on its channel is 1 - R_after / R_before, with R
the residual power summed over the held-out data's (run, speed bin) cells and the
channel's signal bands. Residual powers add over cells, so the cells are the units to
resample: a bootstrap over them (``BOOTSTRAP`` draws from a fixed seed) gives the gain's
95 % interval without assuming a distribution, from the data the decision judged.

The word follows from the interval and the decision's bar (``min_gain`` plus the penalty
for the extension's parameters):

* **high**: the interval's lower end clears the bar, and no other hypothesis that passed
  has a gain inside the interval;
* **moderate**: the gain clears the bar but the interval reaches below it, or a runner-up
  gains about as much;
* **low**: fewer than ``MIN_CELLS`` held-out cells, too few to resample.

A rail or wheel finding is held out by speed or by run with one error each; it carries
its gain without an interval and the word ``moderate``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .evidence import DiagnosisData
from .response import ResponseFit, residuals_by_cell

#: bootstrap draws of the held-out cells
BOOTSTRAP = 2000
#: fewer held-out cells than this give no interval (and the word "low")
MIN_CELLS = 4


@dataclass(frozen=True)
class Confidence:
    """A finding's held-out gain, its 95 % interval (None: not resampled) over ``cells``
    held-out cells, and the word for it, with the reason."""

    gain: float
    interval: tuple[float, float] | None
    cells: int
    word: str
    why: str

    def to_json(self) -> dict:
        return {"gain": self.gain, "interval_95": None if self.interval is None else list(self.interval),
                "heldout_cells": self.cells, "confidence": self.word, "why": self.why}


def cell_residuals(data: DiagnosisData, fit: ResponseFit, channel: int, masks: np.ndarray) -> np.ndarray:
    """``fit``'s residual power on ``channel`` in each held-out cell (in key order), over the
    channel's signal bands."""
    m = masks[:, channel]
    keys = sorted(data.keys(data.test))
    R = residuals_by_cell(data.stats, data.layout, keys, fit)
    return np.array([R[k][m, channel].sum() for k in keys])


def response_confidence(data: DiagnosisData, before: ResponseFit, after: ResponseFit, channel: str,
                        masks: np.ndarray, bar: float, rivals: list[float]) -> Confidence:
    """The confidence of a response finding that improves ``before`` to ``after`` on
    ``channel``; ``bar``: the raw gain it must clear; ``rivals``: the gains of the other
    hypotheses that passed."""
    c = data.layout.response_names.index(channel)
    r0 = cell_residuals(data, before, c, masks)
    r1 = cell_residuals(data, after, c, masks)
    return from_cells(r0, r1, bar, rivals)


def hypothesis_intervals(data: DiagnosisData, before: ResponseFit, hyps, masks: np.ndarray) -> dict:
    """Each response hypothesis's held-out gain over ``before`` with its 95 % interval, as a
    finding's (:func:`response_confidence`, judged against the bar alone): name ->
    :class:`Confidence`. The runners-up's intervals say how far behind they really are."""
    s = data.settings
    baseline_cells: dict = {}  # a channel's baseline residuals per cell, shared by the hypotheses
    out = {}
    for h in hyps:
        if h.kind != "response" or h.fit is None or h.best_channel is None:
            continue
        c = data.layout.response_names.index(h.best_channel)
        if c not in baseline_cells:
            baseline_cells[c] = cell_residuals(data, before, c, masks)
        out[h.name] = from_cells(baseline_cells[c], cell_residuals(data, h.fit, c, masks),
                                 s.bar(h.extension.n_params), [])
    return out


def from_cells(r0: np.ndarray, r1: np.ndarray, bar: float, rivals: list[float]) -> Confidence:
    """The confidence of a gain from the held-out cells' residual powers before (``r0``) and
    after (``r1``) (see the module's description)."""
    r0, r1 = np.asarray(r0, float), np.asarray(r1, float)
    gain = float(1.0 - r1.sum() / max(r0.sum(), 1e-300))
    if r0.size < MIN_CELLS:
        return Confidence(gain, None, r0.size, "low", f"{r0.size} held-out cells, too few to resample")
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
    return Confidence(gain, (lo, hi), r0.size, word, why)


def held_out_confidence(gain: float, how: str) -> Confidence:
    """A rail or wheel finding: one held-out error, no interval."""
    return Confidence(gain, None, 0, "moderate", f"held out {how}: one error, no interval")
