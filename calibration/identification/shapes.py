"""Identified mode shapes of an in-service campaign: the first singular vector of the summed
cross-spectral matrix of the response channels at each identified mode's frequency (FDD,
Brincker et al. 2001), from the same random segments as the rest of the identification.

Axle-box channels are not in it (the rail input, :mod:`calibration.models.channel_shapes`),
and before the decomposition each channel's spectrum is made a vertical displacement (a
gyro's pitch times its lever), so that no channel dominates the singular vector by its unit.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.errors import InputError
from ..models.channel_shapes import ResponseChannel, displacement_factors
from .fdd import Analysis, FDDResult

SHAPE_ANALYSIS = "response_shapes"


@dataclass(frozen=True)
class ModeShape:
    """An identified shape: one complex entry per channel, each a vertical displacement
    relative to the largest (which is 1, real); ``levers`` [m] are the lengths a gyro's pitch
    was multiplied by (1 for an accelerometer); ``frequency_hz`` the bin it was read at."""

    channels: tuple[str, ...]
    values: tuple[complex, ...]
    levers: tuple[float, ...]
    frequency_hz: float

    def to_json(self) -> dict:
        v = np.asarray(self.values)
        return {"channels": list(self.channels), "real": [float(x) for x in v.real],
                "imag": [float(x) for x in v.imag], "levers_m": list(self.levers), "frequency_hz": self.frequency_hz}

    @classmethod
    def from_json(cls, data, where: str) -> "ModeShape | None":
        """A shape read back (None when absent); :class:`InputError` keyed ``where``."""
        if data is None:
            return None
        keys = ("channels", "real", "imag", "levers_m")
        if not isinstance(data, dict) or not all(isinstance(data.get(k), list) for k in keys) \
                or len({len(data[k]) for k in keys}) != 1 or not data["channels"]:
            raise InputError("a shape needs equally long, non-empty lists channels, real, imag and levers_m",
                             key=where)
        if not all(isinstance(c, str) for c in data["channels"]):
            raise InputError("a shape's channels must be names", key=f"{where}.channels")
        for k in keys[1:]:
            if not all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in data[k]):
                raise InputError("expected finite numbers", key=f"{where}.{k}")
        f = data.get("frequency_hz")
        if isinstance(f, bool) or not isinstance(f, (int, float)) or not f > 0:
            raise InputError(f"expected a positive frequency, got {f!r}", key=f"{where}.frequency_hz")
        values = tuple(complex(a, b) for a, b in zip(data["real"], data["imag"]))
        return cls(tuple(data["channels"]), values, tuple(float(x) for x in data["levers_m"]), float(f))


def shape_analysis(channels: tuple[ResponseChannel, ...], n_fdds: int) -> Analysis | None:
    """The FDD analysis of the response channels; None without any."""
    if not channels:
        return None
    return Analysis(SHAPE_ANALYSIS, tuple(c.name for c in channels), n_fdds, "response_shapes")


def mode_shape(result: FDDResult, channels: tuple[ResponseChannel, ...], frequency_hz: float) -> ModeShape:
    """The first singular vector of ``result``'s summed CSD at the bin nearest
    ``frequency_hz`` [Hz], in displacements, its largest entry made 1 (real)."""
    k = int(np.argmin(np.abs(result.frequency - frequency_hz)))
    f = float(result.frequency[k])
    d = displacement_factors(channels, f)
    G = d[:, None] * result.csd[k] * np.conj(d)[None, :]
    _, vectors = np.linalg.eigh(G)  # Hermitian and semi-definite: its eigenvectors are its singular vectors
    u = vectors[:, -1]
    u = u / u[int(np.argmax(np.abs(u)))]
    return ModeShape(tuple(c.name for c in channels), tuple(complex(x) for x in u),
                     tuple(float(c.lever) for c in channels), f)
