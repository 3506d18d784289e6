"""What a campaign declares (campaign.toml): its types, and reading and checking the file.

The types (:class:`Sensor`, :class:`Prior`, :class:`Excitation`, :class:`CampaignMeta`)
check themselves when made and raise a ValueError naming the field. :func:`parse_meta`
checks a parsed campaign.toml first, so bad input gets a :class:`CampaignError` naming
the file and key instead. Unknown keys are ignored with a warning, as the spec says.
"""
from __future__ import annotations

import collections
import math
import re
import tomllib
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Mapping

from .errors import CampaignError, excerpt, quoted
from .files import BOM, check_file, read_bytes
from .limits import GEOMETRY_RANGES, MAX_POSITION, MAX_TOML_BYTES, MAX_TOML_DEPTH, RATE_RANGE
from .units import BODIES, QUANTITIES, ROTATIONS, TRANSLATIONS, UNIT_ALIASES, UNITS, canonical_unit, si_factor

FORMAT = "railcal-campaign/1"
KINDS = ("in_service", "stationary_excitation")
NAME_RE = re.compile(r"^[A-Za-z0-9_]+$")
#: Run-file columns that are not sensors; ``<sensor>_clipped`` is reserved as well.
AXES = ("time", "distance", "speed")
_TOP_KEYS = {"format", "kind", "name", "vehicle", "priors", "sensors", "sampling", "excitation"}
_SENSOR_KEYS = {"name", "quantity", "unit", "body", "direction", "position", "scale"}
_PRIOR_KEYS = ("nominal", "low", "high")


# -------------------------------------------------------------------------------- types
def _bad(obj, name: str, message: str) -> ValueError:
    return ValueError(f"{type(obj).__name__}.{name}: {message}")


def _finite(x) -> bool:
    try:
        return not isinstance(x, bool) and math.isfinite(x)
    except TypeError:
        return False


def _check_point(obj, name: str, xyz) -> None:
    try:
        ok = len(xyz) == 3 and all(_finite(v) for v in xyz)
    except TypeError:
        ok = False
    if not ok:
        raise _bad(obj, name, f"expected [x, y, z], three finite numbers in metres, got {xyz!r}")


@dataclass(frozen=True)
class Sensor:
    """One measured channel: ``name`` is its run-file column, ``unit`` the column's unit,
    ``position`` [m] a point in the vehicle frame, ``scale`` a factor applied before the
    unit conversion."""

    name: str
    quantity: str
    unit: str
    body: str
    direction: str
    position: tuple[float, float, float]  # [m] vehicle frame
    scale: float = 1.0

    def __post_init__(self):
        if not isinstance(self.name, str) or not NAME_RE.match(self.name):
            raise _bad(self, "name", f"{self.name!r} must match [A-Za-z0-9_]+")
        if self.name in AXES or self.name.endswith("_clipped"):
            raise _bad(self, "name", f"{self.name!r} is reserved for a run-file column")
        if self.quantity not in QUANTITIES:
            raise _bad(self, "quantity", f"unknown quantity {self.quantity!r}; expected one of {', '.join(QUANTITIES)}")
        unit = canonical_unit(self.unit) if isinstance(self.unit, str) else self.unit
        if unit not in UNITS:
            raise _bad(self, "unit", f"unknown unit {self.unit!r}; expected one of {', '.join(UNITS)}")
        if UNITS[unit][0] != self.quantity:
            raise _bad(self, "unit", f"{self.unit!r} is not a unit of {self.quantity}")
        if self.body not in BODIES:
            raise _bad(self, "body", f"unknown body {self.body!r}; expected one of {', '.join(BODIES)}")
        allowed = ROTATIONS if self.quantity == "angular_velocity" else TRANSLATIONS
        if self.direction not in allowed:
            raise _bad(self, "direction", f"{self.direction!r} is not a direction of {self.quantity}; expected one of "
                                          f"{', '.join(allowed)}")
        _check_point(self, "position", self.position)
        if not _finite(self.scale) or not _finite(self.si_factor) or self.si_factor == 0:
            raise _bad(self, "scale", f"{self.scale!r} times the {self.unit} to SI factor is not finite and non-zero")

    @property
    def si_factor(self) -> float:
        """Multiply the raw column by this to get SI units (scale and unit together)."""
        return self.scale * si_factor(self.unit)

    def to_toml(self) -> dict:
        return {"name": self.name, "quantity": self.quantity, "unit": self.unit, "body": self.body,
                "direction": self.direction, "position": list(self.position), "scale": self.scale}


