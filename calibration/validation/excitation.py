"""Validation of a box calibration on its excitation test: measured against model FRFs
(RTRI seed, Figure 9).

The model accelerance from the exciter force to every floor accelerometer is the modal
sum of the calibrated box model (all modes up to 100 Hz and the static residual of the
rest, :func:`calibration.models.box.modal.modal_model`), with the identified damping ratio
on each mode paired with a measured one and the median identified ratio on the others.
Per channel over the analysis band: the frequency response assurance criterion

    FRAC = |sum_f conj(H_meas) H_model|^2 / (sum_f |H_meas|^2 sum_f |H_model|^2)

(1: same shape over frequency) and the log-magnitude error in dB
(:mod:`calibration.signals.modal`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.campaign import Campaign
from ..data.errors import InputError
from ..identification.excitation import ExcitationIdentification, identify_excitation
from ..models.box.modal import modal_model
from ..models.box.shinkansen import calibrated_box_model
from ..signals.modal import frac, log_error_db


@dataclass(frozen=True, eq=False)
class FRFComparison:
    sensors: tuple[str, ...]
    frequency: np.ndarray
    measured: np.ndarray  # (n_f, n_s)
    model: np.ndarray  # (n_f, n_s)
    frac: np.ndarray  # (n_s,)
    log_error_db: np.ndarray  # (n_s,) rms of 20 log10 |H_model / H_meas| over the band
    band: tuple[float, float]
    coherence: np.ndarray | None = None  # (n_f, n_s) of the measured H1

    def plot_phase(self, path, channels: int = 3):
        """Magnitude, phase and coherence, measured and model, of the channels with the lowest,
        the median and the highest FRAC, at ``path``."""
        from .plots import plot_frf_phase

        return plot_frf_phase(self, path, channels)

    def plot(self, path, channels: int = 9):
        """|H| measured and model for up to ``channels`` accelerometers at ``path``."""
        from .plots import plot_frf_comparison

        return plot_frf_comparison(self, path, channels)

    def to_json(self) -> dict:
        return {"kind": "stationary_excitation", "band_hz": list(self.band),
                "channels": {s: {"frac": float(f), "log_error_db": float(e)}
                             for s, f, e in zip(self.sensors, self.frac, self.log_error_db)},
                "frac_min": float(self.frac.min()), "frac_median": float(np.median(self.frac))}


def compare_frf(campaign: Campaign, calibration: dict, ident: ExcitationIdentification | None = None) -> FRFComparison:
    ident = identify_excitation(campaign) if ident is None else ident
    meta = campaign.meta
    sensors = tuple(meta.sensor(n) for n in ident.sensors)
    exciter = meta.exciter()
    if not (isinstance(calibration, dict) and {"parameters", "fit"} <= set(calibration)):
        raise InputError("not a box calibration result: it needs parameters and fit", key="--calibration")
    fit = calibration["fit"]
    model, params = calibrated_box_model(calibration)  # the file's factor set; parameters checked
    modal0 = modal_model(model, params, sensors=sensors, exciter=exciter)
    zeta = np.full(modal0.frequency_hz.size, np.nan)
    # damping of the modes the calibration was fitted to (its own identification), by label
    rows = calibration.get("identified_modes") or [{"label": m.label, "damping_ratio": m.damping_ratio}
                                                  for m in ident.modes]
    identified = {r["label"]: r["damping_ratio"] for r in rows}
    for row in fit:  # a target of merged modes ("mode_5+mode_6", a close pair's span): their mean
        known = [identified[part] for part in row["label"].split("+") if identified.get(part) is not None]
        if row.get("model_mode") and known:
            zeta[int(row["model_mode"]) - 1] = float(np.mean(known))
    default = float(np.median([z for z in identified.values() if z is not None]))
    zeta = np.where(np.isfinite(zeta), zeta, np.where(np.array(modal0.kind) == "elastic", default,
                                                      modal0.damping_ratio))
    modal = modal0.with_damping(zeta)
    lo, hi = ident.settings.band
    sel = (ident.frf.frequency >= lo) & (ident.frf.frequency <= hi)
    f = ident.frf.frequency[sel]
    Hm, Ha = ident.frf.H[sel], modal.frf(f)
    return FRFComparison(ident.sensors, f, Hm, Ha, frac(Hm, Ha), log_error_db(Hm, Ha), (lo, hi),
                         ident.frf.coherence[sel])
