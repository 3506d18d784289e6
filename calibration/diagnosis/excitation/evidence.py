"""Evidence from the baseline: its held-out FRF misfit per channel (normalised, FRAC, rms
log-magnitude error), the identified modes against the model's (paired by MAC: frequency
errors, MAC deficits, identified modes the model cannot pair), resonances identified at one
channel alone (:class:`~calibration.identification.excitation.LocalResonance`), factors at
their bounds, and whether the misfit is confined to one channel (then checked by
calibrating the baseline again without that channel)."""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from ...data.campaign import Campaign
from ...identification.excitation import LocalResonance
from ...models.box import BoxModel, FactorSet
from ...signals.modal import frac, log_error_db, mac_matrix
from .baseline import SwarmRecord, fit_baseline
from .context import Context, build_context
from .fitting import Fitted, at_bounds
from .frf import normalised_error_lines
from .settings import ExcitationDiagnosisSettings

#: a paired mode whose MAC is below this is listed among the MAC deficits (a report: the
#: decision does not read it)
MAC_DEFICIT = 0.95


@dataclass(frozen=True, eq=False)
class HeldOut:
    """A fitted model against the held-out FRFs.

    H : (n_f, n_s) the model's accelerance [(m/s^2)/N] at the held-out lines
    error : (n_s,) E per channel [-] (1 = the noise)
    lines : (n_f,) E per line, the mean over channels [-]
    frac : (n_s,) FRAC [-]; log_error_db : (n_s,) rms log-magnitude error [dB]
    """

    H: np.ndarray
    error: np.ndarray
    lines: np.ndarray
    frac: np.ndarray
    log_error_db: np.ndarray


def heldout(ctx: Context, fitted: Fitted) -> HeldOut:
    """``fitted`` judged on the held-out part."""
    meas = ctx.meas_test
    H = fitted.accelerance(meas.frequency)
    lines = normalised_error_lines(meas, H, ctx.settings.floor)
    return HeldOut(H, lines.mean(axis=0), lines.mean(axis=1), frac(meas.H, H), log_error_db(meas.H, H))


@dataclass(frozen=True)
class ModePair:
    """An identified (training) mode and its model partner, the model mode in the band its
    shape is most alike (MAC); ``partner`` indexes the model modes in the band, and
    ``paired`` says whether the pair holds (MAC and frequency within the alarms, and no other
    identified mode more alike on the same partner)."""

    label: str
    identified_hz: float
    damping_ratio: float | None
    model_hz: float
    error_pct: float
    mac: float
    partner: int
    shares_partner: bool
    paired: bool

    def to_json(self) -> dict:
        return asdict(self)


@dataclass(frozen=True, eq=False)
class ModeComparison:
    """Identified modes against a model's modes in the identification band (widened 10 %):
    the pairs, the MAC matrix (identified x model modes) and the labels of its rows and
    columns."""

    pairs: tuple[ModePair, ...]
    mac: np.ndarray
    rows: tuple[str, ...]
    cols: tuple[str, ...]


def compare_modes(ctx: Context, fitted: Fitted) -> ModeComparison:
    """Each identified (training) mode against the model modes of ``fitted`` in the band,
    paired by MAC; two identified modes on one model mode: the less alike is unpaired."""
    s = ctx.settings
    modes, _ = fitted.modes()
    hz = modes.frequency_hz
    sel = np.flatnonzero((hz >= 0.9 * s.identify.band[0]) & (hz <= 1.1 * s.identify.band[1]))
    cols = tuple(f"{hz[k]:.2f} Hz" for k in sel)
    rows = tuple(f"{m.label} {m.frequency_hz:.2f} Hz" for m in ctx.ident.modes)
    if not ctx.ident.modes or not sel.size:
        return ModeComparison((), np.zeros((len(ctx.ident.modes), sel.size)), rows, cols)
    shapes = np.column_stack([m.shape for m in ctx.ident.modes])
    mac = mac_matrix(shapes, modes.sensor_shapes[:, sel])
    found = []
    for i, m in enumerate(ctx.ident.modes):
        j = int(np.argmax(mac[i]))
        found.append({"label": m.label, "identified_hz": m.frequency_hz, "damping_ratio": m.damping_ratio,
                      "model_hz": float(hz[sel[j]]), "error_pct": float(100 * (hz[sel[j]] / m.frequency_hz - 1)),
                      "mac": float(mac[i, j]), "partner": int(j)})
    pairs = []
    for r in found:
        rivals = [q for q in found if q["partner"] == r["partner"]]
        paired = bool(r["mac"] >= s.mac_alarm and abs(r["error_pct"]) <= 100 * s.frequency_alarm
                      and r["mac"] >= max(q["mac"] for q in rivals))
        pairs.append(ModePair(**r, shares_partner=len(rivals) > 1, paired=paired))
    return ModeComparison(tuple(pairs), mac, rows, cols)


@dataclass(frozen=True)
class UnpairedMode:
    """An identified mode the model does not pair, with the held-out error around it.

    heldout_error_near : mean held-out E over the lines within ``mode_band`` of its
        frequency (all channels); None where no line of the comparison band is that near
    """

    label: str
    identified_hz: float
    mac: float
    error_pct: float
    shares_partner: bool
    heldout_error_near: float | None

    def to_json(self) -> dict:
        return {"label": self.label, "identified_hz": self.identified_hz, "mac": self.mac,
                "error_pct": self.error_pct, "shares_partner": self.shares_partner,
                "heldout_error_near": self.heldout_error_near}


