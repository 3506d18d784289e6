"""An independent truth simulator for in-service campaigns, built in exudyn.

It shares no model-building code with railcal (``calibration.models``, the diagnosis or
the other truth simulators); an import-linter contract in pyproject.toml and a test hold
that. See docs/methods/truth-independent.md.
"""
from .campaign import IndependentSettings, synth_in_service_independent, truth_line
from .hidden import HiddenEffect, parse_hidden
from .vehicles import VEHICLES, VehicleSpec, vehicle

__all__ = ["IndependentSettings", "synth_in_service_independent", "truth_line", "HiddenEffect", "parse_hidden",
           "VEHICLES", "VehicleSpec", "vehicle"]
