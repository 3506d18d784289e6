"""Truth simulator for the stationary excitation test (box-model seed, section 3.2).

The Shinkansen-type test vehicle of :mod:`calibration.models.box.shinkansen` stands on
the rails (wheelsets held); an electrodynamic exciter on the ground pushes the floor
from below with a band-random force, flat in 5-50 Hz; a load cell measures the force and
floor accelerometers the vertical response; the logger samples at 200 Hz behind 80 Hz
anti-alias filters. The seed's Figure 4 (the measurement points) is not available to us:
:data:`SENSOR_GRID` is our assumption, stated once, and :data:`EXCITER` the exciter's.

The truth is a modal model of the full box model at the truth parameters
(:func:`truth_modes`):

* stiffness factors ``model.names`` = nominal 1 times a lognormal draw (sigma 0.15,
  clipped to [0.6, 1.6]);
* every mode up to ``max_mode_hz`` (100 Hz: about 120 modes), M-normalised, plus one
  *residual pseudo-mode*: the static response of the omitted modes to the exciter force,
  psi = K^-1 e - sum_kept phi phi^T e / omega^2, which is M- and K-orthogonal to the kept
  modes, so it is one more decoupled mode (near 170 Hz) that makes the static and low
  frequency response exact (modal truncation augmentation). Without it the omitted modes
  change the 5-50 Hz accelerance by 3 % (median; up to 11 %, norm over the sensors);
  with it by 0.05 % (up to 0.8 %), checked against direct solves of the full model;
* modal damping: a carbody elastic mode gets a ratio drawn per seed in 1-3 %; a
  rigid-body-on-suspension mode (the carbody moving rigidly, or most of the kinetic
  energy in the bogies; in this vehicle the six carbody modes up to 4.2 Hz and the twelve
  bogie modes at 7.5-26 Hz) gets the suspension dampers' proportional estimate
  phi^T C phi / (2 omega), clipped to [0.02, 0.3]; the pseudo-mode 5 %. Damping is
  exactly modal (the suspension's coupling between modes is left out): the truth is this
  modal model, whose accelerance :meth:`ModalModel.frf` gives exactly.

The response is stepped exactly (:class:`calibration.models.simulate.ModalSimulator`,
first-order hold) at 1000 Hz, so the force is linear between 1 ms samples and the
recorded force samples are the applied force. Sensor noise (white to 500 Hz, and a small
offset) is added before an 8th-order Butterworth low-pass at 80 Hz, applied causally to
every channel (force included, so H1 = G_fy / G_ff is unaffected), and the channels are
decimated to 200 Hz. Each run starts ``pre_roll`` seconds after the excitation, when
the start transient has decayed. Everything random comes from one seeded generator.

Hidden effects (``underfloor_equipment``, ``local_panel_softening``) and the sensor
bracket outside the catalogue are built by :mod:`calibration.truth.excitation_effects`;
their details come from a second generator, ``default_rng([seed, EFFECT_STREAM])``, so the
effect-free campaign of a seed is unchanged and the same seed draws the same vehicle
parameters with or without one.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.signal

from ..data.campaign import CampaignMeta, Excitation, Prior
from ..data.outputs import CampaignWriter, write_json_atomic
from ..models.box import SEARCH_PARAMETERS, BoxModel
from ..models.box.assembly import carbody_mass
from ..models.box.modal import ModalModel, ModalSettings, modal_model
from ..models.box.panel import Panel
from ..models.box.rig import EXCITER, GEOMETRY, SENSOR_GRID
from ..models.box.shinkansen import LOWEST_ORDER_CHANGE, floor_panel, shinkansen_model
from ..signals.filters import band_random
from ..signals.modal import mac_matrix
from ..models.simulate import ModalSimulator
from .effects import EffectChoice
from .excitation_effects import (EFFECT_STREAM, EQUIPMENT_DETUNING, SOFTENING_PANELS, EquipmentModes, SensorBracket,
                                 UnderfloorEquipment, add_equipment, choose_tuned_mode, draw_bracket,
                                 draw_equipment_position, mount_point, soften_panel)
from .in_service import TRUTH_FORMAT

PARAMETER_NAMES = tuple(q.name for q in SEARCH_PARAMETERS)



@dataclass(frozen=True)
class ExcitationSettings:
    """What a synthetic stationary excitation test looks like (SI units)."""

    runs: int = 2
    duration: float = 600.0  # [s] total recording, split evenly over the runs
    fs: float = 200.0  # [Hz] logger rate (seed section 3.2)
    fs_sim: float = 1000.0  # [Hz] simulation rate (analog side)
    anti_alias_hz: float = 80.0  # seed section 3.2
    anti_alias_order: int = 8
    band: tuple[float, float] = (5.0, 50.0)  # [Hz] band-random force, flat in band (seed section 3.2)
    force_rms: float = 500.0  # [N]
    pre_roll: float = 10.0  # [s] excitation before each run's recording starts
    acc_noise: float = 0.002  # [m/s^2] rms, white up to fs_sim / 2, before the anti-alias filter
    acc_offset: float = 0.005  # [m/s^2] max |offset| per channel
    force_noise: float = 1.0  # [N] rms, white up to fs_sim / 2
    force_offset: float = 2.0  # [N] max |offset|
    perturb_sigma: float = 0.15  # lognormal sigma of the truth stiffness factors
    perturb_clip: tuple[float, float] = (0.6, 1.6)
    elastic_damping: tuple[float, float] = (0.01, 0.03)  # drawn per elastic mode
    suspension_damping: tuple[float, float] = (0.02, 0.3)  # clip of phi^T C phi / (2 omega)
    residual_damping: float = 0.05  # of the residual pseudo-mode
    max_mode_hz: float = 100.0  # modes kept in the simulation
    truth_band_hz: tuple[float, float] = (3.0, 25.0)  # modes listed in the truth
    order_change: int = 0  # added to every panel order (negative: a coarse, fast model for tests)
    chunk: int = 1 << 14  # samples per simulation step

    def __post_init__(self):
        if self.runs < 1:
            raise ValueError(f"runs must be >= 1, got {self.runs}")
        if not self.duration / self.runs >= 20.0:
            raise ValueError(f"each run must last >= 20 s; {self.duration} s over {self.runs} runs")
        step = self.fs_sim / self.fs
        if abs(step - round(step)) > 1e-9 or step < 2:
            raise ValueError(f"fs_sim = {self.fs_sim} Hz must be an integer multiple (>= 2) of fs = {self.fs} Hz")
        lo, hi = self.band
        if not 0 < lo < hi < self.anti_alias_hz < self.fs / 2:
            raise ValueError(f"need 0 < band {self.band} < anti_alias_hz = {self.anti_alias_hz} < fs / 2")
        if not hi < self.max_mode_hz:
            raise ValueError(f"max_mode_hz = {self.max_mode_hz} must exceed the force band {self.band}")
        for name in ("perturb_clip", "elastic_damping", "suspension_damping", "truth_band_hz"):
            a, b = getattr(self, name)
            if not 0 <= a < b:
                raise ValueError(f"{name} = {(a, b)} must satisfy 0 <= low < high")
        if self.order_change < LOWEST_ORDER_CHANGE:
            raise ValueError(f"order_change = {self.order_change} would leave a panel order below 1")

    @property
    def run_duration(self) -> float:
        return self.duration / self.runs


def draw_truth_parameters(settings: ExcitationSettings, rng: np.random.Generator) -> dict[str, float]:
    """The vehicle the test was 'measured' on: each stiffness factor = 1 x lognormal."""
    lo, hi = settings.perturb_clip
    f = np.clip(np.exp(rng.normal(0.0, settings.perturb_sigma, len(PARAMETER_NAMES))), lo, hi)
    return {n: float(v) for n, v in zip(PARAMETER_NAMES, f)}


def campaign_priors() -> dict[str, Prior]:
    """The stiffness factors' search box (nominal 1, 0.5-2), as prior knowledge."""
    return {n: Prior(1.0, 0.5, 2.0) for n in PARAMETER_NAMES}