@dataclass(frozen=True)
class Prior:
    """Prior knowledge of a model parameter, in its SI unit: ``low < high`` and ``nominal``
    between them."""

    nominal: float
    low: float
    high: float

    def __post_init__(self):
        for name in _PRIOR_KEYS:
            if not _finite(getattr(self, name)):
                raise _bad(self, name, f"expected a finite number, got {getattr(self, name)!r}")
        if not self.low < self.high:
            raise _bad(self, "low", f"{self.low} must be below high = {self.high} (infeasible bounds)")
        if not self.low <= self.nominal <= self.high:
            raise _bad(self, "nominal", f"{self.nominal} outside [low, high] = [{self.low}, {self.high}]")


@dataclass(frozen=True)
class Excitation:
    """The force channel of a stationary excitation test and where it acts [m]."""

    sensor: str
    position: tuple[float, float, float]

    def __post_init__(self):
        if not isinstance(self.sensor, str) or not NAME_RE.match(self.sensor):
            raise _bad(self, "sensor", f"{self.sensor!r} must match [A-Za-z0-9_]+")
        _check_point(self, "position", self.position)


@dataclass(frozen=True)
class CampaignMeta:
    """Everything campaign.toml says. ``sampling_rate`` [Hz]; ``geometry`` [m] by the keys
    of :data:`~calibration.data.limits.GEOMETRY_RANGES`; ``priors`` by parameter name."""

    kind: str
    name: str
    vehicle: str
    sensors: tuple[Sensor, ...]
    sampling_rate: float
    geometry: Mapping[str, float] = field(default_factory=dict)
    priors: Mapping[str, Prior] = field(default_factory=dict)
    excitation: Excitation | None = None

    def __post_init__(self):
        if self.kind not in KINDS:
            raise _bad(self, "kind", f"expected one of {', '.join(KINDS)}, got {self.kind!r}")
        if not self.sensors or not all(isinstance(s, Sensor) for s in self.sensors):
            raise _bad(self, "sensors", "expected at least one Sensor, and only Sensors")
        names = [s.name for s in self.sensors]
        twice = sorted(n for n, k in collections.Counter(names).items() if k > 1)
        if twice:
            raise _bad(self, "sensors", f"sensor name(s) {', '.join(twice)} declared twice")
        if not _finite(self.sampling_rate) or self.sampling_rate <= 0:
            raise _bad(self, "sampling_rate", f"expected a positive number [Hz], got {self.sampling_rate!r}")
        for k, v in self.geometry.items():
            if k not in GEOMETRY_RANGES:
                raise _bad(self, "geometry", f"unknown key {k!r}; expected some of {', '.join(GEOMETRY_RANGES)}")
            if not _finite(v) or v <= 0:
                raise _bad(self, "geometry", f"{k} must be a positive length [m], got {v!r}")
        for k, p in self.priors.items():
            if not isinstance(p, Prior):
                raise _bad(self, "priors", f"{k!r} is not a Prior: {p!r}")
        if self.excitation is None:
            if self.kind == "stationary_excitation":
                raise _bad(self, "excitation", "a stationary_excitation campaign needs an Excitation")
        elif self.excitation.sensor not in names:
            raise _bad(self, "excitation", f"names sensor {self.excitation.sensor!r}, which is not in sensors")

    def sensor(self, name: str) -> Sensor:
        for s in self.sensors:
            if s.name == name:
                return s
        raise KeyError(f"no sensor {name!r}; have {', '.join(s.name for s in self.sensors)}")

    def exciter(self) -> Sensor:
        """The excitation's force sensor placed at the point the force acts (a stationary
        excitation test's ``[excitation]``)."""
        if self.excitation is None:
            raise KeyError("the campaign has no [excitation]")
        return replace(self.sensor(self.excitation.sensor), position=tuple(self.excitation.position))

    def to_toml(self) -> dict:
        d: dict = {"format": FORMAT, "kind": self.kind, "name": self.name}
        vehicle: dict = {"name": self.vehicle, **{k: float(v) for k, v in self.geometry.items()}}
        d["vehicle"] = vehicle
        if self.priors:
            d["priors"] = {k: {"nominal": p.nominal, "low": p.low, "high": p.high} for k, p in self.priors.items()}
        d["sensors"] = [s.to_toml() for s in self.sensors]
        d["sampling"] = {"rate": self.sampling_rate}
        if self.excitation is not None:
            d["excitation"] = {"sensor": self.excitation.sensor, "position": list(self.excitation.position)}
        return d


