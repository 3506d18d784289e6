"""The hidden effects of the synthetic stationary excitation test
(:mod:`calibration.truth.excitation`), and the sensor bracket outside the catalogue.

Hidden effects (:mod:`calibration.truth.effects`; their details come from a second
generator, ``default_rng([seed, EFFECT_STREAM])``, so the effect-free campaign of a seed
is unchanged and the same seed draws the same vehicle parameters with or without one):

* ``underfloor_equipment``: a rigid mass m_e = MAGNITUDE x the carbody mass hung on a
  vertical spring-damper (damping ratio 5 %) under a floor point off the centre line
  (x drawn in -7..7 m between the bolsters, y = +-0.8 m, side drawn, at least 2 m from the
  exciter). Its mounting frequency sqrt(k_e / m_e) is the frequency of one carbody elastic
  mode in 8-20 Hz times 1 + U(-4 %, +4 %); the mode is drawn among those the mount point
  and the exciter-to-sensor path both see (each >= 1/4 of the best in the band). The
  equipment is one more DOF coupled to the modal truth through the modes' values at the
  mount point, the modal basis carrying a second residual pseudo-mode (the static response
  of the omitted modes to a load at the mount), so the coupled frequencies equal the full
  box model's with the extra DOF (to 1e-5, tested). The coupled (modal + 1) system is
  re-diagonalised (:func:`add_equipment`): undamped modes, and the damping matrix in their
  coordinates kept whole (the mount's damper couples the split modes), so the simulation
  and :meth:`ModalModel.frf` are exact and the truth lists the damped system's poles.
  The tuned mode splits into a coupled mode below and one above its frequency
  (:meth:`EquipmentModes.split`); the split (about sqrt(m_e phi^2) of the frequency for an
  isolated mode) is often wider than the spacing of the carbody's modes, so neighbouring
  modes take part too.
* ``local_panel_softening``: one of the roof, front, middle and rear floor panels (drawn)
  has its eight rigidities divided by MAGNITUDE; the vehicle is re-assembled with that
  panel's properties (:func:`soften_panel`); the stiffness factors of its group still act
  on it. The roof is a single panel, so its softening equals roof_membrane and
  roof_bending factors / MAGNITUDE; a floor panel's cannot be expressed by the factors.
* ``force_calibration``: the exciter's force sensor reads MAGNITUDE times the applied
  force (its calibration factor off). The structure and every draw are the effect-free
  campaign's; only the recorded force column, noise included, is scaled
  (:func:`calibration.truth.excitation.synth_excitation`).

Outside the catalogue (:data:`calibration.truth.effects.UNCATALOGUED`; the diagnosis has
no extension for it and must answer ``unexplained``):

* ``sensor_bracket``: one floor accelerometer (drawn among :data:`SENSOR_GRID`, not the
  two next to the exciter) sits on a resilient bracket, a base-excited oscillator of
  natural frequency MAGNITUDE and damping ratio drawn in 3-6 % between the floor point and
  the sensor: that channel records the floor's acceleration through the transmissibility
  T(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2) (:class:`SensorBracket`), appended
  to the modal state space in series, so the simulation stays exact. The structure is
  unchanged; :func:`truth_model` returns it (the bracket is the measurement's, in the
  truth file's ``effect``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg

from ..data.campaign import Sensor
from ..models.box import BoxModel, assemble
from ..models.box.modal import ModalModel
from ..models.box.rig import EXCITER, GEOMETRY, SENSOR_GRID
from ..models.car2d import StateSpace

EFFECT_STREAM = 7  #: effect details come from ``np.random.default_rng([seed, EFFECT_STREAM])``
SOFTENING_PANELS = ("roof", "floor_front", "floor_middle", "floor_rear")  #: candidates, drawn uniformly
EQUIPMENT_X = (-7.0, 7.0)  #: [m] mount point x, drawn uniformly (between the bogie bolsters at +-8.75 m)
EQUIPMENT_Y = 0.8  #: [m] mount point |y| (off the centre line; the side is drawn)
EQUIPMENT_CLEARANCE = 2.0  #: [m] least distance of the mount point from the exciter (redrawn if closer)
EQUIPMENT_BAND = (8.0, 20.0)  #: [Hz] elastic modes the mount may be tuned to
EQUIPMENT_DETUNING = 0.04  #: mounting frequency = tuned mode's x (1 + U(-0.04, 0.04))
EQUIPMENT_DAMPING = 0.05  #: mount damping ratio c_e / (2 sqrt(k_e m_e))


BRACKET_DAMPING = (0.03, 0.06)  #: sensor bracket damping ratio, drawn uniformly
BRACKET_CLEARANCE = 2.0  #: [m] the bracketed sensor is at least this far from the exciter (so its FRF is not the drive point's)


@dataclass(frozen=True)
class SensorBracket:
    """An accelerometer on a resilient bracket (outside the catalogue): a base-excited
    oscillator between the floor point and the sensor, so the channel reads the floor's
    acceleration through T(s) = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2). SI units."""

    sensor: str  # the channel of :data:`SENSOR_GRID` on the bracket
    frequency_hz: float  # [Hz] w / 2 pi (on a rigid floor)
    damping_ratio: float  # [-]

    def __post_init__(self):
        if self.sensor not in [s.name for s in SENSOR_GRID]:
            raise ValueError(f"no sensor {self.sensor!r} in the sensor grid")
        if not (self.frequency_hz > 0 and self.damping_ratio > 0):
            raise ValueError(f"a bracket needs frequency_hz > 0 and damping_ratio > 0; got {self.frequency_hz} Hz, "
                             f"{self.damping_ratio}")

    def transmissibility(self, f) -> np.ndarray:
        """T(i 2 pi f): the sensor's acceleration over the floor point's [-]."""
        s, w, z = 2j * np.pi * np.asarray(f, float), 2 * np.pi * self.frequency_hz, self.damping_ratio
        return (2 * z * w * s + w**2) / (s**2 + 2 * z * w * s + w**2)

    def in_series(self, ss: StateSpace) -> StateSpace:
        """``ss`` with the bracket between its output ``sensor`` and what is measured: two
        states xi (xi1' = xi2, xi2' = -w^2 xi1 - 2 zeta w xi2 + a) driven by the floor's
        acceleration a = C_k x + D_k u; the channel reads w^2 xi1 + 2 zeta w xi2."""
        k = ss.outputs.index(self.sensor)
        w, z = 2 * np.pi * self.frequency_hz, self.damping_ratio
        n = ss.A.shape[0]
        Ab, Bb, Cb = np.array([[0.0, 1.0], [-w**2, -2 * z * w]]), np.array([[0.0], [1.0]]), np.array([w**2, 2 * z * w])
        A = np.block([[ss.A, np.zeros((n, 2))], [Bb @ ss.C[k:k + 1], Ab]])
        B = np.vstack([ss.B, Bb @ ss.D[k:k + 1]])
        C = np.hstack([ss.C, np.zeros((ss.C.shape[0], 2))])
        C[k] = np.concatenate([np.zeros(n), Cb])
        D = ss.D.copy()
        D[k] = 0.0
        return StateSpace(A, B, C, D, ss.outputs, ss.inputs)


def draw_bracket(rng: np.random.Generator, frequency_hz: float, exciter=EXCITER) -> SensorBracket:
    """The bracketed sensor (uniformly among those at least :data:`BRACKET_CLEARANCE` from
    the exciter) and its damping."""
    far = [s.name for s in SENSOR_GRID
           if np.hypot(s.position[0] - exciter.position[0], s.position[1] - exciter.position[1]) >= BRACKET_CLEARANCE]
    return SensorBracket(far[int(rng.integers(len(far)))], frequency_hz, float(rng.uniform(*BRACKET_DAMPING)))


def soften_panel(model: BoxModel, panel: str, divisor: float) -> BoxModel:
    """The vehicle of ``model`` re-assembled with the eight rigidities of ``panel`` divided
    by ``divisor`` (the stiffness factors of its group still multiply them)."""
    names = [pn.name for pn in model.vehicle.panels]
    if panel not in names:
        raise ValueError(f"no panel {panel!r}; panels: {', '.join(names)}")
    if not divisor > 0:
        raise ValueError(f"rigidity divisor must be positive, got {divisor}")
    panels = tuple(replace(pn, rigidity={k: v / divisor for k, v in pn.rigidity.items()}) if pn.name == panel
                   else pn for pn in model.vehicle.panels)
    return assemble(replace(model.vehicle, panels=panels))


@dataclass(frozen=True)
class UnderfloorEquipment:
    """A rigid mass hung under the floor on a resilient mount: one vertical spring-damper
    between the mass and a floor point. SI units."""

    mass: float  # [kg] m_e
    position: tuple[float, float, float]  # [m] mount point on the floor, carbody frame
    frequency_hz: float  # [Hz] mounting frequency sqrt(k_e / m_e) / (2 pi) (on a rigid floor)
    damping_ratio: float = EQUIPMENT_DAMPING  # [-] c_e / (2 sqrt(k_e m_e))

    def __post_init__(self):
        if not (self.mass > 0 and self.frequency_hz > 0 and self.damping_ratio >= 0):
            raise ValueError(f"underfloor equipment needs mass > 0, frequency_hz > 0 and damping_ratio >= 0; got "
                             f"{self.mass} kg, {self.frequency_hz} Hz, {self.damping_ratio}")

    @property
    def stiffness(self) -> float:
        """k_e [N/m]."""
        return self.mass * (2 * np.pi * self.frequency_hz) ** 2

    @property
    def damping(self) -> float:
        """c_e [N s/m]."""
        return 2 * self.damping_ratio * np.sqrt(self.stiffness * self.mass)

    def mount(self) -> Sensor:
        return mount_point(self.position)


def mount_point(position) -> Sensor:
    """The equipment's mount point as a vertical floor 'sensor' (where the modes are read)."""
    return Sensor("equipment_mount", "displacement", "m", "floor", "z", tuple(float(v) for v in position))


