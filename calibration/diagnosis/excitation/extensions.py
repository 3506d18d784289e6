"""The registry of hypotheses: one extension of the box model per excitation-test cause of
the effects catalogue. Adding a cause is one entry here (and its fit)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .equipment import fit_equipment
from .force import fit_force
from .softening import DIVISOR_RANGE, fit_softening


@dataclass(frozen=True)
class ExcitationExtension:
    """One cause of the effects catalogue as a physical addition to the box model.

    parameters : what is fitted (counted for the complexity penalty)
    fit : (context, baseline fit) -> list of fits, best first
    null_end : (parameter, value) where the effect vanishes: the edge of its search (a
        softening divisor), or 1 for a gain. A fit that ends within ``null_tol`` of it (in
        log) gains by adjusting the baseline, not by the effect, and is not named as the
        cause; for the force gain that 1 % is a load cell's calibration tolerance
    uniform_level : the effect is one factor on every channel (the force gain): it is named
        only where that factor stands above the channels' own level scatter
        (:data:`.force.UNIFORM`)
    """

    name: str
    description: str
    parameters: tuple[str, ...]
    fit: Callable
    null_end: tuple[str, float] | None = None
    null_tol: float = 0.01
    uniform_level: bool = False

    def at_null_end(self, parameters: dict) -> bool:
        """Whether the fitted ``parameters`` end within :attr:`null_tol` (log) of :attr:`null_end`."""
        if self.null_end is None:
            return False
        name, value = self.null_end
        return bool(abs(np.log(float(parameters[name]) / value)) <= self.null_tol)

    @property
    def n_params(self) -> int:
        return len(self.parameters)


#: The registry: one extension per excitation-test cause of the effects catalogue.
EXTENSIONS: dict[str, ExcitationExtension] = {e.name: e for e in (
    ExcitationExtension(
        "underfloor_equipment",
        "a resiliently mounted underfloor mass: rigid mass on a vertical spring-damper under a floor point, "
        "coupled to the carbody's modes through their values at the mount",
        ("equipment_mass_kg", "mounting_frequency_hz", "mounting_damping_ratio", "mount_x_m", "mount_y_m"),
        fit_equipment),
    ExcitationExtension(
        "local_panel_softening",
        "one carbody panel (the roof or a floor panel, as the effects catalogue's) with its rigidities divided by "
        "its own factor",
        ("panel", "rigidity_divisor"), fit_softening, null_end=("rigidity_divisor", DIVISOR_RANGE[0])),
    ExcitationExtension(
        "force_calibration",
        "the exciter's force sensor reads the applied force times a gain (its calibration factor off), so every "
        "FRF is the structure's divided by it; a carbody mass and stiffness all off by one factor would read the "
        "same",
        ("force_gain",), fit_force, null_end=("force_gain", 1.0), uniform_level=True),
)}