# ------------------------------------------------------------------------ campaign.toml
def _number(value, path, key) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CampaignError(f"expected a finite number, got {quoted(value)}", path=path, key=key)
    try:
        x = float(value)  # a TOML integer of hundreds of digits has no float
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise CampaignError(f"expected a finite number, got {quoted(value)}", path=path, key=key)
    return x


def _position(value, path, key) -> tuple[float, float, float]:
    if not isinstance(value, list) or len(value) != 3:
        raise CampaignError(f"expected [x, y, z] in metres, got {quoted(value)}", path=path, key=key)
    xyz = tuple(_number(v, path, key) for v in value)
    if max(abs(v) for v in xyz) > MAX_POSITION:
        raise CampaignError(f"a coordinate beyond {MAX_POSITION:g} m of the carbody centre: {quoted(value)}",
                            path=path, key=key)
    return xyz  # type: ignore[return-value]


def _check_geometry(geometry: Mapping[str, float], path) -> None:
    """The [vehicle] lengths fit together: the axles of a bogie lie between the bogie
    centres, and the bogie centres under the carbody (at its ends on articulated units)."""
    L_v, L_b, length = (geometry.get(k) for k in ("bogie_semi_spacing", "semi_wheelbase", "length"))
    if L_v is not None and L_b is not None and not L_b < L_v:
        raise CampaignError(f"semi_wheelbase {L_b:g} m must be below bogie_semi_spacing {L_v:g} m", path=path,
                            key="vehicle.semi_wheelbase")
    windows = geometry.get("windowed_length")
    if windows is not None and length is not None and not windows < length:
        raise CampaignError(f"windowed_length {windows:g} m must be below the carbody's length {length:g} m",
                            path=path, key="vehicle.windowed_length")
    if L_v is not None and length is not None and not L_v <= length / 2:
        raise CampaignError(f"bogie_semi_spacing {L_v:g} m puts the bogies beyond the ends of a {length:g} m "
                            f"carbody", path=path, key="vehicle.bogie_semi_spacing")


# The parts of parse_meta below warn with a stacklevel that names parse_meta's caller, as it does.
def _vehicle(data: dict, path: Path) -> tuple[str, dict[str, float]]:
    vehicle = data.get("vehicle", {})
    if not isinstance(vehicle, (dict, str)):
        raise CampaignError(f"expected a [vehicle] table or a name, got {quoted(vehicle)}", path=path, key="vehicle")
    vehicle_name = data.get("vehicle") if isinstance(data.get("vehicle"), str) else ""
    geometry: dict[str, float] = {}
    if isinstance(vehicle, dict):
        vehicle_name = str(vehicle.get("name", vehicle_name))
        for k, v in vehicle.items():
            if k in GEOMETRY_RANGES:
                geometry[k] = _number(v, path, f"vehicle.{k}")
                lo, hi = GEOMETRY_RANGES[k]
                if not lo <= geometry[k] <= hi:
                    raise CampaignError(f"{geometry[k]:g} m is not a plausible {k} (expected {lo:g} to {hi:g} m)",
                                        path=path, key=f"vehicle.{k}")
            elif k != "name":
                warnings.warn(f"{path}: unknown key 'vehicle.{excerpt(k)}' ignored", stacklevel=3)
        _check_geometry(geometry, path)
    return vehicle_name, geometry


