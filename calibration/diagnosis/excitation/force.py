"""The extension ``force_calibration``: the exciter's force sensor reads g times the force
it applies (a load cell's or its amplifier's calibration factor off), so every measured
FRF is the structure's divided by g, on every channel at every frequency.

The baseline cannot absorb that: its factors are stiffnesses, and a stiffness moves
frequencies and the response near them, not the level far from resonance. A carbody whose
mass and every stiffness were off by one common factor would read the same, and the
FRFs cannot tell the two apart; the summary's description says so.

The fit starts at the closed-form level offset of the baseline against the training FRFs
(the weighted mean of log|H_baseline / H_measured|) and is refined jointly with the
factors and dampings.

A load cell's gain is one factor on every channel. A model whose level is off by different
amounts on different channels (its masses or modal constants wrong) also has a common
offset, which a gain removes in part; so the gain is named only where it stands
:data:`UNIFORM` times above the scatter of the channels' own level offsets left after it
(:func:`.frf.level_scatter`, on the held-out FRFs)."""
from __future__ import annotations

import numpy as np

from .context import Context
from .family import Layout
from .fitting import Fitted, factor_bounds, fit
from .frf import level_offsets

#: force gains searched (measured / applied): a calibration factor off by up to a factor 2
#: either way; a load cell's usual uncertainty is a per cent or two
GAIN_RANGE = (0.5, 2.0)
#: how many times the channels' level scatter a gain's log must reach to be named (stated
#: 2026-11-28 before any bench run with it; development: the own generator's load cell at
#: 0.96 left a channel spread of 0.027-0.041 around 0.035, the clean shell car's level error
#: -0.43 to +0.14 around -0.12)
UNIFORM = 2.0


def level_offset(ctx: Context, base: Fitted) -> float:
    """log g at which ``base`` / g fits the training FRFs' levels best: the mean of
    log|H_base / H_meas| weighted as the residual weights each line."""
    meas = ctx.meas
    return level_offsets(meas, base.accelerance(meas.frequency), ctx.settings.floor)[0]


def fit_force(ctx: Context, base: Fitted) -> list[Fitted]:
    """The baseline with a force gain, started at its level offset (clipped to
    :data:`GAIN_RANGE`) and refined jointly with the factors and dampings."""
    lay = Layout(base.layout.n_p, base.layout.n_slots, "force")
    lo, hi = factor_bounds(ctx, lay.n_slots)
    g_lo, g_hi = np.log(GAIN_RANGE)
    g0 = float(np.clip(level_offset(ctx, base), g_lo + 1e-6, g_hi - 1e-6))
    ctx.say(f"force calibration: the baseline's level offset {np.exp(g0):.4f}")
    x0 = np.concatenate([base.x, [g0]])
    return [fit(ctx, "force_calibration", lay, base.family.slots, x0, np.concatenate([lo, [g_lo]]),
                np.concatenate([hi, [g_hi]]), red=base.family.red)]
