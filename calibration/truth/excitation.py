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
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import scipy.signal
import scipy.sparse.linalg

from ..data.campaign import CampaignMeta, CampaignWriter, Excitation, Prior, Sensor, write_json_atomic
from ..models.box import SEARCH_PARAMETERS, BoxModel, assemble, shinkansen_vehicle
from ..models.box.fit import sensor_operator
from ..models.box.reduced import full_modes
from ..models.box.shinkansen import ORDERS, Geometry, floor_panel
from ..models.car2d import StateSpace
from ..models.simulate import ModalSimulator
from .effects import EffectChoice
from .in_service import TRUTH_FORMAT

# ---------------------------------------------------------------------------- sensors
GEOMETRY = Geometry()
PARAMETER_NAMES = tuple(q.name for q in SEARCH_PARAMETERS)


#: Floor accelerometers (our assumption for the seed's Figure 4): vertical, on the floor
#: (z = floor_z), at 9 stations x = +11.2 .. -11.2 m (step 2.8 m; station 01 at the front,
#: the bogie-1 end) on 3 lines y = +1.2 (l, left), 0 (c), -1.2 m (r, right). Named
#: ``acc_f<station>_<line>``, e.g. ``acc_f01_l``, in station-major order; in m/s^2, AC
#: coupled (no gravity). Each sits on the floor panel containing it (:func:`floor_panel`).
SENSOR_GRID: tuple[Sensor, ...] = tuple(
    Sensor(f"acc_f{i + 1:02d}_{line}", "acceleration", "m/s^2", "floor", "z", (round(11.2 - 2.8 * i, 1), y,
                                                                                GEOMETRY.floor_z))
    for i in range(9) for line, y in (("l", 1.2), ("c", 0.0), ("r", -1.2)))

#: The exciter pushes the floor up from below at an off-centre point, off every symmetry
#: line, so bending, torsion and breathing modes all respond; the load cell's channel.
#: Positive force is upward (+z) on the carbody.
EXCITER = Sensor("exciter_force", "force", "N", "floor", "z", (5.6, 0.8, GEOMETRY.floor_z))


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
        if self.order_change < 1 - min(min(o) for o in ORDERS.values()):
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
@dataclass(frozen=True, eq=False)
class ModalModel:
    """Modal model of the vehicle: kept modes and, last, the residual pseudo-mode.

    ``sensor_shapes[o, k]`` and ``exciter_shape[k]`` are the vertical displacements of
    M-normalised mode k at sensor o of :data:`SENSOR_GRID` and at the exciter [1/sqrt(kg)];
    ``kind[k]`` is ``"elastic"``, ``"carbody_rigid"``, ``"bogie"`` or ``"residual"``;
    ``suspension_damping`` the proportional estimate phi^T C phi / (2 omega) [-].
    """

    parameters: Mapping[str, float]
    frequency_hz: np.ndarray  # (n,)
    damping_ratio: np.ndarray  # (n,)
    kind: tuple[str, ...]
    sensor_shapes: np.ndarray  # (n_sensors, n)
    exciter_shape: np.ndarray  # (n,)
    suspension_damping: np.ndarray  # (n,)

    def frf(self, frequency) -> np.ndarray:
        """Accelerance H[i, o] = a_o / F [(m/s^2)/N] at ``frequency[i]`` [Hz], time
        dependence exp(+i omega t) (the convention of ``scipy.signal.csd``)."""
        w = 2 * np.pi * np.asarray(frequency, float)[:, None]
        wn = 2 * np.pi * self.frequency_hz[None, :]
        g = -w**2 * self.exciter_shape / (wn**2 - w**2 + 2j * self.damping_ratio * wn * w)
        return g @ self.sensor_shapes.T

    def state_space(self) -> StateSpace:
        """x = [q; q'] (modal), input the exciter force [N], outputs the sensors'
        accelerations [m/s^2] (with the feed-through of the force)."""
        n = self.frequency_hz.size
        wn = 2 * np.pi * self.frequency_hz
        dyn = np.hstack([-np.diag(wn**2), -np.diag(2 * self.damping_ratio * wn)])  # q'' = dyn x + phi_e f
        A = np.vstack([np.hstack([np.zeros((n, n)), np.eye(n)]), dyn])
        B = np.concatenate([np.zeros(n), self.exciter_shape])[:, None]
        C = self.sensor_shapes @ dyn
        D = (self.sensor_shapes @ self.exciter_shape)[:, None]
        return StateSpace(A, B, C, D, tuple(s.name for s in SENSOR_GRID), (EXCITER.name,))

    def listed(self, band: tuple[float, float]) -> np.ndarray:
        """Indices of the physical modes with frequency in ``band`` [Hz]."""
        f = self.frequency_hz
        return np.flatnonzero((f >= band[0]) & (f <= band[1]) & (np.asarray(self.kind) != "residual"))


