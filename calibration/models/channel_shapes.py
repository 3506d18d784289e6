"""Mode shapes at a campaign's measured channels, for comparing the 2D car's modes with the
identified ones (MAC).

Only channels that respond to the vehicle's modes take part: vertical accelerometers and
pitch gyros on the bogies and the carbody. Axle-box accelerometers are left out: with the
wheelsets on the rail they measure the rail, the input, not a response of the car.

A shape's entries are all vertical displacements [m], so that no channel weighs in a MAC by
its unit: an accelerometer's entry is the displacement at its position, a gyro's the pitch
angle times a lever (a bogie's semi-wheelbase L_b, the carbody's bogie semi-spacing L_v), the
vertical motion the pitch gives where the body rests on its suspension. A measured spectrum at
f [Hz] is turned into these entries by :func:`displacement_factors`.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.metadata import Sensor
from .assembly import Assembly
from .car2d import Mode, Output, damped_modes, output_rows

RESPONSE_BODIES = ("bogie1", "bogie2", "carbody", "floor")


@dataclass(frozen=True)
class ResponseChannel:
    """A measured channel as a model output: ``output`` an acceleration at (body, x) or a
    pitch rate of a body; ``lever`` [m] the length a pitch is multiplied by (1 for a
    vertical accelerometer)."""

    output: Output
    lever: float = 1.0

    @property
    def name(self) -> str:
        return self.output.name


def response_channels(sensors: tuple[Sensor, ...], *, L_v: float, L_b: float) -> tuple[ResponseChannel, ...]:
    """The vertical accelerometers and pitch gyros of ``sensors`` on the bogies and the
    carbody (a ``floor`` sensor is on the carbody), in their declared order. Axle-box
    channels are not among them (the rail input, see the module)."""
    out = []
    for s in sensors:
        if s.body not in RESPONSE_BODIES:
            continue
        body = "carbody" if s.body == "floor" else s.body
        if s.quantity == "acceleration" and s.direction == "z":
            out.append(ResponseChannel(Output(s.name, "acceleration", body, float(s.position[0]))))
        elif s.quantity == "angular_velocity" and s.direction == "pitch":
            out.append(ResponseChannel(Output(s.name, "pitch_rate", body), L_v if body == "carbody" else L_b))
    return tuple(out)


def displacement_factors(channels: tuple[ResponseChannel, ...], frequency_hz: float) -> np.ndarray:
    """Per channel, the complex factor that turns its spectrum at ``frequency_hz`` into its
    shape entry [m]: 1 / (i w)^2 for an acceleration, L / (i w) for a pitch rate."""
    iw = 2j * np.pi * frequency_hz
    return np.array([c.lever / iw if c.output.kind == "pitch_rate" else 1 / iw ** 2 for c in channels])


def model_shapes(asm: Assembly, channels: tuple[ResponseChannel, ...]) -> list[tuple[Mode, np.ndarray]]:
    """The damped (complex) modes of ``asm`` and each one's shape at ``channels`` [m]. Damped
    modes, because a measured shape carries the damping's phases: the car's damping is not
    proportional, so its modes are complex."""
    rows, _ = output_rows(asm, [c.output for c in channels])
    levers = np.array([c.lever for c in channels])
    return [(m, levers * (rows @ m.shape)) for m in damped_modes(asm)]
