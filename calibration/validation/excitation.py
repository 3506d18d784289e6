"""Validation of a box calibration on its excitation test: measured against model FRFs
(RTRI seed, Figure 9).

The model accelerance from the exciter force to every floor accelerometer is the modal
sum of the calibrated box model (all modes up to 100 Hz and the static residual of the
rest, :func:`calibration.models.box.modal.modal_model`), with the identified damping ratio
on each mode paired with a measured one and the median identified ratio on the others. A
diagnosis's extended model (a file with an ``extension``) is paired again by mode shape
(:func:`shape_paired_damping`), and a load cell's gain divides its FRFs; its equipment is
coupled to the modal model of the vehicle without it through the mount's impedance, the form
the diagnosis fits (:mod:`calibration.models.box.mount`), which carries the mount's damper
exactly where modal damping ratios could not.
Per channel over the analysis band: the frequency response assurance criterion

    FRAC = |sum_f conj(H_meas) H_model|^2 / (sum_f |H_meas|^2 sum_f |H_model|^2)

(1: same shape over frequency) and the log-magnitude error in dB
(:mod:`calibration.signals.modal`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..data.campaign import Campaign, Sensor
from ..data.errors import InputError
from ..identification.excitation import ExcitationIdentification, ExcitationIdentifySettings, identify_excitation
from ..models.box.extended import EQUIPMENT, extension_of, force_gain
from ..models.box.modal import modal_model
from ..models.box.mount import equipment_accelerance
from ..models.box.shinkansen import calibrated_box_model
from ..signals.modal import frac, log_error_db, mac_matrix


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


#: an identified mode gives its damping to the elastic model mode its shape is most alike
#: (MAC at least this) within :data:`PAIR_FREQUENCY` of its frequency
PAIR_MAC = 0.5
PAIR_FREQUENCY = 0.2


def shape_paired_damping(modal, ident: ExcitationIdentification) -> np.ndarray:
    """Damping ratios for ``modal``'s modes (NaN where none is identified): each identified
    mode's on the elastic model mode of largest MAC (at least :data:`PAIR_MAC`, within
    :data:`PAIR_FREQUENCY` in frequency), the pairs taken in order of MAC, one each."""
    zeta = np.full(modal.frequency_hz.size, np.nan)
    modes = [m for m in ident.modes if m.damping_ratio is not None]
    if not modes:
        return zeta
    mac = mac_matrix(np.column_stack([m.shape for m in modes]), modal.sensor_shapes)
    elastic = np.array(modal.kind) == "elastic"
    pairs = []
    for i, m in enumerate(modes):
        for k in np.nonzero(elastic & (np.abs(modal.frequency_hz / m.frequency_hz - 1) <= PAIR_FREQUENCY))[0]:
            if mac[i, k] >= PAIR_MAC:
                pairs.append((float(mac[i, k]), m.label, int(k), m.damping_ratio))
    taken = set()
    for _, label, k, z in sorted(pairs, reverse=True):
        if label not in taken and np.isnan(zeta[k]):
            zeta[k] = z
            taken.add(label)
    return zeta


def compare_frf(campaign: Campaign, calibration: dict, ident: ExcitationIdentification | None = None) -> FRFComparison:
    # the modes give the damping; their standard errors are not read here
    ident = identify_excitation(campaign, ExcitationIdentifySettings(standard_errors=False)) if ident is None else ident
    meta = campaign.meta
    sensors = tuple(meta.sensor(n) for n in ident.sensors)
    exciter = meta.exciter()
    extended = isinstance(calibration, dict) and bool(calibration.get("extension"))
    if not (isinstance(calibration, dict) and "parameters" in calibration and ("fit" in calibration or extended)):
        raise InputError("not a box calibration result: it needs parameters and fit (or a diagnosis's extended "
                         "model)", key="--calibration")
    ext = extension_of(calibration) if extended else None
    mount = None
    if ext is not None and ext[0] == EQUIPMENT:  # the equipment coupled as the diagnosis fits it (its mount damper)
        ext_p = ext[1]
        model, params = calibrated_box_model({k: v for k, v in calibration.items() if k != "extension"})
        mount = Sensor("equipment_mount", "displacement", "m", "floor", "z",
                       (ext_p["mount_x_m"], ext_p["mount_y_m"], model.panel("floor_middle").centre[2]))
        modal0 = modal_model(model, params, sensors=(*sensors, mount), exciter=exciter, residual_points=(mount,))
        mount_shape, modal0 = modal0.sensor_shapes[-1], replace(modal0, sensor_shapes=modal0.sensor_shapes[:-1],
                                                                outputs=modal0.outputs[:-1])
    else:
        model, params = calibrated_box_model(calibration)  # the file's factor set and extension; parameters checked
        modal0 = modal_model(model, params, sensors=sensors, exciter=exciter)
    if extended:  # the calibration's pairing is of the model before the extension: paired again here
        zeta = shape_paired_damping(modal0, ident)
        identified = {m.label: m.damping_ratio for m in ident.modes}
    else:
        zeta = np.full(modal0.frequency_hz.size, np.nan)
        # damping of the modes the calibration was fitted to (its own identification), by label
        rows = calibration.get("identified_modes") or [{"label": m.label, "damping_ratio": m.damping_ratio}
                                                      for m in ident.modes]
        identified = {r["label"]: r["damping_ratio"] for r in rows}
        for row in calibration["fit"]:  # a target of merged modes ("mode_5+mode_6", a close pair's span): their mean
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
    if mount is None:
        Ha = modal.frf(f)
    else:
        Ha = equipment_accelerance(f, 2 * np.pi * modal.frequency_hz, modal.damping_ratio, modal.sensor_shapes,
                                   modal.exciter_shape, mount_shape, ext_p["equipment_mass_kg"],
                                   ext_p["mounting_frequency_hz"], ext_p["mounting_damping_ratio"])
    Hm, Ha = ident.frf.H[sel], Ha / force_gain(calibration)  # the FRF per force as its load cell reads it
    return FRFComparison(ident.sensors, f, Hm, Ha, frac(Hm, Ha), log_error_db(Hm, Ha), (lo, hi),
                         ident.frf.coherence[sel])