# ------------------------------------------------------------------------ modal truth
def truth_modes(parameters: Mapping[str, float] | None = None, *, damping=None,
                settings: ExcitationSettings = ExcitationSettings(), model: BoxModel | None = None,
                sensors=SENSOR_GRID, exciter=EXCITER, residual_points=()) -> ModalModel:
    """The truth's modal model (:func:`calibration.models.box.modal.modal_model`) at
    ``parameters`` (missing ones nominal 1), kept modes and damping from ``settings``; the
    elastic modes get the middle of ``settings.elastic_damping`` unless ``damping`` gives
    every ratio (a truth file's ``modes_kept.damping_ratios`` gives back exactly the
    simulated model). ``model``: built from ``settings`` when not given."""
    names = PARAMETER_NAMES if model is None else model.names
    unknown = sorted(set(parameters or {}) - set(names))
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(names)}")
    model = shinkansen_model(settings.order_change) if model is None else model
    modal = ModalSettings(max_mode_hz=settings.max_mode_hz, elastic_damping=float(np.mean(settings.elastic_damping)),
                          suspension_damping=settings.suspension_damping, residual_damping=settings.residual_damping)
    return modal_model(model, parameters, sensors=sensors, exciter=exciter, damping=damping, settings=modal,
                       residual_points=residual_points)