def error_near(frequency: np.ndarray, lines: np.ndarray, hz: float, band: float) -> float | None:
    """Mean of ``lines`` (per-line error at ``frequency`` [Hz]) within ``band`` (relative)
    of ``hz`` [Hz]; None if no line is that near."""
    near = np.abs(frequency / hz - 1) <= band
    return float(lines[near].mean()) if near.any() else None


@dataclass(frozen=True)
class ChannelLeftOut:
    """The baseline re-calibrated without ``channel``, judged on the other ``channels``."""

    channel: str
    channels: int
    heldout_error_mean: float
    heldout_error_per_channel: dict
    parameters: dict

    def to_json(self) -> dict:
        return asdict(self)


def confined_channel(heldout_error: Mapping[str, float],
                     settings: ExcitationDiagnosisSettings) -> tuple[str, float] | None:
    """(channel, share) if the mean of the held-out errors per channel is over
    ``noise_alarm`` and one channel carries at least ``one_channel`` of their excess over
    the noise, else None."""
    if float(np.mean(list(heldout_error.values()))) <= settings.noise_alarm:
        return None
    name, worst = max(heldout_error.items(), key=lambda kv: kv[1])
    excess = sum(max(v - 1.0, 0.0) for v in heldout_error.values())
    share = (worst - 1.0) / excess
    return (name, share) if share >= settings.one_channel else None


def without_channel(campaign: Campaign, settings: ExcitationDiagnosisSettings, model: BoxModel, channel: str,
                    say, factors: FactorSet | None = None, start=None, start_fit_pct=None) -> ChannelLeftOut:
    """The baseline re-calibrated (identification, swarm, FRF refinement) with ``channel``
    left out, and its held-out error on the other channels: where they are then explained,
    the misfit was that measurement point's, not the carbody's."""
    say(f"the misfit is confined to {channel}: baseline re-calibrated without it")
    ctx = build_context(campaign, settings, model, say, without=(channel,), factors=factors, start=start,
                        start_fit_pct=start_fit_pct)
    base, _ = fit_baseline(ctx)
    e = heldout(ctx, base).error
    say(f"without {channel}: held-out error {np.mean(e):.2f} x noise on {e.size} channels")
    return ChannelLeftOut(channel, int(e.size), float(np.mean(e)), {n: float(v) for n, v in zip(ctx.sensors, e)},
                          base.factors(ctx.names))


@dataclass(frozen=True, eq=False)
class Evidence:
    """What the baseline leaves: its held-out misfit, its modes against the identified
    ones, its factors at their bounds, and (where the misfit is confined to one channel)
    the baseline calibrated without that channel.

    training_error_mean : mean over channels of E on the training part [-]
    modal_fit_of_swarm_pct : the baseline swarm's largest identified-frequency error [%]
    identified_in_heldout : frequencies of the modes identified in the held-out part [Hz]
    local_resonances : resonances identified (training part) at one channel alone: of a
        measurement point, not of the carbody, so not calibrated to
    """

    sensors: tuple[str, ...]
    heldout: HeldOut
    training_error_mean: float
    modes: ModeComparison
    unpaired: tuple[UnpairedMode, ...]
    parameters_at_bounds: tuple[str, ...]
    modal_fit_of_swarm_pct: float | None  # None: a calibration's start that states none
    identified_in_heldout: tuple[float, ...]
    without_channel: ChannelLeftOut | None = None
    local_resonances: tuple[LocalResonance, ...] = ()

    @property
    def heldout_error_per_channel(self) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.sensors, self.heldout.error)}

    @property
    def heldout_error_mean(self) -> float:
        return float(np.mean(self.heldout.error))

    def to_json(self) -> dict:
        pairs = self.modes.pairs
        out = {
            "heldout_error_per_channel": self.heldout_error_per_channel,
            "heldout_error_mean": self.heldout_error_mean,
            "training_error_mean": self.training_error_mean,
            "frac": {n: float(v) for n, v in zip(self.sensors, self.heldout.frac)},
            "frac_min": float(np.min(self.heldout.frac)), "frac_median": float(np.median(self.heldout.frac)),
            "log_error_db": {n: float(v) for n, v in zip(self.sensors, self.heldout.log_error_db)},
            "identified_modes": [r.to_json() for r in pairs],
            "unpaired_modes": [r.to_json() for r in self.unpaired],
            "mac_deficits": {r.label: float(1 - r.mac) for r in pairs if r.paired and r.mac < MAC_DEFICIT},
            "frequency_errors_pct": {r.label: r.error_pct for r in pairs if r.paired},
            "parameters_at_bounds": list(self.parameters_at_bounds),
            "modal_fit_of_swarm_pct": self.modal_fit_of_swarm_pct,
            "identified_in_heldout": list(self.identified_in_heldout),
            "local_resonances": [r.to_json() for r in self.local_resonances],
        }
        if self.without_channel is not None:
            out["without_channel"] = self.without_channel.to_json()
        return out


def gather_evidence(ctx: Context, base: Fitted, held: HeldOut, modes: ModeComparison, swarm: SwarmRecord,
                    left_out: ChannelLeftOut | None) -> Evidence:
    """The evidence of the baseline ``base`` (judged ``held``, its modes ``modes``)."""
    unpaired = tuple(UnpairedMode(r.label, r.identified_hz, r.mac, r.error_pct, r.shares_partner,
                                  error_near(ctx.meas_test.frequency, held.lines, r.identified_hz,
                                             ctx.settings.mode_band))
                     for r in modes.pairs if not r.paired)
    return Evidence(ctx.sensors, held, base.train_error / len(ctx.sensors), modes, unpaired,
                    tuple(at_bounds(ctx, base)), swarm.modal_fit_pct,
                    tuple(m.frequency_hz for m in ctx.ident_test.modes), left_out, ctx.ident.local)