@dataclass(frozen=True, eq=False)
class EquipmentModes:
    """The modal truth with the equipment: ``modal`` (n + 1 modes); per coupled mode the
    equipment's displacement ``equipment_shape`` and the mount point's ``mount_shape``
    [1/sqrt(kg)]; ``structure`` (n, n + 1) the coupled modes in the uncoupled modes'
    coordinates (per column, its squares and m_e equipment_shape^2 sum to 1);
    ``uncoupled_hz`` (n,) the uncoupled frequencies [Hz] and ``uncoupled_mount`` (n,) the
    uncoupled modes' values at the mount point [1/sqrt(kg)]."""

    modal: ModalModel
    equipment_shape: np.ndarray  # (n + 1,)
    mount_shape: np.ndarray  # (n + 1,)
    structure: np.ndarray  # (n, n + 1)
    uncoupled_hz: np.ndarray  # (n,)
    uncoupled_mount: np.ndarray  # (n,)
    equipment: UnderfloorEquipment

    @property
    def equipment_share(self) -> np.ndarray:
        """Fraction of each coupled mode's kinetic energy in the equipment [-]."""
        return self.equipment.mass * self.equipment_shape**2

    def split(self, mode: int) -> tuple[int, int]:
        """The two coupled modes uncoupled mode ``mode`` splits into: of the coupled modes
        below its frequency, the one holding most of it (largest ``structure[mode]^2``),
        and likewise above. (With a heavy mass among close modes, the tuned mode spreads
        over more than two; these are its largest parts on either side.)"""
        content, below = self.structure[mode] ** 2, self.modal.frequency_hz < self.uncoupled_hz[mode]
        if below.all() or not below.any():
            raise ValueError(f"mode {mode} has no coupled mode on one side")
        return int(np.argmax(np.where(below, content, -1.0))), int(np.argmax(np.where(below, -1.0, content)))


