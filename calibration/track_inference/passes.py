"""A campaign's journeys as passes over the line: each contiguous stretch of a run, its
sensors resampled on a uniform distance grid of the car's centre.

The inverse works in distance, where the track is stationary and the car's speed is a
known, slowly varying coefficient. A run's position is its speed integrated, scaled and
shifted to fit its GPS distance (:func:`line_position`). The channels are low-passed in
time (zero phase) below the grid's Nyquist wavenumber at the speed where each sample was
taken, then read at the grid points' times. A stretch ends where the car is slower than
3 m/s, at a gap and at an invalid sample; a run of several stretches gives passes named
``run:1``, ``run:2``, ...

Sensors used: the leading bogie's vertical accelerometers and pitch gyro and, when asked
for, the leading bogie's axle boxes (the two boxes of an axle averaged, which cancels the
axle's roll over cross level).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np
import scipy.signal

from ..data.campaign import Campaign
from ..data.errors import CampaignError
from ..identification.fdd import distance_axis

#: [m/s] below this the car is stopping or standing: a stretch ends there
MIN_SPEED = 3.0
#: [s] how long a GPS position error takes to change: fixes this far apart count as independent
GPS_WANDER_S = 60.0


@dataclass(frozen=True)
class Channel:
    """One measured quantity on the grid: ``kind`` 'bogie_acc' (at ``x`` [m] in the vehicle
    frame), 'gyro' (the bogie's pitch rate) or 'axle' (wheelset ``wheelset``'s vertical
    acceleration); SI units."""

    name: str
    kind: str
    values: np.ndarray
    x: float = 0.0
    wheelset: int = 0


@dataclass(frozen=True)
class Pass:
    """A stretch of one run on the distance grid ``s`` [m] (the car's centre), with the
    grid points' times ``t`` [s], speed ``v`` [m/s] and longitudinal acceleration ``a``
    [m/s^2]."""

    run_id: str  # unique: the run's id, with ":k" for the k-th stretch of a run split into several
    s: np.ndarray
    t: np.ndarray
    v: np.ndarray
    a: np.ndarray
    channels: tuple[Channel, ...]


def _lowpass(x: np.ndarray, cutoff: float, fs: float) -> np.ndarray:
    if cutoff >= 0.45 * fs:
        return x
    sos = scipy.signal.butter(4, cutoff, fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x)


def _sensors(campaign: Campaign, axle_boxes: bool, bogie_dx: float):
    bogie, axles = [], {}
    for s in campaign.meta.sensors:
        if s.body == "bogie1" and s.quantity == "acceleration" and s.direction == "z":
            bogie.append((s.name, "bogie_acc", s.position[0] + bogie_dx, 0))
        elif s.body == "bogie1" and s.quantity == "angular_velocity" and s.direction == "pitch":
            bogie.append((s.name, "gyro", 0.0, 0))
        elif axle_boxes and s.body in ("axle1", "axle2") and s.quantity == "acceleration" and s.direction == "z":
            axles.setdefault(int(s.body[4:]), []).append(s.name)
    return bogie, axles


def read_passes(campaign: Campaign, *, step: float, axle_boxes: bool = False, bogie_dx: float = 0.0,
                min_length: float = 200.0, max_lowpass: float = 40.0, progress=None) -> list[Pass]:
    """The campaign's passes on a grid of ``step`` [m]; stretches shorter than
    ``min_length`` [m], or where a used channel has an invalid sample, are left out (a
    stretch is split at such samples)."""
    if campaign.meta.kind != "in_service":
        raise CampaignError(f"track inference needs an in-service campaign, not {campaign.meta.kind}",
                            path=campaign.root / "campaign.toml", key="kind")
    bogie, axles = _sensors(campaign, axle_boxes, bogie_dx)
    if not bogie:
        raise CampaignError("no leading-bogie vertical accelerometer or pitch gyro (body bogie1) to infer the "
                            "track from", path=campaign.root / "campaign.toml", key="sensors")
    if axle_boxes and not axles:
        raise CampaignError("axle boxes asked for, but the campaign has no vertical accelerometer on axle1 or "
                            "axle2", path=campaign.root / "campaign.toml", key="sensors")
    names = [b[0] for b in bogie] + [n for group in axles.values() for n in group]
    out = []
    for run in campaign.iter_runs():
        d = line_position(run, campaign.root / "runs")
        fs = 1.0 / float(np.median(np.diff(run.time)))
        stretches = []
        for a, b in run.blocks:
            t, dd = run.time[a:b], d[a:b]
            if t.size < 4:
                continue
            v = np.gradient(dd, t)
            ok = (v > MIN_SPEED) & np.all([run.valid[n][a:b] for n in names], axis=0)
            for i0, i1 in _runs_of(ok):
                if dd[i1 - 1] - dd[i0] < min_length:
                    continue
                p = _one_pass(run, names, bogie, axles, t[i0:i1], dd[i0:i1], v[i0:i1], a + i0, fs, step,
                              max_lowpass)
                if p is not None:
                    stretches.append(p)
        for k, p in enumerate(stretches):
            if len(stretches) > 1:
                p = replace(p, run_id=f"{run.run_id}:{k + 1}")
            out.append(p)
            if progress:
                progress(f"infer-track: {p.run_id} {p.s[0]:.0f}-{p.s[-1]:.0f} m at {np.mean(p.v):.1f} m/s mean")
    if not out:
        raise CampaignError(f"no run has a stretch of at least {min_length:g} m above {MIN_SPEED:g} m/s with "
                            f"valid {', '.join(names)}", path=campaign.root / "runs")
    return out


def line_position(run, where) -> np.ndarray:
    """[m] The run's position along the line at its samples: the speed integrated, shifted
    onto the GPS distance (the median difference), and scaled to it where the least-squares
    scale differs from 1 by more than three standard errors of the GPS's wander: a speed
    that reads 0.3 % high would drift 30 m over 10 km, while a scale fitted to the wander
    alone moved the ends of a 10 km pass by a metre on the bench. With one of the two
    columns only, that one, with a warning: speed alone gives no position on the line (it
    starts at 0 m), distance alone carries the GPS's wander into every wavelength."""
    if run.speed is None:
        warnings.warn(f"{where / run.path.name}: no speed column; the position along the line is the GPS distance "
                      "alone, and its wander blurs the profile", stacklevel=3)
        return distance_axis(run.distance, None, run.time)
    d_speed = distance_axis(None, run.speed, run.time)
    if run.distance is None:
        warnings.warn(f"{where / run.path.name}: no distance column; the position along the line is the speed "
                      "integrated from 0 m at the run's start", stacklevel=3)
        return d_speed
    ok = np.isfinite(run.distance)
    A = np.column_stack([np.ones(ok.sum()), d_speed[ok]])
    coef, *_ = np.linalg.lstsq(A, run.distance[ok], rcond=None)
    # the GPS error wanders over tens of seconds: count one independent fix a minute
    resid = run.distance[ok] - A @ coef
    n_eff = max(2.0, (run.time[-1] - run.time[0]) / GPS_WANDER_S)
    se = np.std(resid) / (np.std(d_speed[ok]) * np.sqrt(n_eff) + 1e-300)
    if abs(coef[1] - 1.0) > 3 * se and 0.9 < coef[1] < 1.1:  # a speed scale error the GPS shows beyond its wander
        return coef[0] + coef[1] * d_speed
    return np.median(run.distance[ok] - d_speed[ok]) + d_speed


def _runs_of(mask: np.ndarray) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return list(zip(edges[::2], edges[1::2]))


def _one_pass(run, names, bogie, axles, t, d, v, first, fs, step, max_lowpass) -> Pass | None:
    grid = np.arange(d[0], d[-1], step)
    if grid.size < 8:
        return None
    tg = np.interp(grid, d, t)
    vg = np.interp(tg, t, v)
    # slow speed changes only: the derivative of the GPS-anchored axis carries its jitter
    sos = scipy.signal.butter(2, 0.2, fs=fs, output="sos")
    v_smooth = scipy.signal.sosfiltfilt(sos, v) if v.size > 30 else v
    ag = np.interp(tg, t, np.gradient(v_smooth, t))
    sl = slice(first, first + t.size)
    # below the grid's Nyquist wavenumber at the local speed: each sample takes the highest of
    # a ladder of cutoffs (steps of sqrt 2) that is under 0.8 v / (2 step) where it was taken
    ladder = max_lowpass / np.sqrt(2.0) ** np.arange(12)
    need = 0.8 * v / (2 * step)
    rung = np.minimum(np.searchsorted(-ladder, -need, side="left"), ladder.size - 1)
    rung_g = np.interp(tg, t, rung).round().astype(int)

    def on_grid(name):
        x = run.channels[name][sl]
        out = np.empty(tg.size)
        for r in np.unique(rung_g):
            at = rung_g == r
            out[at] = np.interp(tg[at], t, _lowpass(x, ladder[r], fs))
        return out

    chans = [Channel(n, kind, on_grid(n), x=x) for n, kind, x, _ in bogie]
    for j, group in sorted(axles.items()):
        mean = np.mean([on_grid(n) for n in group], axis=0)
        chans.append(Channel(f"axle{j}", "axle", mean, wheelset=j))
    return Pass(run.run_id, grid, tg, vg, ag, tuple(chans))
