"""Diagnosis of an excitation test (a shaker test of the box-type carbody; campaign kind
``stationary_excitation``): what the calibrated carbody gets wrong, the cause, the extended
model and the held-out gain (docs/methods/diagnosis-excitation.md).

1. **Split** (:mod:`.data`). Odd runs train, even runs are held out; a single run is split
   into halves. Everything is fitted on the training part; the held-out part is used once,
   to judge.
2. **Baseline** (:mod:`.baseline`). Modes of the training FRFs (H1 + p-LSCF), the box
   model's stiffness factors calibrated to them by the seed's particle swarm with MAC
   pairing, then *FRF refinement*: the factors (within the campaign's priors) and the
   damping ratio of every elastic mode in the comparison band fitted by least squares to
   the training FRFs of all channels (:mod:`.least_squares`, :mod:`.fitting`).
3. **Evidence** (:mod:`.evidence`) from the baseline: held-out FRF misfit per channel
   (normalised, :mod:`.frf`; FRAC; rms log-magnitude error), the identified modes against
   the model's, factors at their bounds; a misfit confined to one channel is checked by
   calibrating the baseline again without that channel.
4. **Hypotheses** (:data:`EXTENSIONS`): ``underfloor_equipment`` (:mod:`.equipment`) and
   ``local_panel_softening`` (:mod:`.softening`), each fitted on the training FRFs from a
   global scan, then refined jointly with the baseline's factors and dampings.
5. **Decision** (:mod:`.decision`) on the held-out part: the cause is the hypothesis that
   reduces the held-out error most (penalised per parameter) if it reduces it enough;
   otherwise ``none`` when the baseline explains the held-out FRFs within the noise, else
   ``unexplained``.

The model is evaluated on reduced bases (:mod:`.basis`: Rayleigh-Ritz on modes,
parameter-derivative vectors and static responses of the full model, rebuilt around the
current point); every figure of the result is computed on a basis rebuilt at the final
parameters. The result is an :class:`ExcitationDiagnosis`; its figures are drawn by
:mod:`.plots`.
"""
from .diagnose import diagnose_excitation
from .extensions import EXTENSIONS, ExcitationExtension
from .result import ExcitationDiagnosis
from .settings import ExcitationDiagnosisSettings

__all__ = ["EXTENSIONS", "ExcitationDiagnosis", "ExcitationDiagnosisSettings", "ExcitationExtension",
           "diagnose_excitation"]