# ------------------------------------------------------------------------------ runs
def anti_alias_sos(settings: ExcitationSettings) -> np.ndarray:
    """The logger's anti-alias low-pass (Butterworth, at the simulation rate)."""
    return scipy.signal.butter(settings.anti_alias_order, settings.anti_alias_hz, fs=settings.fs_sim, output="sos")


def simulate_run(modal: ModalModel, settings: ExcitationSettings, rng: np.random.Generator,
                 bracket: SensorBracket | None = None) -> tuple[dict, dict]:
    """One test run: columns ``time`` [s], ``exciter_force`` [N] and the accelerometers
    [m/s^2] at ``settings.fs``, and the run's truth (force rms, offsets). ``bracket``: a
    sensor on a resilient bracket (outside the catalogue), in series with its channel."""
    step = round(settings.fs_sim / settings.fs)
    n_pre = round(settings.pre_roll * settings.fs) * step
    n_out = round(settings.run_duration * settings.fs)
    n = n_pre + n_out * step
    force = band_random(n, settings.fs_sim, settings.band, settings.force_rms, rng)
    ss = modal.state_space()
    sim = ModalSimulator(ss if bracket is None else bracket.in_series(ss), 1.0 / settings.fs_sim)
    acc = np.vstack([sim.step_chunk(force[a:a + settings.chunk, None]) for a in range(0, n, settings.chunk)])
    n_s = len(SENSOR_GRID)
    offsets = np.concatenate([[rng.uniform(-settings.force_offset, settings.force_offset)],
                              rng.uniform(-settings.acc_offset, settings.acc_offset, n_s)])
    rms = np.concatenate([[settings.force_noise], np.full(n_s, settings.acc_noise)])
    raw = np.column_stack([force, acc]) + rng.standard_normal((n, n_s + 1)) * rms + offsets
    measured = scipy.signal.sosfilt(anti_alias_sos(settings), raw, axis=0)[n_pre::step]
    cols = {"time": np.arange(n_out) / settings.fs, EXCITER.name: measured[:, 0]}
    cols.update({s.name: measured[:, i + 1] for i, s in enumerate(SENSOR_GRID)})
    info = {"duration_s": settings.run_duration, "force_rms_n": float(force[n_pre:].std()),
            "offsets_si": {nm: float(v) for nm, v in zip([EXCITER.name] + [s.name for s in SENSOR_GRID], offsets)}}
    return cols, info


# -------------------------------------------------------------------------- campaign
def _unit_shapes(shapes: np.ndarray) -> np.ndarray:
    """Columns scaled so that their largest-magnitude entry is +1."""
    peak = shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])]
    return shapes / peak


def _settings_from_json(d: Mapping) -> ExcitationSettings:
    return ExcitationSettings(**{k: tuple(v) if isinstance(v, list) else v for k, v in d.items()})


def truth_model(truth: Mapping, *, model: BoxModel | None = None) -> ModalModel:
    """The system a truth file of :func:`synth_excitation` says was simulated, hidden
    effect included, rebuilt exactly (same modes, damping, shapes at :data:`SENSOR_GRID`).
    A sensor bracket is the measurement's, not the system's: the structure is returned
    (the bracketed channel reads its accelerance times :meth:`SensorBracket.transmissibility`).
    ``model``: the assembled vehicle without effect, built from the file's settings when
    not given."""
    settings = _settings_from_json(truth["settings"])
    model = shinkansen_model(settings.order_change) if model is None else model
    effect = truth["effect"] or {}
    if effect.get("name") == "underfloor_equipment":
        equipment = UnderfloorEquipment(effect["equipment_mass_kg"], tuple(effect["position_m"]),
                                        effect["mounting_frequency_hz"], effect["mounting_damping_ratio"])
        mounts = (equipment.mount(),)
        base = truth_modes(truth["parameters"], damping=effect["structure_damping_ratios"], settings=settings,
                           model=model, sensors=SENSOR_GRID + mounts, residual_points=mounts)
        base, mount_shape = replace(base, sensor_shapes=base.sensor_shapes[:-1]), base.sensor_shapes[-1]
        return add_equipment(base, mount_shape, equipment).modal
    if effect.get("name") == "local_panel_softening":
        model = soften_panel(model, effect["panel"], effect["magnitude"])
    return truth_modes(truth["parameters"], damping=truth["modes_kept"]["damping_ratios"], settings=settings,
                       model=model)


