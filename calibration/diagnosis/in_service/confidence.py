"""How sure an in-service finding is (:mod:`calibration.diagnosis.confidence`): the held-out
gain of a response extension on its channel, resampled over the held-out data's (run, speed
bin) cells.

The gain is 1 - R_after / R_before, with R the residual power summed over the cells and the
channel's signal bands. Residual powers add over cells, so the cells are the units a
bootstrap resamples.

A rail or wheel finding is held out by speed or by run with one error each; it carries
its gain without an interval and the word ``moderate``.
"""
from __future__ import annotations

import numpy as np

from ..confidence import Confidence, from_units
from .evidence import DiagnosisData
from .response import ResponseFit, residuals_by_cell


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
    after (``r1``)."""
    return from_units(r0, r1, bar, rivals, "cells")


def held_out_confidence(gain: float, how: str) -> Confidence:
    """A rail or wheel finding: one held-out error, no interval."""
    return Confidence(gain, None, 0, "moderate", f"held out {how}: one error, no interval")
