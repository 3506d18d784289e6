"""Hidden effects of the independent truth, parsed here (not from calibration/truth/effects.py).

The catalogue's names and magnitude ranges are the diagnosis's vocabulary and are kept;
what each one does to this truth is its own:

* ``carbody_bending`` [Hz]: the carbody beam's first free-free bending at MAGNITUDE (6-12);
* ``cog_offset`` [m]: the carbody structure's mass centre MAGNITUDE ahead or behind (0.4-1.5);
* ``airspring_reservoir`` [-]: reservoir volume MAGNITUDE x the bag's behind a restricted
  orifice whose transition falls at 1.5-4 Hz (drawn) (0.5-2);
* ``sensor_offset`` [m]: the bogie accelerometer and gyro MAGNITUDE off their declared x (0.3-1.5);
* ``track_flexibility`` [N/m]: soft ballast: track stiffness per wheelset MAGNITUDE (20e6-80e6);
* ``wheel_out_of_round`` [m]: a polygonal wheelset (1 or 2): dominant order 1-3 of radius
  amplitude MAGNITUDE plus three higher harmonics of 10-40 % of it (0.05e-3-0.3e-3);
* ``floor_sensor_offset`` [m]: the worst-placed carbody floor accelerometer (drawn) MAGNITUDE
  off its declared x, the other two anywhere within it (0.3-1.5).

Near-mimics outside the catalogue (the diagnosis has no extension for them):

* ``rigid_equipment`` [kg]: a mass of MAGNITUDE bolted rigidly to the floor at a drawn x;
* ``load_variation`` [-]: the journeys' payload differs by up to +-MAGNITUDE x the carbody mass;
* ``suspension_friction`` [N]: dry friction of MAGNITUDE across each bogie's air springs (a
  binding guide or a friction-damped bolster), which damps a quiet ride more than a rough
  one; the diagnosis fits it as a property (``amplitude_dependent_suspension``), not a cause;

and any two of the above joined by ``+`` (``cog_offset=0.8+carbody_bending=8``).

The stationary excitation test (:mod:`.stationary`) has its own (:data:`STATIONARY_RANGES`):

* ``underfloor_equipment`` [-]: a body of MAGNITUDE x the carbody's mass hung under the floor
  on mounts tuned within 4 % of the elastic mode in 8-20 Hz that moves the mount point most
  (0.01-0.05);
* ``local_panel_softening`` [-]: the rigidities of one region (roof, front, middle or rear
  floor) divided by MAGNITUDE (3-10);
* ``force_calibration`` [-]: the load cell reads MAGNITUDE times the force applied, on top of
  its own gain error (within 0.5 %); nothing else of the campaign changes (0.9-1.1);

and, outside the catalogue, ``sensor_bracket`` [Hz] (one floor accelerometer on a bracket of
that natural frequency, 10-28) and ``rigid_equipment`` [kg] (a mass bolted to the floor).
"""
from __future__ import annotations

from dataclasses import dataclass

from ...data.errors import InputError


@dataclass(frozen=True)
class HiddenEffect:
    name: str
    magnitude: float
    unit: str
    catalogued: bool

    def to_json(self) -> dict:
        return {"name": self.name, "magnitude": self.magnitude, "unit": self.unit, "catalogued": self.catalogued}


RANGES = {  # name: (low, high, default, unit, catalogued)
    "carbody_bending": (6.0, 12.0, 8.0, "Hz", True),
    "cog_offset": (0.4, 1.5, 0.8, "m", True),
    "airspring_reservoir": (0.5, 2.0, 1.0, "-", True),
    "sensor_offset": (0.3, 1.5, 0.8, "m", True),
    "track_flexibility": (20.0e6, 80.0e6, 40.0e6, "N/m", True),
    "wheel_out_of_round": (0.05e-3, 0.3e-3, 0.15e-3, "m", True),
    "floor_sensor_offset": (0.3, 1.5, 0.8, "m", True),
    "rigid_equipment": (300.0, 1000.0, 700.0, "kg", False),
    "load_variation": (0.05, 0.2, 0.12, "-", False),
    "suspension_friction": (300.0, 1500.0, 800.0, "N", False),
}


STATIONARY_RANGES = {
    "underfloor_equipment": (0.01, 0.05, 0.03, "-", True),
    "local_panel_softening": (3.0, 10.0, 5.0, "-", True),
    "force_calibration": (0.9, 1.1, 1.05, "-", True),
    "sensor_bracket": (10.0, 28.0, 20.0, "Hz", False),
    "rigid_equipment": (300.0, 1000.0, 700.0, "kg", False),
}


def parse_hidden(text: str | None, ranges: dict = RANGES) -> tuple[HiddenEffect, ...]:
    """``NAME[=MAGNITUDE][+NAME[=MAGNITUDE]]`` with the names of ``ranges`` (the in-service
    test's by default); InputError naming what is wrong."""
    if text is None or text == "":
        return ()
    out = []
    for part in text.split("+"):
        name, _, mag = part.partition("=")
        name = name.strip()
        if name not in ranges:
            raise InputError(f"unknown effect {name!r} for the independent truth; available: {', '.join(ranges)}",
                             key="--effect")
        lo, hi, default, unit, cat = ranges[name]
        if mag:
            try:
                value = float(mag)
            except ValueError:
                raise InputError(f"magnitude {mag!r} of effect {name} is not a number", key="--effect") from None
            if not lo <= value <= hi:
                raise InputError(f"magnitude {value} {unit} of effect {name} outside its range [{lo}, {hi}]",
                                 key="--effect")
        else:
            value = default
        out.append(HiddenEffect(name, value, unit, cat))
    if len(out) > 2 or len({e.name for e in out}) < len(out):
        raise InputError(f"at most two different effects may be combined, got {text!r}", key="--effect")
    return tuple(out)