def _labels(modal: ModalModel, band) -> tuple[np.ndarray, list[str]]:
    listed = modal.listed(band)
    return listed, [f"mode_{k + 1:02d}" for k in listed]  # numbered as in the full model, lowest first


def _equipment_record(coupled: EquipmentModes, tuned: int, detuning: float, carbody_kg: float,
                      structure_damping: np.ndarray, band) -> dict:
    """What the truth file says about the underfloor equipment (see :func:`synth_excitation`)."""
    eq, modal = coupled.equipment, coupled.modal
    f, _ = modal.poles()
    listed, labels = _labels(modal, band)
    lo, hi = coupled.split(tuned)
    base_hz = coupled.uncoupled_hz
    a = coupled.uncoupled_mount
    share = coupled.equipment_share
    base_band = np.flatnonzero((base_hz >= band[0]) & (base_hz <= band[1]))
    return {
        "equipment_mass_kg": eq.mass, "carbody_mass_kg": carbody_kg, "position_m": list(eq.position),
        "panel": floor_panel(eq.position[0]), "mounting_frequency_hz": eq.frequency_hz,
        "mounting_damping_ratio": eq.damping_ratio, "mounting_stiffness_n_per_m": eq.stiffness,
        "mounting_damping_n_s_per_m": eq.damping, "detuning": detuning,
        "tuned_mode": {"label": f"mode_{tuned + 1:02d}", "frequency_hz": float(base_hz[tuned]),
                       "mount_shape": float(a[tuned]), "effective_mass_ratio": float(eq.mass * a[tuned] ** 2)},
        "split_modes": {f"mode_{k + 1:02d}": float(f[k]) for k in (lo, hi)},
        "split_content": [float(coupled.structure[tuned, k] ** 2) for k in (lo, hi)],
        "split_hz": float(f[hi] - f[lo]), "split_pct": float(100 * (f[hi] - f[lo]) / base_hz[tuned]),
        "equipment_energy_share": {lb: float(share[k]) for lb, k in zip(labels, listed) if share[k] >= 0.01},
        "uncoupled_frequencies_hz": {f"mode_{k + 1:02d}": float(base_hz[k]) for k in base_band},
        "structure_damping_ratios": structure_damping.tolist(),
    }


def _softening_record(modal: ModalModel, unsoftened: ModalModel, panel: Panel, band) -> dict:
    """What the truth file says about the softened panel: the unsoftened vehicle's modes
    (same parameters) and each listed mode's change, paired by MAC at the sensors."""
    listed, labels = _labels(modal, band)
    base_listed, base_labels = _labels(unsoftened, (band[0], 2 * band[1]))
    mac = mac_matrix(modal.sensor_shapes[:, listed], unsoftened.sensor_shapes[:, base_listed])
    rows, cols = scipy.optimize.linear_sum_assignment(-mac)
    changes = {}
    for r, c in zip(rows, cols):
        if mac[r, c] >= 0.9:
            f0 = unsoftened.frequency_hz[base_listed[c]]
            changes[labels[r]] = {"unsoftened": base_labels[c], "unsoftened_hz": float(f0),
                                  "change_pct": float(100 * (modal.frequency_hz[listed[r]] / f0 - 1)),
                                  "mac": float(mac[r, c])}
    keep = unsoftened.frequency_hz[base_listed] <= band[1]
    return {"panel": panel.name, "group": panel.group, "panel_area_m2": panel.a * panel.b,
            "unsoftened_frequencies_hz": {lb: float(unsoftened.frequency_hz[k])
                                          for lb, k, ok in zip(base_labels, base_listed, keep) if ok},
            "frequency_changes": dict(sorted(changes.items()))}


