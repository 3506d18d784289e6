"""The in-service diagnosis: what the calibrated 2D car gets wrong on an in-service
campaign, which physical effect of a catalogue explains it, and how much adding that
effect gains on held-out data.

:func:`diagnose_in_service` returns an :class:`InServiceDiagnosis`, made once, that
writes itself as JSON (``to_json``) and draws its figures (``plot``).

Modules: :mod:`.diagnose` (the flow and the decision), :mod:`.records` (the data's band
statistics), :mod:`.response` (the residual fit), :mod:`.evidence` (what the baseline's
residuals show), :mod:`.extensions` (the registry of causes), :mod:`.hypotheses` (an
extension fitted and judged), :mod:`.wheels` (wheel polygons), :mod:`.track` (track
flexibility), :mod:`.settings`, :mod:`.result` and :mod:`.plots` (the figures, imported
only when drawn).
"""
from .diagnose import diagnose_in_service
from .extensions import EXTENSIONS, Extension
from .hypotheses import Hypothesis
from .result import InServiceDiagnosis
from .settings import DiagnosisSettings

__all__ = ["EXTENSIONS", "DiagnosisSettings", "Extension", "Hypothesis", "InServiceDiagnosis", "diagnose_in_service"]
