"""Every settings class checks itself: a negative, zero, inverted or unknown value is refused
with a message naming the class and the field."""
import pytest

from calibration.calibrate_box import PairingSettings, RefineSettings, SwarmSettings
from calibration.identification.excitation import ExcitationIdentifySettings
from calibration.identification.fdd import FDDSettings
from calibration.identification.in_service import IdentifySettings
from calibration.models.box.modal import ModalSettings
from calibration.optimisers.cross_entropy import CESettings
from calibration.optimisers.pso import PSOSettings
from calibration.signals.spectral_lines import LineSettings
from calibration.truth.excitation import ExcitationSettings
from calibration.truth.in_service import InServiceSettings
from calibration.truth.track import LineSpec

BAD = [
    (FDDSettings, {"segment_length": -1.0}, "segment_length"),
    (FDDSettings, {"welch_s": 0.0}, "welch_s"),
    (FDDSettings, {"overlap": 1.0}, "overlap"),
    (FDDSettings, {"band": (20.0, 2.0)}, "band"),
    (LineSettings, {"window_s": -8.0}, "window_s"),
    (LineSettings, {"welch_s": 10.0}, "welch_s"),
    (LineSettings, {"impact_lags": (100.0, 5.0)}, "impact_lags"),
    (ExcitationIdentifySettings, {"band": (24.0, 6.0)}, "band"),
    (ExcitationIdentifySettings, {"nperseg": 0}, "nperseg"),
    (ExcitationIdentifySettings, {"orders": (20, 16)}, "orders"),
    (ExcitationIdentifySettings, {"cluster_mac": 1.5}, "cluster_mac"),
    (ExcitationIdentifySettings, {"local_share": 1.2}, "local_share"),
    (ExcitationIdentifySettings, {"local_min_channels": 1}, "local_min_channels"),
    (IdentifySettings, {"carbody_band": (4.0, 0.4)}, "carbody_band"),
    (IdentifySettings, {"min_coherence": -0.1}, "min_coherence"),
    (IdentifySettings, {"bogie_band_factor": 1.0}, "bogie_band_factor"),
    (IdentifySettings, {"max_extra_order": 0}, "max_extra_order"),
    (PSOSettings, {"particles": 1}, "particles"),
    (PSOSettings, {"max_velocity": -0.2}, "max_velocity"),
    (CESettings, {"elite_fraction": 1.5}, "elite_fraction"),
    (ModalSettings, {"max_mode_hz": -1.0}, "max_mode_hz"),
    (ModalSettings, {"suspension_damping": (0.3, 0.02)}, "suspension_damping"),
    (ExcitationSettings, {"runs": 0}, "runs"),
    (ExcitationSettings, {"elastic_damping": (0.03, 0.01)}, "elastic_damping"),
    (InServiceSettings, {"speed_range": (45.0, 20.0)}, "speed_range"),
    (InServiceSettings, {"axle_acc_noise": -0.1}, "axle_acc_noise"),
    (InServiceSettings, {"journeys": 0}, "journeys"),
    (LineSpec, {"min_wavelength": 80.0, "max_wavelength": 3.0}, "wavelength"),
    (SwarmSettings, {"swarms": 0}, "swarms"),
    (SwarmSettings, {"done_pct": -0.1}, "done_pct"),
    (RefineSettings, {"rounds": 0}, "rounds"),
    (RefineSettings, {"polish_steps": -1}, "polish_steps"),
    (PairingSettings, {"min_mac": 1.2}, "min_mac"),
]


@pytest.mark.parametrize("cls, kwargs, field", BAD, ids=[f"{c.__name__}-{f}" for c, _, f in BAD])
def test_a_bad_value_is_refused_naming_its_field(cls, kwargs, field):
    with pytest.raises(ValueError, match=field):
        cls(**kwargs)


@pytest.mark.parametrize("cls", sorted({c for c, _, _ in BAD}, key=lambda c: c.__name__))
def test_defaults_are_valid_and_unknown_names_are_refused(cls):
    settings = cls()
    with pytest.raises(TypeError, match="nosuch"):
        cls(nosuch=1)
    with pytest.raises(AttributeError):  # frozen: settings cannot change after they are checked
        settings.__setattr__(next(iter(settings.__dataclass_fields__)), None)