def build_model(settings: ExcitationSettings = ExcitationSettings()) -> BoxModel:
    return assemble(shinkansen_vehicle(order_increase=settings.order_change))


def vertical_operators(model: BoxModel, sensors=SENSOR_GRID, exciter=EXCITER) -> tuple[np.ndarray, np.ndarray]:
    """Rows giving what the sensors read (n_sensors, n_dof) (:data:`SENSOR_GRID` by
    default) and the exciter's displacement along its direction (n_dof,); the exciter's
    row is also the generalised force of a unit force there."""
    return sensor_operator(model, sensors), sensor_operator(model, (exciter,))[0]


def _rigid_share(model: BoxModel, X: np.ndarray) -> np.ndarray:
    """Fraction of each mode's carbody motion that is a rigid-body motion (least-squares
    fit of a + theta x r to the displacements at 9 points of every panel)."""
    D, R = [], []
    for pn in model.vehicle.panels:
        for s in (-0.8, 0.0, 0.8):
            for t in (-0.8, 0.0, 0.8):
                r = np.asarray(pn.centre, float) + pn.axes[:, 0] * pn.a / 2 * s + pn.axes[:, 1] * pn.b / 2 * t
                D.append(model.displacement(pn.name, r))
                R.append(np.hstack([np.eye(3), [[0, r[2], -r[1]], [-r[2], 0, r[0]], [r[1], -r[0], 0]]]))
    d = np.vstack(D) @ X
    R = np.vstack(R)
    fit = R @ np.linalg.lstsq(R, d, rcond=None)[0]
    return np.sum(fit**2, axis=0) / np.sum(d**2, axis=0)


def truth_modes(parameters: Mapping[str, float] | None = None, *, damping=None,
                settings: ExcitationSettings = ExcitationSettings(), model: BoxModel | None = None,
                sensors=SENSOR_GRID, exciter=EXCITER) -> ModalModel:
    """Modal model of the full box model at ``parameters`` (factors by name; missing ones
    nominal 1): every mode up to ``settings.max_mode_hz`` and the residual pseudo-mode.

    ``damping``: ratios of all those modes, pseudo-mode last (a truth file's
    ``modes_kept.damping_ratios`` gives back exactly the simulated model). By default the
    suspension estimate for rigid-body-on-suspension modes and the middle of
    ``elastic_damping`` for elastic ones (the simulator draws these per seed).
    ``model``: the assembled vehicle, built from ``settings`` when not given.
    ``sensors``, ``exciter``: campaign sensors the shapes are taken at (default: this
    simulator's grid and exciter)."""
    parameters = dict(parameters or {})
    names = PARAMETER_NAMES if model is None else model.names
    unknown = sorted(set(parameters) - set(names))
    if unknown:
        raise ValueError(f"unknown parameter(s) {', '.join(unknown)}; known: {', '.join(names)}")
    model = build_model(settings) if model is None else model
    p = np.array([float(parameters.get(n, 1.0)) for n in model.names])
    n = min(150, model.n_dof - 2)
    while True:
        f, X = full_modes(model, p, n)
        if f[-1] > settings.max_mode_hz or n == model.n_dof - 2:
            break
        n = min(n + 60, model.n_dof - 2)
    keep = f <= settings.max_mode_hz
    f, X = f[keep], X[:, keep]
    w = 2 * np.pi * f
    S, e = vertical_operators(model, sensors, exciter)
    # residual pseudo-mode: static response of the omitted modes to the exciter force
    psi = scipy.sparse.linalg.splu(model.stiffness(p).tocsc()).solve(e) - X @ (X.T @ e / w**2)
    m_psi = psi @ (model.M @ psi)
    psi_hat = psi / np.sqrt(m_psi)
    f_res = np.sqrt((psi @ e) / m_psi) / (2 * np.pi)
    # kinds and the suspension's damping estimate
    bogies = np.concatenate([np.arange(model.n_dof)[model.dof_slices[b.name]] for b in model.vehicle.bodies])
    bogie_share = np.einsum("ij,ij->j", X[bogies], (model.M @ X)[bogies])
    rigid = _rigid_share(model, X)
    kind = tuple("bogie" if b > 0.5 else "carbody_rigid" if r > 0.95 else "elastic" for b, r in zip(bogie_share, rigid))
    zeta_s = np.einsum("ij,ij->j", X, model.C @ X) / (2 * w)
    zeta = np.append(np.where(np.array(kind) == "elastic", np.mean(settings.elastic_damping),
                              np.clip(zeta_s, *settings.suspension_damping)), settings.residual_damping)
    if damping is not None:
        if len(damping) != zeta.size:
            raise ValueError(f"damping has {len(damping)} ratios; the model keeps {zeta.size - 1} modes and the "
                             f"residual pseudo-mode ({zeta.size})")
        zeta = np.asarray(damping, float)
    return ModalModel(
        parameters={nm: float(v) for nm, v in zip(model.names, p)},
        frequency_hz=np.append(f, f_res), damping_ratio=zeta,
        kind=kind + ("residual",), sensor_shapes=np.column_stack([S @ X, S @ psi_hat]),
        exciter_shape=np.append(X.T @ e, psi_hat @ e), suspension_damping=np.append(zeta_s, 0.0))


