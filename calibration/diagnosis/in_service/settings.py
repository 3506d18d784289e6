"""The in-service diagnosis's settings: how records are read, the wheel and track fits,
and the thresholds of the evidence and of the decision."""
from __future__ import annotations

from dataclasses import dataclass, field

from .records import RecordSettings
from .track import TrackSettings
from .wheels import WheelSettings


@dataclass(frozen=True, kw_only=True)
class DiagnosisSettings:
    """Settings of :func:`~calibration.diagnosis.in_service.diagnose_in_service`.

    The thresholds' defaults were set while the diagnosis was developed on synthetic
    campaigns (seeds 3-58 and the benches of seeds 1000-1879 in docs/CHANGELOG.md's
    measurement log); later fresh-seed benches measured them (docs/methods/diagnosis-in-service.md).
    """

    records: RecordSettings = field(default_factory=RecordSettings)
    wheels: WheelSettings = field(default_factory=WheelSettings)
    track: TrackSettings = field(default_factory=TrackSettings)
    min_gain: float = 0.15  # penalised held-out error reduction for a cause
    penalty: float = 0.01  # subtracted from the gain per extension parameter
    max_loss: float = 0.05  # largest held-out worsening of any channel (relative, and against the gain)
    # a response extension must explain the systematic residual it gains on: on its best
    # channel, held-out error x residual input-coherence, after / before, at most this
    max_systematic_left: float = 0.25
    coherence_alarm: float = 0.35  # residual input-coherence (mean over signal bands) that is systematic
    # held-out NRP x residual input-coherence under which a channel's residual is within a
    # model's accuracy: the coherent error's rms under 10 % of the channel's, the agreement a
    # validation of simulation against test (e.g. EN 14363's) asks of a model
    systematic_floor: float = 0.01
    # a cause gaining at least this (penalised) on held-out data is named, with confidence
    # low, though every channel it gains on was within the floor: the reservoirs the floor
    # hid gained 50-72 % there, clean cars 0-0.5 % (docs/methods/diagnosis-in-service.md);
    # None: never below the floor
    under_floor_gain: float | None = 0.40
    peak_alarm: float = 4.0  # residual PSD peak over its floor
    line_alarm: float = 30.0  # wheel-line power over floor (with one-sided wheelset asymmetry)
    asymmetry: float = 2.0  # line power ratio between the two axle boxes of a wheel line
    fit_leading: int = 10  # hypotheses fitted, best evidence first
    starts: int = 6  # global-stage starts of a response extension's fit
    screen: int = 64  # global-stage candidates whose cost is evaluated; the ``starts`` cheapest are refined
    signal_factor: float = 4.0  # a signal band stands this far above the channel's spectral floor
    input_noise_share: float = 0.3  # bands where input noise makes more of the residual are not evidence
    prior_spread: float = 3.0  # search factor around nominal for parameters without priors

    def bar(self, n_params: int) -> float:
        """The held-out gain an extension of ``n_params`` parameters must clear: ``min_gain``
        plus ``penalty`` per parameter."""
        return self.min_gain + self.penalty * n_params

    def __post_init__(self):
        for name in ("penalty", "max_loss"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"DiagnosisSettings.{name} must be zero or positive, got {getattr(self, name)}")
        for name in ("min_gain", "max_systematic_left", "systematic_floor", "peak_alarm", "line_alarm", "signal_factor",
                     "input_noise_share"):
            if not getattr(self, name) > 0:
                raise ValueError(f"DiagnosisSettings.{name} must be positive, got {getattr(self, name)}")
        if not 0 < self.coherence_alarm <= 1:
            raise ValueError(f"DiagnosisSettings.coherence_alarm must be in (0, 1], got {self.coherence_alarm}")
        if not self.asymmetry >= 1:
            raise ValueError(f"DiagnosisSettings.asymmetry must be at least 1 (a ratio), got {self.asymmetry}")
        if self.under_floor_gain is not None and not 0 < self.under_floor_gain < 1:
            raise ValueError("DiagnosisSettings.under_floor_gain must be in (0, 1) or None, "
                             f"got {self.under_floor_gain}")
        if not self.prior_spread > 1:
            raise ValueError(f"DiagnosisSettings.prior_spread must be above 1 (a factor), got {self.prior_spread}")
        for name in ("fit_leading", "starts", "screen"):
            if not getattr(self, name) >= 1:
                raise ValueError(f"DiagnosisSettings.{name} must be at least 1, got {getattr(self, name)}")