def synth_excitation(out, *, seed: int = 0, settings: ExcitationSettings = ExcitationSettings(),
                     effect: EffectChoice | None = None, fmt: str = "csv", overwrite: bool = False,
                     model: BoxModel | None = None, progress=None) -> dict:
    """Write a synthetic stationary excitation campaign to ``out`` and its truth to
    ``out.truth.json``; returns the truth. ``model``: the assembled vehicle (built from
    ``settings`` when not given; pass it to reuse one assembly over many seeds).

    ``effect``: a hidden effect for stationary tests, of the catalogue or outside it
    (module docstring).
    ``truth["effect"]`` is then ``effect.to_json()`` and the drawn details:

    * underfloor equipment: mass, carbody mass, mount position and panel, mounting
      frequency, damping ratio, stiffness and damper, the detuning, the tuned mode (label
      and frequency without the equipment, its value at the mount, m_e phi^2), the two
      ``split_modes`` it became (labels of the truth's listing, pole frequencies; see
      :meth:`EquipmentModes.split`), the share of the tuned mode each holds
      (``split_content``), their distance (``split_hz``, ``split_pct`` of the tuned
      frequency), each listed
      mode's kinetic energy share in the equipment (>= 1 %), the listing without the
      equipment, and the structure's modal damping (to rebuild the truth, :func:`truth_model`);
    * panel softening: the panel, its group and area, the unsoftened vehicle's modes and
      each listed mode's frequency change against its MAC-paired unsoftened mode;
    * force calibration: the force sensor and its gain (the runs are the effect-free
      campaign's of the same seed, the force column times the gain);
    * sensor bracket (outside the catalogue): the sensor, the bracket's frequency and
      damping ratio, and |T| at its frequency.

    The truth lists the simulated system's poles: with the equipment the damping is not
    modal, so frequencies are |s| / 2 pi and ratios -Re(s) / |s| (undamped shapes)."""
    if effect is not None and "stationary_excitation" not in effect.spec.kinds:
        raise ValueError(f"effect {effect.spec.name} is for {', '.join(effect.spec.kinds)} campaigns, "
                         "not stationary excitation tests")
    if effect is not None and effect.spec.name not in ("underfloor_equipment", "local_panel_softening",
                                                       "force_calibration", "sensor_bracket"):
        raise NotImplementedError(f"effect {effect.spec.name} is registered but not simulated")
    out = Path(out)
    g = GEOMETRY
    meta = CampaignMeta(
        kind="stationary_excitation", name=f"synthetic stationary excitation test (seed {seed})",
        vehicle="Shinkansen-type test vehicle, extended box-type model (railcal truth simulator)",
        sensors=(EXCITER,) + SENSOR_GRID, sampling_rate=settings.fs,
        geometry={"bogie_semi_spacing": g.bogie_x, "semi_wheelbase": g.semi_wheelbase, "length": g.length,
                  "width": g.width, "height": g.roof_z},
        priors=campaign_priors(), excitation=Excitation(EXCITER.name, EXCITER.position))
    with CampaignWriter(out, meta, fmt=fmt, overwrite=overwrite) as w:  # refuses an existing folder first
        rng = np.random.default_rng(seed)
        parameters = draw_truth_parameters(settings, rng)
        if progress:
            progress("assembling the box model and solving its modes")
        model = shinkansen_model(settings.order_change) if model is None else model
        effect_rng = np.random.default_rng([seed, EFFECT_STREAM])  # the effect's own draws
        name = None if effect is None else effect.spec.name
        truth_vehicle, mounts, bracket = model, (), None
        if name == "sensor_bracket":
            bracket = draw_bracket(effect_rng, effect.magnitude)
            if progress:
                progress(f"{bracket.sensor} on a bracket: {bracket.frequency_hz:.2f} Hz, damping "
                         f"{bracket.damping_ratio:.3f}")
        elif name == "local_panel_softening":
            panel = model.panel(SOFTENING_PANELS[int(effect_rng.integers(len(SOFTENING_PANELS)))])
            truth_vehicle = soften_panel(model, panel.name, effect.magnitude)
            if progress:
                progress(f"{panel.name}: rigidities / {effect.magnitude:g}")
        elif name == "underfloor_equipment":
            mounts = (mount_point(draw_equipment_position(effect_rng)),)
        modal = truth_modes(parameters, settings=settings, model=truth_vehicle, sensors=SENSOR_GRID + mounts,
                            residual_points=mounts)
        if mounts:
            mount_shape = modal.sensor_shapes[-1]
            modal = replace(modal, sensor_shapes=modal.sensor_shapes[:-1])
        elastic = np.array(modal.kind) == "elastic"
        drawn = rng.uniform(*settings.elastic_damping, elastic.size - len(mounts))  # as many draws as without
        modal = replace(modal, damping_ratio=np.where(elastic, np.append(drawn, np.zeros(len(mounts))),
                                                      modal.damping_ratio))
        if progress:
            progress(f"{modal.frequency_hz.size - 1 - len(mounts)} modes up to {settings.max_mode_hz:g} Hz and "
                     f"a residual pseudo-mode at {modal.frequency_hz[-1]:.0f} Hz")
        details = {}
        if name == "underfloor_equipment":
            tuned = choose_tuned_mode(modal, mount_shape, effect_rng)
            detuning = float(effect_rng.uniform(-EQUIPMENT_DETUNING, EQUIPMENT_DETUNING))
            equipment = UnderfloorEquipment(effect.magnitude * carbody_mass(model), mounts[0].position,
                                            float(modal.frequency_hz[tuned] * (1 + detuning)))
            coupled = add_equipment(modal, mount_shape, equipment)
            details = _equipment_record(coupled, tuned, detuning, carbody_mass(model), modal.damping_ratio,
                                        settings.truth_band_hz)
            modal = coupled.modal
            if progress:
                split = ", ".join(f"{v:.2f}" for v in details["split_modes"].values())
                progress(f"underfloor equipment {equipment.mass:.0f} kg at {equipment.position[:2]} m on "
                         f"{equipment.frequency_hz:.2f} Hz: mode {tuned + 1} at "
                         f"{details['tuned_mode']['frequency_hz']:.2f} Hz splits into {split} Hz")
        elif name == "local_panel_softening":
            unsoftened = truth_modes(parameters, settings=settings, model=model)
            details = _softening_record(modal, unsoftened, panel, settings.truth_band_hz)
        elif name == "force_calibration":
            details = {"sensor": EXCITER.name, "force_gain": effect.magnitude}
        elif name == "sensor_bracket":
            details = {"sensor": bracket.sensor, "frequency_hz": bracket.frequency_hz,
                       "damping_ratio": bracket.damping_ratio,
                       "peak_transmissibility": float(np.abs(bracket.transmissibility(bracket.frequency_hz)))}
        runs = []
        for k in range(settings.runs):
            run_id = f"run_{k + 1:03d}"
            cols, info = simulate_run(modal, settings, rng, bracket)
            if name == "force_calibration":  # the load cell reads the force times the gain, noise and all
                cols = {**cols, EXCITER.name: cols[EXCITER.name] * effect.magnitude}
            w.write_run(run_id, cols)
            runs.append({"run_id": run_id, **info})
            if progress:
                progress(f"{run_id}: {settings.run_duration:g} s, force {info['force_rms_n']:.0f} N rms")
        w.commit()
    listed, labels = _labels(modal, settings.truth_band_hz)
    f_pole, zeta_pole = modal.poles()
    truth = {
        "format": TRUTH_FORMAT, "kind": "stationary_excitation", "seed": seed, "campaign": out.name,
        "model": "box", "parameters": modal.parameters,
        "frequencies_hz": {lb: float(f_pole[k]) for lb, k in zip(labels, listed)},
        "damping_ratios": {lb: float(zeta_pole[k]) for lb, k in zip(labels, listed)},
        "mode_kinds": {lb: modal.kind[k] for lb, k in zip(labels, listed)},
        "mode_shapes": _unit_shapes(modal.sensor_shapes[:, listed]).T.tolist(),  # per mode, in sensor order
        "sensors": [s.name for s in SENSOR_GRID],
        "exciter": {"sensor": EXCITER.name, "position": list(EXCITER.position), "direction": "z",
                    "panel": floor_panel(EXCITER.position[0])},
        "effect": None if effect is None else {**effect.to_json(), **details},
        "modes_kept": {"count": int(np.sum(np.array(modal.kind) != "residual")), "max_hz": settings.max_mode_hz,
                       "residual_pseudo_mode_hz": float(modal.frequency_hz[-1]),
                       "frequencies_hz": f_pole.tolist(), "damping_ratios": zeta_pole.tolist(),
                       "kinds": list(modal.kind)},
        "settings": asdict(settings),
        "runs": runs,
    }
    write_json_atomic(Path(f"{out}.truth.json"), truth)
    return truth