def _priors(data: dict, path: Path) -> dict[str, Prior]:
    priors: dict[str, Prior] = {}
    raw_priors = data.get("priors") or {}
    if not isinstance(raw_priors, dict):
        raise CampaignError("expected tables [priors.NAME] with nominal, low, high", path=path, key="priors")
    for pname, pr in raw_priors.items():
        key = f"priors.{pname}"
        if not isinstance(pr, dict):
            raise CampaignError("expected a table with nominal, low, high", path=path, key=key)
        missing = [k for k in _PRIOR_KEYS if k not in pr]
        if missing:
            raise CampaignError(f"missing {', '.join(missing)}", path=path, key=key)
        nominal, low, high = (_number(pr[k], path, f"{key}.{k}") for k in _PRIOR_KEYS)
        if not (low < high):
            raise CampaignError(f"low = {low} must be below high = {high} (infeasible bounds)", path=path, key=key)
        if not (low <= nominal <= high):
            raise CampaignError(f"nominal = {nominal} outside [low, high] = [{low}, {high}]", path=path, key=key)
        priors[pname] = Prior(nominal, low, high)
    return priors


def _sensor(s, key: str, seen: Mapping[str, int], path: Path) -> Sensor:
    if not isinstance(s, dict):
        raise CampaignError("expected a table", path=path, key=key)
    for k in sorted(set(s) - _SENSOR_KEYS):
        warnings.warn(f"{path}: unknown key '{key}.{excerpt(k)}' ignored", stacklevel=4)
    for k in ("name", "quantity", "unit", "body", "direction", "position"):
        if k not in s:
            raise CampaignError(f"missing '{k}'", path=path, key=key)
        if k != "position" and not isinstance(s[k], str):
            raise CampaignError(f"expected a string, got {quoted(s[k])}", path=path, key=f"{key}.{k}")
    name = s["name"]
    if not isinstance(name, str) or not NAME_RE.match(name):
        raise CampaignError(f"sensor name {quoted(name)} must match [A-Za-z0-9_]+", path=path, key=f"{key}.name")
    if name in AXES or name.endswith("_clipped"):
        raise CampaignError(f"sensor name {quoted(name)} is reserved", path=path, key=f"{key}.name")
    if name in seen:
        raise CampaignError(f"sensor name {quoted(name)} declared twice (also sensors[{seen[name]}])", path=path,
                            key=f"{key}.name")
    q, unit = s["quantity"], canonical_unit(s["unit"])
    if q not in QUANTITIES:
        raise CampaignError(f"unknown quantity {quoted(q)}; expected one of {', '.join(QUANTITIES)}", path=path,
                            key=f"{key}.quantity")
    if unit not in UNITS:
        raise CampaignError(f"unknown unit {quoted(unit)}; expected one of {', '.join(UNITS)} (or "
                            f"{', '.join(UNIT_ALIASES)} for m/s^2)", path=path,
                            key=f"{key}.unit")
    if UNITS[unit][0] != q:
        raise CampaignError(f"unit {quoted(unit)} is not a unit of {q}", path=path, key=f"{key}.unit")
    if s["body"] not in BODIES:
        raise CampaignError(f"unknown body {quoted(s['body'])}; expected one of {', '.join(BODIES)}", path=path,
                            key=f"{key}.body")
    direction = s["direction"]
    allowed = ROTATIONS if q == "angular_velocity" else TRANSLATIONS
    if direction not in allowed:
        raise CampaignError(f"direction {quoted(direction)} not valid for {q}; expected one of {', '.join(allowed)}",
                            path=path, key=f"{key}.direction")
    scale = _number(s.get("scale", 1.0), path, f"{key}.scale")
    if scale == 0:
        raise CampaignError("scale must not be zero", path=path, key=f"{key}.scale")
    factor = scale * si_factor(unit)
    if not math.isfinite(factor) or factor == 0:
        raise CampaignError(f"scale {scale:g} times the {unit} to SI factor {si_factor(unit):g} is not finite "
                            f"and non-zero", path=path, key=f"{key}.scale")
    return Sensor(name, q, unit, s["body"], direction, _position(s["position"], path, f"{key}.position"), scale)


def _sensors(data: dict, path: Path) -> tuple[Sensor, ...]:
    raw_sensors = data.get("sensors")
    if not isinstance(raw_sensors, list) or not raw_sensors:
        raise CampaignError("expected at least one [[sensors]] table", path=path, key="sensors")
    sensors = []
    seen: dict[str, int] = {}
    for i, s in enumerate(raw_sensors):
        sensors.append(_sensor(s, f"sensors[{i}]", seen, path))
        seen[sensors[-1].name] = i
    return tuple(sensors)


