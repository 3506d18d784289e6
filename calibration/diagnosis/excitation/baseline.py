"""The baseline: the box model without extension calibrated to the training part, first by
the seed's particle swarm on the identified modes, then by least squares on the FRFs of all
channels (the factors within the campaign's priors and the damping ratio of every elastic
mode in the band). Modal frequencies alone leave most of the twelve factors undetermined;
the FRFs of many channels fix them, so that without a hidden effect the baseline's
held-out misfit is at the noise."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...calibrate_box import RefineSettings, SwarmSettings, calibrate_box, targets_from_identification
from ...signals.modal import mac_matrix
from .context import Context
from .family import Layout, Slots
from .fitting import Fitted, at_bounds, basis_at, factor_bounds, fit

#: an identified mode gives its damping ratio to a slot's start when their shapes are at least
#: this alike (MAC) ...
START_MAC = 0.8
#: ... and their frequencies within this (relative): a pairing looser than the evidence's own
#: (``frequency_alarm``, 3 %), since a start only needs to be near
START_FREQUENCY = 0.05


@dataclass(frozen=True)
class SwarmRecord:
    """The baseline's swarm on the identified modes (:func:`calibration.calibrate_box.calibrate_box`),
    or (no particles, no iterations) the calibration the baseline started from instead.

    modal_fit_pct : its objective, the largest frequency error of the identified modes [%]
        (a calibration's own, None where its file states none)
    undetermined_by_frequencies : the factor directions the frequencies leave open, in words
    """

    particles: int
    iterations: int
    stop_pct: float
    modal_fit_pct: float | None
    parameters: dict
    undetermined_by_frequencies: tuple[str, ...]

    def to_json(self) -> dict:
        return {"particles": self.particles, "iterations": self.iterations, "stop_pct": self.stop_pct,
                "modal_fit_pct": self.modal_fit_pct, "parameters": self.parameters,
                "undetermined_by_frequencies": list(self.undetermined_by_frequencies)}


def fit_baseline(ctx: Context) -> tuple[Fitted, SwarmRecord]:
    """Swarm on the identified modes (:func:`calibrate_box`; a calibration's factors
    instead where the context has them), then FRF refinement; a factor the refinement drives
    to a bound is retried from its prior mean (:func:`retry_bounds`)."""
    s = ctx.settings
    campaign = ctx.campaign
    sensors = tuple(campaign.meta.sensor(n) for n in ctx.sensors)
    if ctx.start is not None:  # a calibration's factors: the user's model, not a swarm's
        p0 = ctx.start
        swarm = SwarmRecord(0, 0, s.pso.target, ctx.start_fit_pct, dict(zip(ctx.names, map(float, p0))), ())
        ctx.say("baseline from the calibration's factors; FRF refinement of the factors and modal damping")
    else:
        cal = calibrate_box(targets_from_identification(ctx.ident), sensors, ctx.search,
                            swarm=SwarmSettings(pso=s.pso, seed=s.seed, log_factors=ctx.log_factors),
                            refinement=RefineSettings(enabled=False), model=ctx.model)
        p0 = np.array([cal.parameters[n] for n in ctx.names])
        swarm = SwarmRecord(s.pso.particles, cal.pso["iterations"], s.pso.target, cal.pso["best_full_pct"],
                            cal.parameters,
                            tuple(d["in_words"] for d in cal.identifiability["undetermined_directions"]))
        ctx.say(f"swarm on {len(ctx.ident.modes)} identified modes: {cal.pso['iterations']} iterations, modal fit "
                f"{cal.pso['best_full_pct']:.2f} %; FRF refinement of the factors and modal damping")
    layout0 = Layout(len(p0), 0)
    red = basis_at(ctx, layout0, np.log(p0), None)
    modes = red.modes(p0)
    slots = Slots.at(red, modes, s.band)
    # each slot starts at the damping of the identified mode it pairs with
    z0 = np.full(slots.n, ctx.default_zeta)
    if ctx.ident.modes and slots.n:
        shapes = np.column_stack([m.shape for m in ctx.ident.modes])
        mac = mac_matrix(shapes, ctx.ops.S @ slots.X0)
        for j in range(slots.n):
            i = int(np.argmax(mac[:, j]))
            m = ctx.ident.modes[i]
            if mac[i, j] >= START_MAC and abs(m.frequency_hz / slots.hz0[j] - 1) < START_FREQUENCY \
                    and m.damping_ratio:
                z0[j] = np.clip(m.damping_ratio, *s.damping_range)
    layout = Layout(len(p0), slots.n)
    lo, hi = factor_bounds(ctx, slots.n)
    fitted = fit(ctx, "baseline", layout, slots, np.concatenate([np.log(p0), np.log(z0)]), lo, hi, red=red)
    retried = retry_bounds(ctx, fitted)
    if retried is not None:
        fitted = retried
    return fitted, swarm


def retry_bounds(ctx: Context, fitted: Fitted) -> Fitted | None:
    """A factor the FRF refinement drove to its bound is often a weakly felt one (a
    stiff edge spring) the trust region walked off along a shallow valley: the fit is
    retried with those factors back at their prior means; the retry is returned if it
    fits the training part better (else None)."""
    at = [n.split(" ")[0] for n in at_bounds(ctx, fitted)]
    if not at:
        return None
    means = {q.name: q.mean for q in ctx.search}
    x = fitted.x.copy()
    for n in at:
        x[ctx.names.index(n)] = np.log(np.clip(means[n], ctx.low[ctx.names.index(n)] * 1.001,
                                               ctx.high[ctx.names.index(n)] / 1.001))
    lo, hi = factor_bounds(ctx, fitted.layout.n_slots)
    alt = fit(ctx, "baseline", fitted.layout, fitted.family.slots, x, lo, hi)
    ctx.say(f"baseline factor(s) at a bound ({', '.join(at)}): retried from the prior mean, training error "
            f"{alt.train_error / len(ctx.sensors):.2f} against {fitted.train_error / len(ctx.sensors):.2f}")
    return alt if alt.train_error < fitted.train_error else None


def baseline_start(ctx: Context, base: Fitted, fitted: Fitted) -> np.ndarray:
    """The baseline's unknowns at a hypothesis's factors, the extension left out (a
    softened panel alone in its group, the roof, gives its group's factors divided by the
    divisor, clipped to their range), with the baseline's dampings."""
    p, _, ext = fitted.layout.split(fitted.x)
    p = p.copy()
    if fitted.layout.extension == "softening":
        for n in ctx.ops.own_group_factors(fitted.panel):
            p[ctx.names.index(n)] /= float(np.exp(ext[0]))
    p = np.clip(p, ctx.low * (1 + 1e-6), ctx.high * (1 - 1e-6))
    _, z, _ = base.layout.split(base.x)
    return np.concatenate([np.log(p), np.log(z)])


def modal_damping(fitted: Fitted) -> dict[str, float]:
    """The damping ratio of every elastic mode up to 1.05 x the highest slot, by its
    frequency (``"12.345 Hz"``)."""
    modes, zeta = fitted.modes()
    sel = modes.elastic & (modes.frequency_hz <= fitted.family.slots.hz0.max(initial=0.0) * 1.05)
    return {f"{h:.3f} Hz": float(z) for h, z in zip(modes.frequency_hz[sel], zeta[sel])}
