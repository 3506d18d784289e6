"""The vehicle models railcal calibrates, one entry each: what the commands do for the model,
from identification to the FMU. The commands dispatch through :data:`MODELS` and the tests
loop over it, so adding a vehicle model is one entry here (and its functions)."""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from calibration.data.errors import InputError
from fmu_src.export import box_fmu_spec, car2d_fmu_spec

from . import box, car2d
from .common import MAC_FIGURE


@dataclass(frozen=True, kw_only=True)
class VehicleModel:
    """One vehicle model and how each command treats it.

    name : the calibration file's ``model`` and ``--model``'s value.
    campaign_kind : the campaign kind (campaign.toml ``kind``) it is calibrated from.
    identify(campaign, args, png, second) -> summary : identify a campaign, write the JSON and
        two figures.
    identification_figure : the suffix of the second figure, written beside the first.
    modes(args) -> dict : the eigen-analysis of ``railcal modes``.
    calibrate(args) -> summary : calibrate to a campaign or to typed targets, write the file.
    calibration_figures : the suffixes of the figures ``calibrate`` may write beside its
        convergence figure (:func:`railcal.common.write_calibration`).
    validate(campaign, calibration, args, figures) -> summary : compare the calibrated model with
        the campaign, write the JSON and its figures at ``figures`` (the first, then one per
        :attr:`validation_figures` suffix: the command names them all before any is written).
    diagnose(campaign, progress, calibration=None, calibration_path=None) -> diagnosis : what
        the model gets wrong, from the user's calibration when given (a result object with
        ``cause``, ``summary``, ``to_json()`` and ``plot(stem)``).
    validation_figures : the suffixes of the figures ``validate`` writes beside its first.
    diagnosis_figures : the suffixes of the figures ``plot`` writes beside the JSON.
    fmu_spec(calibration, track=, campaign=, cutoff_hz=) -> ModelSpec : the FMU's description.
    crosscheck(calibration, distance, level, args, png) -> (report, summary) : the exudyn
        cross-check over a track [m].
    crosscheck_figure : whether the cross-check draws a figure (beside its JSON, .png).
    example_calibration() -> dict : a calibration of the model at nominal parameters, for
        building and testing its FMU without a campaign.
    infer_track(campaign, calibration, args, files) -> summary : the track's level from the
        vehicle's response (None: the model's campaigns do not run over a track).
    """

    name: str
    description: str
    campaign_kind: str
    identify: Callable
    identification_figure: str
    modes: Callable
    calibrate: Callable
    calibration_figures: tuple[str, ...]
    validate: Callable
    validation_figures: tuple[str, ...]
    diagnose: Callable
    diagnosis_figures: tuple[str, ...]
    fmu_spec: Callable
    crosscheck: Callable
    crosscheck_figure: bool
    example_calibration: Callable[[], dict]
    infer_track: Callable | None = None


def _diagnose_in_service(campaign, progress, calibration=None, calibration_path=None):
    from calibration.diagnosis.in_service import diagnose_in_service

    return diagnose_in_service(campaign, progress=progress, calibration=calibration,
                               calibration_path=calibration_path)


def _diagnose_excitation(campaign, progress, calibration=None, calibration_path=None):
    """With a calibration, the baseline is its box model (factor set, end strips, orders),
    started at its factors and fitted again to the campaign's training part."""
    from calibration.diagnosis.excitation import diagnose_excitation
    from calibration.models.box.shinkansen import calibrated_box_model, factor_set

    if calibration is None:
        return diagnose_excitation(campaign, progress=progress)
    if calibration.get("extension"):  # its file could not carry a second one beside it
        raise InputError("the calibration is already an extended model (a diagnosis's); the box model carries one "
                         "extension: diagnose from the calibration it extends", path=calibration_path, key="extension")
    model, start = calibrated_box_model(calibration)
    factors = factor_set(calibration.get("factor_set"), side_end_zone=calibration.get("side_end_zone_m"))
    fit = calibration.get("max_error_pct")
    if fit is not None and (isinstance(fit, bool) or not isinstance(fit, (int, float)) or not 0 <= fit < math.inf):
        raise InputError(f"'max_error_pct' must be a percentage (0 or more), got {fit!r}", path=calibration_path,
                         key="max_error_pct")
    return diagnose_excitation(campaign, progress=progress, model=model, factors=factors, start=start,
                               start_fit_pct=None if fit is None else float(fit), model_keys=calibration)


def _car_example() -> dict:
    from calibration.models.vehicles import INTERCITY_TRAILER

    return {"model": "car2d", "parameters": INTERCITY_TRAILER.as_dict()}


def _box_example() -> dict:
    from calibration.models.box.rig import EXCITER, SENSOR_GRID, point_record

    return {"model": "box", "parameters": {}, "sensors": [point_record(s) for s in SENSOR_GRID],
            "exciter": point_record(EXCITER)}


MODELS: dict[str, VehicleModel] = {m.name: m for m in (
    VehicleModel(name="car2d", description="the 2D car: carbody, two bogies, four wheelsets (in-service seed)",
                 campaign_kind="in_service", identify=car2d.identify, identification_figure="_spectra",
                 modes=car2d.modes, calibrate=car2d.calibrate, calibration_figures=(MAC_FIGURE,),
                 validate=car2d.validate, validation_figures=("_runs",), diagnose=_diagnose_in_service,
                 diagnosis_figures=("_residual_psd", "_speed_map"), fmu_spec=car2d_fmu_spec,
                 crosscheck=car2d.crosscheck, crosscheck_figure=True, example_calibration=_car_example,
                 infer_track=car2d.infer_track),
    VehicleModel(name="box", description="the box-type vehicle: flexible carbody on its suspension (carbody seed)",
                 campaign_kind="stationary_excitation", identify=box.identify, identification_figure="_mac",
                 modes=box.modes,
                 calibrate=box.calibrate, calibration_figures=(), validate=box.validate, validation_figures=("_phase",),
                 diagnose=_diagnose_excitation,
                 diagnosis_figures=("_frf", "_mac"), fmu_spec=box_fmu_spec, crosscheck=box.crosscheck,
                 crosscheck_figure=False, example_calibration=_box_example),
)}


def model_named(name, *, key: str = "--model", path=None) -> VehicleModel:
    """The entry of ``name``, or exit 2 naming where the name came from."""
    if name not in MODELS:
        raise InputError(f"unknown model {name!r}; have: {', '.join(MODELS)}", path=path, key=key)
    return MODELS[name]


def model_of_calibration(calibration: dict, path) -> VehicleModel:
    """The model a calibration file names (files without ``model``: car2d, the first kind)."""
    return model_named(calibration.get("model", "car2d"), key="model", path=Path(path))


def model_for_campaign(campaign) -> VehicleModel:
    """The model a campaign of its kind calibrates."""
    for m in MODELS.values():
        if m.campaign_kind == campaign.meta.kind:
            return m
    raise InputError(f"no model is calibrated from a {campaign.meta.kind!r} campaign",
                     path=campaign.root / "campaign.toml", key="kind")
