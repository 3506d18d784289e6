"""``railcal export-fmu``: a calibration file (``railcal calibrate --out``) to an FMU.

Each model has its description builder: :func:`car2d_fmu_spec` gives the car FMU of
``shared/spec/interfaces.md`` (calibrated parameters as tunable parameters),
:func:`box_fmu_spec` the box-type vehicle FMU; the application's model registry picks one
by the calibration's ``model``. A track recording (campaign format, checked on reading)
is shipped in ``resources/`` for stand-alone running. A campaign adds an output per calibrated acceleration sensor (car) or
gives the box FMU's measurement points (box; otherwise the calibration file's).
"""
from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from calibration.data.campaign import read_track_file
from calibration.data.errors import InputError
from calibration.models.car2d import (CarExtras, carbody_centre, extras_from_json, floor_sensors_from_json,
                                     sensor_model_from_json)
from calibration.models.parameters import CarParameters

from .build import BuiltFMU, build_fmu
from .variables import CAR_BODIES, ModelSpec, TrackTooShort, car2d_spec


def car_sensors(campaign, p: CarParameters, extras: CarExtras | None = None, bogie_dx: float = 0.0,
                floor: dict | None = None) -> tuple:
    """(name, body, dx) of the campaign's vertical accelerometers on the car's bodies, dx
    from the body centre (the carbody's centre of mass, bogie 1 at +L_v, bogie 2 at -L_v);
    the bogies' sensors ``bogie_dx`` [m] ahead of their declared places and each floor
    sensor of ``floor`` ({name: (dx [m], gain)}) its own dx (a calibration's ``sensor_model``;
    a gain is the measurement's, not the vehicle's, and the FMU's outputs do not carry it)."""
    centre = {"carbody": carbody_centre(p, extras), "bogie1": p.L_v, "bogie2": -p.L_v}
    floor = floor or {}

    def moved(s) -> float:
        return bogie_dx if s.body != "carbody" else floor.get(s.name, (0.0, 1.0))[0]
    return tuple((s.name, s.body, float(s.position[0]) - centre[s.body] + moved(s))
                 for s in campaign.meta.sensors
                 if s.quantity == "acceleration" and s.direction == "z" and s.body in CAR_BODIES)


def box_points(campaign) -> tuple:
    """(sensors, exciter) of a stationary excitation campaign for the box FMU: its vertical
    accelerometers and the excitation's force sensor at the excitation point."""
    meta = campaign.meta
    if meta.excitation is None:
        raise InputError("the campaign has no [excitation]: the box FMU's force input needs the exciter's point",
                         path=campaign.root / "campaign.toml", key="excitation")
    sensors = tuple(s for s in meta.sensors if s.quantity == "acceleration" and s.direction == "z")
    exciter = meta.exciter()
    return sensors, exciter


def _track_csv(track: Path, folder: Path) -> Path:
    """The recording checked (CampaignError, exit 2, names file, line and column) and
    written plainly (distance, level in SI) for the FMU's reader."""
    rec = read_track_file(Path(track))
    out = folder / "track.csv"
    np.savetxt(out, np.column_stack([rec.distance, rec.level]), delimiter=",", header="distance,level",
               comments="", fmt="%.17g")
    return out


def car2d_fmu_spec(calibration: dict, *, track: Path | None = None, campaign=None,
                   cutoff_hz: float | None = None) -> ModelSpec:
    """The car FMU of a car2d calibration: its parameters (and an extended model's ``extras``)
    as tunable parameters, an output per vertical accelerometer of ``campaign`` on the car's
    bodies (when given; at the places the calibration's ``sensor_model`` puts them)."""
    if cutoff_hz is not None:
        raise InputError("--cutoff-hz is for the box model", key="--cutoff-hz")
    p = CarParameters.from_mapping(calibration["parameters"])  # names, finiteness and physical ranges checked here
    try:
        extras = extras_from_json(calibration.get("extras") or {})
        bogie_dx, _ = sensor_model_from_json(calibration.get("sensor_model"))
        floor = floor_sensors_from_json(calibration.get("sensor_model"))
        carbody_centre(p, extras)  # hung bodies leaving the carbody a mass and inertia
    except ValueError as e:
        raise InputError(str(e), key="extras / sensor_model") from None
    sensors = car_sensors(campaign, p, extras, bogie_dx, floor) if campaign is not None else ()
    return car2d_spec(p.as_dict(), track=track, sensors=sensors, extras=extras)


def box_fmu_spec(calibration: dict, *, track: Path | None = None, campaign=None,
                 cutoff_hz: float | None = None) -> ModelSpec:
    """The box-type vehicle FMU of a box calibration, its outputs at the campaign's
    accelerometers when given, else at the points the calibration was fitted at."""
    from .box import DEFAULT_CUTOFF_HZ, box_spec

    return box_spec(calibration, cutoff_hz=cutoff_hz or DEFAULT_CUTOFF_HZ, track=track,
                    points=box_points(campaign) if campaign is not None else None)


def export_fmu(calibration: dict, fmi_version: int, out: Path, *, spec_for, track: Path | None = None,
               campaign=None, platforms: tuple[str, ...] | None = None, cutoff_hz: float | None = None) -> BuiltFMU:
    """Build the FMU of ``calibration`` into ``out``. ``spec_for(calibration, track=, campaign=,
    cutoff_hz=)`` gives the model's description (the model registry's FMU builder:
    :func:`car2d_fmu_spec`, :func:`box_fmu_spec`); ``track``: a recording shipped for
    stand-alone running."""
    if fmi_version not in (2, 3):
        raise InputError(f"--fmi-version must be 2 or 3, got {fmi_version!r}", key="--fmi-version")
    if not isinstance(calibration.get("parameters") if isinstance(calibration, dict) else None, dict):
        raise InputError("the calibration has no parameters table", key="parameters")
    with tempfile.TemporaryDirectory(prefix="railcal_track_") as tmp:
        track_csv = _track_csv(track, Path(tmp)) if track is not None else None
        try:
            spec = spec_for(calibration, track=track_csv, campaign=campaign, cutoff_hz=cutoff_hz)
        except TrackTooShort as e:
            raise InputError(str(e), path=track) from None
        return build_fmu(spec, fmi_version, out, platforms=platforms)