def add_equipment(modal: ModalModel, mount_shape: np.ndarray, equipment: UnderfloorEquipment) -> EquipmentModes:
    """Couple ``equipment`` to ``modal`` at a floor point where the modes' vertical
    displacements are ``mount_shape`` (n,) [1/sqrt(kg)], and re-diagonalise.

    In the coordinates (q, z_e): M = diag(I, m_e); K = diag(omega^2, 0) + k_e b b^T,
    C = D + c_e b b^T with b = (mount_shape, -1) (the spring's extension), D the modal
    damping (or ``modal.damping_matrix``). The undamped problem K y = lambda M y gives the
    coupled modes (M-normalised); C in their coordinates is kept whole as the coupled
    model's ``damping_matrix``, so nothing is approximated. A coupled mode's kind is that
    of the uncoupled mode dominating it."""
    a = np.asarray(mount_shape, float)
    n = modal.frequency_hz.size
    if a.shape != (n,):
        raise ValueError(f"mount_shape has shape {a.shape}; the modal model has {n} modes")
    w = 2 * np.pi * modal.frequency_hz
    b = np.append(a, -1.0)
    M = np.diag(np.append(np.ones(n), equipment.mass))
    K = np.diag(np.append(w**2, 0.0)) + equipment.stiffness * np.outer(b, b)
    C = scipy.linalg.block_diag(modal._damping(), 0.0) + equipment.damping * np.outer(b, b)
    lam, Y = scipy.linalg.eigh(K, M)
    wc = np.sqrt(lam)
    D = Y.T @ C @ Y
    Yq = Y[:n]
    kind = tuple(modal.kind[k] for k in np.argmax(Yq**2, axis=0))
    suspension = np.einsum("kj,k,kj->j", Yq, 2 * modal.suspension_damping * w, Yq) / (2 * wc)
    coupled = ModalModel(parameters=modal.parameters, frequency_hz=wc / (2 * np.pi),
                         damping_ratio=np.diag(D) / (2 * wc), kind=kind, sensor_shapes=modal.sensor_shapes @ Yq, exciter_shape=Yq.T @ modal.exciter_shape,
                         suspension_damping=suspension, damping_matrix=D)
    return EquipmentModes(coupled, Y[n], a @ Yq, Yq, modal.frequency_hz, a, equipment)