def _sampling_rate(data: dict, path: Path) -> float:
    sampling = data.get("sampling")
    if not isinstance(sampling, dict) or "rate" not in sampling:
        raise CampaignError("expected [sampling] with rate [Hz]", path=path, key="sampling.rate")
    rate = _number(sampling["rate"], path, "sampling.rate")
    if not RATE_RANGE[0] <= rate <= RATE_RANGE[1]:
        raise CampaignError(f"{rate:g} Hz is not a plausible sampling rate (expected {RATE_RANGE[0]:g} to "
                            f"{RATE_RANGE[1]:g} Hz)", path=path, key="sampling.rate")
    return rate


def _excitation(data: dict, path: Path, sensors: tuple[Sensor, ...]) -> Excitation:
    ex = data.get("excitation")
    if not isinstance(ex, dict) or not isinstance(ex.get("sensor"), str):
        raise CampaignError("a stationary_excitation campaign needs [excitation] sensor = ...", path=path,
                            key="excitation")
    if ex["sensor"] not in {s.name for s in sensors}:
        raise CampaignError(f"names sensor {quoted(ex['sensor'])}, which is not declared in [[sensors]]", path=path,
                            key="excitation.sensor")
    return Excitation(ex["sensor"], _position(ex.get("position", [0, 0, 0]), path, "excitation.position"))


def parse_meta(data: dict, path: Path) -> CampaignMeta:
    """Check and convert the parsed campaign.toml; ``path`` is named in every message."""
    for k in sorted(set(data) - _TOP_KEYS):
        warnings.warn(f"{path}: unknown key '{excerpt(k)}' ignored", stacklevel=2)
    fmt = data.get("format")
    if fmt != FORMAT:
        raise CampaignError(f"expected format = \"{FORMAT}\", got {quoted(fmt)}", path=path, key="format")
    kind = data.get("kind")
    if kind not in KINDS:
        raise CampaignError(f"expected one of {', '.join(KINDS)}, got {quoted(kind)}", path=path, key="kind")
    vehicle_name, geometry = _vehicle(data, path)
    priors = _priors(data, path)
    sensors = _sensors(data, path)
    rate = _sampling_rate(data, path)
    excitation = _excitation(data, path, sensors) if kind == "stationary_excitation" else None
    return CampaignMeta(kind, str(data.get("name", "")), vehicle_name, sensors, rate, geometry, priors, excitation)


def _toml_line(text: str, pos: int) -> int:
    return text.count("\n", 0, pos) + 1


def _too_deep(text: str) -> int | None:
    """Line where brackets and braces first nest deeper than MAX_TOML_DEPTH, counted
    over the text as a whole (strings included: it only places an error message)."""
    depth = 0
    for m in re.finditer(r"[\[\]{}]", text):
        depth += 1 if m.group() in "[{" else -1
        if depth > MAX_TOML_DEPTH:
            return _toml_line(text, m.start())
    return None


_DIGITS = re.compile(r"\d{1000,}")


def load_toml(path: Path, *, root: Path | None) -> dict:
    """campaign.toml parsed, after :func:`~calibration.data.files.check_file` (inside
    ``root`` when given); a CampaignError names the line of a syntax error."""
    check_file(path, MAX_TOML_BYTES, root=root)
    data = read_bytes(path, MAX_TOML_BYTES)
    if data.startswith(BOM):
        data = data[len(BOM):]
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise CampaignError("not UTF-8 text", path=path, line=data[:e.start].count(b"\n") + 1) from None
    text = text.replace("\r\n", "\n").replace("\r", "\n")  # CR alone ends lines as in the run files
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"line (\d+)", str(e))  # tomllib says "at end of document" for a cut file
        line = int(m.group(1)) if m else text.count("\n") + 1
        raise CampaignError(f"not valid TOML: {excerpt(e, 120)}", path=path, line=line) from None
    except RecursionError:
        raise CampaignError(f"arrays or tables nested deeper than {MAX_TOML_DEPTH} levels", path=path,
                            line=_too_deep(text) or 1) from None
    except ValueError:  # an integer of thousands of digits (Python's int conversion limit)
        m = _DIGITS.search(text)
        raise CampaignError("a number of thousands of digits", path=path,
                            line=_toml_line(text, m.start()) if m else None) from None
