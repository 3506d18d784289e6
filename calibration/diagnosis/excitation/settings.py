"""How an excitation test is diagnosed: one frozen settings object that checks itself."""
from __future__ import annotations

from dataclasses import dataclass, field

from ... import checks
from ...identification.excitation import ExcitationIdentifySettings
from ...optimisers.pso import PSOSettings


def _small_swarm() -> PSOSettings:
    """The baseline's swarm: one swarm of 40 particles x 40 iterations, stopped at 0.5 %
    (docs/methods/diagnosis-excitation.md, section 1): the FRF refinement after it fixes
    the factors, so the swarm only has to find the basin."""
    return PSOSettings(particles=40, iterations=40, target=0.5)


def _modes_only() -> ExcitationIdentifySettings:
    return ExcitationIdentifySettings(standard_errors=False)


@dataclass(frozen=True, kw_only=True)
class ExcitationDiagnosisSettings:
    """How an excitation test is diagnosed (SI units; frequencies in Hz).

    Attributes
    ----------
    identify : identification of the training and held-out FRFs (H1, p-LSCF); its ``nperseg``,
        ``band`` etc. have the meanings of :class:`calibration.identification.excitation.ExcitationIdentifySettings`
        (by default without the modes' standard errors, which the diagnosis does not read).
    band : (low, high) [Hz], the FRF comparison band (inside the exciter's 5-50 Hz force band).
    pso : the baseline's particle swarm on the identified modes.
    seed : the swarm's generator seed.
    basis_hz : [Hz] every reduced basis keeps all full-model modes below this (at the nominal
        factors); more than twice the band's top, since modes just above the band shape the
        accelerance inside it.
    derivative_modes : lowest modes whose parameter derivatives enter the basis.
    basis_extra : derivative directions, compressed to this many basis vectors.
    damping_range : (low, high), the elastic modal damping ratios fitted [-].
    floor : model accuracy floor in the error's standard deviation [-] (0.01: 1 %).
    refine_iterations : least-squares iterations per refinement (at least 3: a quick fit,
        ranking starts, runs a third of them).
    starts : global-search candidates of each extension refined (briefly; the best fully).
    min_gain : penalised held-out error reduction a cause needs [-].
    penalty : subtracted from the gain per extension parameter [-].
    max_loss : largest held-out worsening of any channel a cause may bring, in units of that
        channel's error or of the noise where the error is below it [-].
    noise_alarm : baseline held-out error (1 = the noise) above which a misfit is systematic.
    mac_alarm : an identified mode pairs with a model mode if their MAC is at least this ...
    frequency_alarm : ... and their frequencies differ by less than this (relative).
    mode_band : an unpaired mode alarms if the held-out error within this (relative) of its
        frequency exceeds ``noise_alarm``.
    one_channel : share of the excess misfit on one channel above which the evidence names it.
    """

    identify: ExcitationIdentifySettings = field(default_factory=_modes_only)
    band: tuple[float, float] = (6.0, 30.0)
    pso: PSOSettings = field(default_factory=_small_swarm)
    seed: int = 0
    basis_hz: float = 70.0
    derivative_modes: int = 16
    basis_extra: int = 40
    damping_range: tuple[float, float] = (0.002, 0.15)
    floor: float = 0.01
    refine_iterations: int = 40
    starts: int = 3
    min_gain: float = 0.3
    penalty: float = 0.01
    max_loss: float = 0.2
    noise_alarm: float = 3.0
    mac_alarm: float = 0.8
    frequency_alarm: float = 0.03
    mode_band: float = 0.03
    one_channel: float = 0.5

    def bar(self, n_params: int) -> float:
        """The held-out gain an extension of ``n_params`` parameters must clear: ``min_gain``
        plus ``penalty`` per parameter (as the in-service settings')."""
        return self.min_gain + self.penalty * n_params

    def __post_init__(self):
        name = type(self).__name__
        for key, kind in (("identify", ExcitationIdentifySettings), ("pso", PSOSettings)):
            if not isinstance(getattr(self, key), kind):
                raise ValueError(f"{name}.{key} must be a {kind.__name__}, got {getattr(self, key)!r}")
        checks.increasing(self, "band", low=0.0)
        if not self.band[0] > 0:
            raise ValueError(f"{name}.band must have a low end > 0 Hz, got {self.band!r}")
        checks.increasing(self, "damping_range", low=0.0)
        if not (0 < self.damping_range[0] and self.damping_range[1] < 1):
            raise ValueError(f"{name}.damping_range must satisfy 0 < low < high < 1, got {self.damping_range!r}")
        checks.positive(self, "basis_hz", "floor", "min_gain", "max_loss", "noise_alarm")
        if not self.basis_hz > 2 * self.band[1]:
            raise ValueError(f"{name}.basis_hz must exceed twice the band's top ({self.band[1]:g} Hz), got "
                             f"{self.basis_hz!r}: modes just above the band shape the accelerance inside it")
        checks.whole(self, "seed", "derivative_modes", "basis_extra", minimum=0)
        checks.whole(self, "starts", minimum=1)
        checks.whole(self, "refine_iterations", minimum=3)  # a quick fit runs a third of them
        checks.non_negative(self, "penalty")
        if not self.noise_alarm > 1:
            raise ValueError(f"{name}.noise_alarm must be > 1 (1 is the noise), got {self.noise_alarm!r}")
        checks.fraction(self, "mac_alarm", "one_channel", closed=True)
        checks.fraction(self, "frequency_alarm", "mode_band")
        for key in ("mac_alarm", "one_channel", "frequency_alarm", "mode_band"):
            if not getattr(self, key) > 0:
                raise ValueError(f"{name}.{key} must be > 0, got {getattr(self, key)!r}")