# ------------------------------------------------------------------------------ runs
def band_random(n: int, fs: float, band: tuple[float, float], rms: float, rng: np.random.Generator) -> np.ndarray:
    """Gaussian random signal of ``n`` samples at ``fs`` [Hz] with a flat spectrum in
    ``band`` [Hz] and none outside (FFT synthesis), scaled to ``rms``."""
    spectrum = np.fft.rfft(rng.standard_normal(n))
    nu = np.fft.rfftfreq(n, 1.0 / fs)
    spectrum[(nu < band[0]) | (nu > band[1])] = 0.0
    x = np.fft.irfft(spectrum, n)
    return x * (rms / x.std())


def anti_alias_sos(settings: ExcitationSettings) -> np.ndarray:
    """The logger's anti-alias low-pass (Butterworth, at the simulation rate)."""
    return scipy.signal.butter(settings.anti_alias_order, settings.anti_alias_hz, fs=settings.fs_sim, output="sos")


def simulate_run(modal: ModalModel, settings: ExcitationSettings, rng: np.random.Generator) -> tuple[dict, dict]:
    """One test run: columns ``time`` [s], ``exciter_force`` [N] and the accelerometers
    [m/s^2] at ``settings.fs``, and the run's truth (force rms, offsets)."""
    step = round(settings.fs_sim / settings.fs)
    n_pre = round(settings.pre_roll * settings.fs) * step
    n_out = round(settings.run_duration * settings.fs)
    n = n_pre + n_out * step
    force = band_random(n, settings.fs_sim, settings.band, settings.force_rms, rng)
    sim = ModalSimulator(modal.state_space(), 1.0 / settings.fs_sim)
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


def synth_excitation(out, *, seed: int = 0, settings: ExcitationSettings = ExcitationSettings(),
                     effect: EffectChoice | None = None, fmt: str = "csv", overwrite: bool = False,
                     model: BoxModel | None = None, progress=None) -> dict:
    """Write a synthetic stationary excitation campaign to ``out`` and its truth to
    ``out.truth.json``; returns the truth. ``model``: the assembled vehicle (built from
    ``settings`` when not given; pass it to reuse one assembly over many seeds)."""
    if effect is not None:
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
        modal = truth_modes(parameters, settings=settings, model=model)
        elastic = np.array(modal.kind) == "elastic"
        modal = replace(modal, damping_ratio=np.where(elastic, rng.uniform(*settings.elastic_damping, elastic.size),
                                                      modal.damping_ratio))
        if progress:
            progress(f"{modal.frequency_hz.size - 1} modes up to {settings.max_mode_hz:g} Hz and a residual "
                     f"pseudo-mode at {modal.frequency_hz[-1]:.0f} Hz")
        runs = []
        for k in range(settings.runs):
            run_id = f"run_{k + 1:03d}"
            cols, info = simulate_run(modal, settings, rng)
            w.write_run(run_id, cols)
            runs.append({"run_id": run_id, **info})
            if progress:
                progress(f"{run_id}: {settings.run_duration:g} s, force {info['force_rms_n']:.0f} N rms")
        w.commit()
    listed = modal.listed(settings.truth_band_hz)
    labels = [f"mode_{k + 1:02d}" for k in listed]  # numbered as in the full model, lowest first
    truth = {
        "format": TRUTH_FORMAT, "kind": "stationary_excitation", "seed": seed, "campaign": out.name,
        "model": "box", "parameters": modal.parameters,
        "frequencies_hz": {lb: float(modal.frequency_hz[k]) for lb, k in zip(labels, listed)},
        "damping_ratios": {lb: float(modal.damping_ratio[k]) for lb, k in zip(labels, listed)},
        "mode_kinds": {lb: modal.kind[k] for lb, k in zip(labels, listed)},
        "mode_shapes": _unit_shapes(modal.sensor_shapes[:, listed]).T.tolist(),  # per mode, in sensor order
        "sensors": [s.name for s in SENSOR_GRID],
        "exciter": {"sensor": EXCITER.name, "position": list(EXCITER.position), "direction": "z",
                    "panel": floor_panel(EXCITER.position[0])},
        "effect": None if effect is None else effect.to_json(),
        "modes_kept": {"count": int(modal.frequency_hz.size - 1), "max_hz": settings.max_mode_hz,
                       "residual_pseudo_mode_hz": float(modal.frequency_hz[-1]),
                       "frequencies_hz": modal.frequency_hz.tolist(), "damping_ratios": modal.damping_ratio.tolist(),
                       "kinds": list(modal.kind)},
        "settings": asdict(settings),
        "runs": runs,
    }
    write_json_atomic(Path(f"{out}.truth.json"), truth)
    return truth