def draw_equipment_position(rng: np.random.Generator, exciter=EXCITER) -> tuple[float, float, float]:
    """Mount point [m]: x uniform in :data:`EQUIPMENT_X`, y = +-:data:`EQUIPMENT_Y` (side
    drawn), on the floor; redrawn while within :data:`EQUIPMENT_CLEARANCE` of the exciter."""
    while True:
        x = float(rng.uniform(*EQUIPMENT_X))
        y = float(EQUIPMENT_Y * rng.choice([-1.0, 1.0]))
        if np.hypot(x - exciter.position[0], y - exciter.position[1]) >= EQUIPMENT_CLEARANCE:
            return round(x, 3), y, GEOMETRY.floor_z


def choose_tuned_mode(modal: ModalModel, mount_shape: np.ndarray, rng: np.random.Generator,
                      band: tuple[float, float] = EQUIPMENT_BAND) -> int:
    """Index of the mode the equipment is tuned to, drawn uniformly among the elastic
    modes in ``band`` [Hz] that the mount point moves in (mount_shape^2) and that the
    exciter drives at the sensors (|phi_e| x norm of the sensor shapes), each at least a
    quarter of the largest in the band (else the best by the product of the two)."""
    f = modal.frequency_hz
    cand = np.flatnonzero((f >= band[0]) & (f <= band[1]) & (np.asarray(modal.kind) == "elastic"))
    if cand.size == 0:
        raise ValueError(f"no elastic mode in {band} Hz to tune the underfloor equipment to")
    mu = np.asarray(mount_shape)[cand] ** 2
    seen = np.abs(modal.exciter_shape[cand]) * np.linalg.norm(modal.sensor_shapes[:, cand], axis=0)
    mu, seen = mu / mu.max(), seen / seen.max()
    ok = (mu >= 0.25) & (seen >= 0.25)
    if not ok.any():
        ok = np.arange(cand.size) == np.argmax(mu * seen)
    return int(rng.choice(cand[ok]))


