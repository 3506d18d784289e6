"""Validation over a measured track profile (in-service seed, section 7).

The calibrated car runs over the campaign's track recording at each journey's measured
speed: the rail under wheelset i at time t is the recorded level at s(t) + x_i, where s(t)
is the journey's distance axis (speed-integrated, GPS-anchored). Its bogie accelerometer
and gyro are simulated exactly (:mod:`calibration.models.simulate`) where they were mounted.

Measurement and simulation are compared where the recording has content. A recording
filtered to D1 holds wavelengths 3-25 m (EN 13848-1); at varying speed that is no fixed
frequency band, so both signals are resampled on distance. The measurement is band-passed
to those wavelengths (zero-phase Butterworth, as the recording was); the simulation is
not, since its input, the recording, is band-limited already (filters commute).

A journey's absolute position comes from GPS and wanders by metres, half a wavelength at
3 m. Each run is therefore synchronised to the recording first: the distance offset
within +-``max_offset`` that maximises the cross-correlation of measured and simulated
bogie responses is found, reported, and the run simulated again at that offset.

The first and last ``4 x`` the band's longest wavelength (100 m for D1) of every section
are left out of the comparison: there the zero-phase band-pass meets the section's ends and
the simulation starts from static equilibrium. On a noise-free synthetic campaign that
trim takes the bogie-acceleration NRMSE from 0.08-0.10 to 0.010-0.015.

The comparison:

* ``nrmse``: rms(simulated - measured) / rms(measured) in the band;
* ``psd_log_error_db``: mean over the band of |10 log10(PSD_sim / PSD_meas)|, Welch
  spectra over spatial frequency;
* ``residual_rms``: rms(simulated - measured), to set beside the sensor's noise.

The same simulation gives the floor's vertical acceleration, from which the ride comfort
over the recording is reckoned (:mod:`.comfort`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import warnings

import numpy as np
import scipy.signal

from ..data.campaign import Campaign
from ..data.errors import CampaignError
from ..data.tracks import BAND_WAVELENGTHS_M
from ..identification.fdd import distance_axis
from ..models.car2d import CarExtras, Output, build_car, state_space, wheelset_positions, with_campaign_geometry
from ..models.parameters import CarParameters
from ..models.simulate import ModalSimulator
from ..signals.peaks import parabolic_shift
from .comfort import comfort_summary, floor_comfort

BANDS_M = BAND_WAVELENGTHS_M
STEP_M = 0.25  # [m] distance grid of the comparison


@dataclass(frozen=True)
class ChannelComparison:
    channel: str
    nrmse: float
    psd_log_error_db: float
    residual_rms: float  # [SI]
    measured_rms: float  # [SI]


@dataclass(frozen=True)
class RunComparison:
    run_id: str
    distance_range: tuple[float, float]  # [m] of the carbody centre
    mean_speed: float  # [m/s]
    offset: float  # [m] added to the run's distance axis to match the recording
    offset_at_limit: bool  # the best offset sits on the search limit: synchronisation is doubtful
    channels: tuple[ChannelComparison, ...]
    distance: np.ndarray = field(repr=False)
    measured: dict = field(repr=False)
    simulated: dict = field(repr=False)
    comfort: tuple = ()  # FloorComfort per floor position (:mod:`.comfort`); () when the stretch is too short


@dataclass(frozen=True)
class ValidationResult:
    track: str
    band_m: tuple[float, float]
    runs: tuple[RunComparison, ...]
    skipped: tuple = ()  # (run, channel, reason) left out of the comparison
    units: dict = field(default_factory=dict)  # channel -> its SI unit

    def summary(self) -> dict:
        """Per channel: median over runs of each metric."""
        out = {}
        names = {c.channel for r in self.runs for c in r.channels}
        for name in sorted(names):
            rows = [c for r in self.runs for c in r.channels if c.channel == name]
            out[name] = {"nrmse": float(np.median([c.nrmse for c in rows])),
                         "psd_log_error_db": float(np.median([c.psd_log_error_db for c in rows])),
                         "residual_rms": float(np.median([c.residual_rms for c in rows])),
                         "measured_rms": float(np.median([c.measured_rms for c in rows])), "runs": len(rows)}
        return out

    def plot(self, path):
        """Measured against simulated responses and their PSDs, per channel, at ``path``."""
        from .plots import plot_validation

        return plot_validation(self, path)

    def plot_runs(self, path):
        """Every run: measured against simulated, and the residual, of its first channel."""
        from .plots import plot_every_run

        return plot_every_run(self, path)

    def to_json(self) -> dict:
        return {"track": self.track, "band_m": list(self.band_m), "channels": self.summary(),
                "skipped": [{"run": r, "channel": c, "reason": why} for r, c, why in self.skipped],
                "runs": [{"run": r.run_id, "distance_range_m": list(r.distance_range), "mean_speed_m_s": r.mean_speed,
                          "offset_m": r.offset, "offset_at_limit": r.offset_at_limit,
                          "channels": {c.channel: {"nrmse": c.nrmse, "psd_log_error_db": c.psd_log_error_db,
                                                   "residual_rms": c.residual_rms, "measured_rms": c.measured_rms}
                                       for c in r.channels},
                          "ride_comfort": {c.position: c.to_json() for c in r.comfort}} for r in self.runs],
                "ride_comfort": comfort_summary(r.comfort for r in self.runs)}


def _bandpass_distance(x: np.ndarray, band_m: tuple[float, float]) -> np.ndarray:
    fs = 1.0 / STEP_M  # samples per metre
    sos = scipy.signal.butter(4, [1.0 / band_m[1], 1.0 / band_m[0]], btype="bandpass", fs=fs, output="sos")
    return scipy.signal.sosfiltfilt(sos, x)


def _compare(name, meas, sim, band_m) -> ChannelComparison:
    resid = sim - meas
    nper = min(len(meas), int(4 * band_m[1] / STEP_M))
    nu, Pm = scipy.signal.welch(meas, fs=1 / STEP_M, nperseg=nper)
    _, Ps = scipy.signal.welch(sim, fs=1 / STEP_M, nperseg=nper)
    sel = (nu >= 1 / band_m[1]) & (nu <= 1 / band_m[0])
    db = float(np.mean(np.abs(10 * np.log10(np.maximum(Ps[sel], 1e-300) / np.maximum(Pm[sel], 1e-300)))))
    rms_m = float(np.sqrt(np.mean(meas**2)))
    rms_r = float(np.sqrt(np.mean(resid**2)))
    return ChannelComparison(name, rms_r / rms_m if rms_m > 0 else float("inf"), db, rms_r, rms_m)


def _best_offset(meas: dict, sim: dict, max_offset: float) -> float:
    """Distance offset [m] that best aligns the simulation with the measurement (summed
    normalised cross-correlation over the channels, parabolic refinement)."""
    lags = np.arange(-int(max_offset / STEP_M), int(max_offset / STEP_M) + 1)
    score = np.zeros(lags.size)
    for name, m in meas.items():
        x = sim[name] - sim[name].mean()
        c = scipy.signal.correlate(m, x, mode="full", method="fft")
        mid = x.size - 1
        score += c[mid + lags] / (np.linalg.norm(m) * np.linalg.norm(x) + 1e-300)
    k = int(np.argmax(score))
    # measured at grid g equals simulated at g - lag: the run sat lag metres further on
    return float(-(lags[k] + parabolic_shift(score, k)) * STEP_M)


def validate(campaign: Campaign, p: CarParameters, *, extras: CarExtras | None = None, bogie_dx: float = 0.0,
             gyro_gain: float = 1.0, min_length: float = 200.0, max_offset: float = 10.0,
             progress=None) -> ValidationResult:
    """The car ``p`` (with ``extras``: a diagnosis's extended model) over the campaign's
    track recording; ``bogie_dx`` [m] moves the bogie accelerometers from their declared x
    and ``gyro_gain`` scales the pitch gyro, as a diagnosis's sensor finding says."""
    meta = campaign.meta
    tracks = [t for t in campaign.tracks() if t.band in BANDS_M]
    if not tracks:
        raise CampaignError("no track recording filtered to D1 or D2 in track/: nothing to validate over",
                            path=campaign.root / "track")
    track = tracks[0]
    if len(tracks) > 1:
        warnings.warn(f"{campaign.root / 'track'}: validating over {track.path.name} only; "
                      f"{', '.join(t.path.name for t in tracks[1:])} not used", stacklevel=2)
    p, geometry = with_campaign_geometry(p, meta.geometry)
    if geometry:
        warnings.warn(f"{campaign.root / 'campaign.toml'}: the calibration's geometry differs from the campaign's "
                      f"[vehicle]; using the campaign's {geometry}", stacklevel=2)
    trim = 4 * BANDS_M[track.band][1]
    band = BANDS_M[track.band]
    slope = np.gradient(track.level, track.distance)
    xw = wheelset_positions(p)
    sensors = {s.name: s for s in meta.sensors if s.body == "bogie1"}
    outputs = [Output(s.name, "acceleration", "bogie1", s.position[0] + bogie_dx) for s in sensors.values()
               if s.quantity == "acceleration" and s.direction == "z"]
    outputs += [Output(s.name, "pitch_rate", "bogie1") for s in sensors.values()
                if s.quantity == "angular_velocity" and s.direction == "pitch"]
    if not outputs:
        raise CampaignError("no bogie-1 vertical accelerometer or pitch gyro to compare with", path=campaign.root /
                            "campaign.toml", key="sensors")
    floor = [Output(s.name, "acceleration", "carbody", s.position[0]) for s in meta.sensors
             if s.body in ("carbody", "floor") and s.quantity == "acceleration" and s.direction == "z"]
    if not floor:  # EN 12299's floor positions: above the bogie centres and at the car's centre
        floor = [Output(f"floor_{w}", "acceleration", "carbody", x) for w, x in
                 (("front", p.L_v), ("centre", 0.0), ("rear", -p.L_v))]
    ss = state_space(build_car(p, extras=extras), outputs + floor)
    gains = np.array([gyro_gain if o.kind == "pitch_rate" else 1.0 for o in outputs + floor])
    nb = len(outputs)
    runs, skipped = [], []
    for run in campaign.iter_runs():
        d = distance_axis(run.distance, run.speed, run.time)
        if run.speed is not None:
            # over one recorded section the integrated speed is far steadier than GPS fixes:
            # use it alone, anchored on the blended axis; the correlation then fixes the offset
            d_speed = distance_axis(None, run.speed, run.time)
            d = d_speed + np.median(d - d_speed)
        inside = (d + xw.max() <= track.distance[-1]) & (d + xw.min() >= track.distance[0])
        for a, b in run.blocks:
            idx = np.flatnonzero(inside[a:b]) + a
            if idx.size < 2 or d[idx[-1]] - d[idx[0]] < min_length:
                continue
            i0, i1 = idx[0], idx[-1] + 1
            t, s = run.time[i0:i1], d[i0:i1]
            if np.ptp(np.diff(t)) > 1e-3 * np.median(np.diff(t)):
                continue  # needs evenly spaced samples for the exact discretisation
            v = np.gradient(s, t)
            dt = float(np.median(np.diff(t)))
            grid = np.arange(s[0], s[-1], STEP_M)

            def simulate_at(offset):
                w = np.empty((t.size, 8))
                for j in range(4):
                    w[:, j] = np.interp(s + offset + xw[j], track.distance, track.level)
                    w[:, 4 + j] = v * np.interp(s + offset + xw[j], track.distance, slope)
                return ModalSimulator(ss, dt, x0="static").step_chunk(w) * gains

            def on_grid(y):
                return [np.interp(grid, s, y[:, k]) for k in range(nb)]

            meas = {}
            for o in outputs:
                if run.valid[o.name][i0:i1].all():
                    m = np.interp(grid, s, run.channels[o.name][i0:i1])
                    meas[o.name] = _bandpass_distance(m - m.mean(), band)
            if not meas:
                continue
            offset = _best_offset(meas, dict(zip([o.name for o in outputs], on_grid(simulate_at(0.0)))), max_offset)
            at_limit = abs(offset) >= max_offset - STEP_M
            y = simulate_at(offset)
            sim_all = dict(zip([o.name for o in outputs], on_grid(y)))
            keep = slice(int(trim / STEP_M), grid.size - int(trim / STEP_M))
            if keep.stop - keep.start < int(min_length / STEP_M):
                continue
            comfort = _floor_comfort(run, floor, y[:, nb:], (i0, i1), s, grid, keep, band, dt)
            grid = grid[keep]
            meas = {name: m[keep] for name, m in meas.items()}
            sim = {name: sim_all[name][keep] - sim_all[name][keep].mean() for name in meas}
            for name in list(meas):
                if np.sqrt(np.mean(meas[name] ** 2)) <= 1e-6 * max(np.sqrt(np.mean(sim[name] ** 2)), 1e-300):
                    skipped.append((run.run_id, name, "no measured content in the band (a stuck or dead sensor?)"))
                    del meas[name], sim[name]
            comps = [_compare(name, meas[name], sim[name], band) for name in meas]
            if comps:
                runs.append(RunComparison(run.run_id, (float(s[0]), float(s[-1])), float(np.mean(v)), offset,
                                          at_limit, tuple(comps), grid, meas, sim, comfort))
                if progress:
                    progress(f"validate: {run.run_id} over {s[-1] - s[0]:.0f} m at {np.mean(v):.1f} m/s, "
                             f"synchronised by {offset:+.2f} m")
    if not runs:
        raise CampaignError(f"no run covers at least {min_length + 2 * trim:g} m of the track recording "
                            f"{track.path.name} with every wheelset ({min_length:g} m compared plus {trim:g} m left "
                            "out at each end) and usable sensors", path=track.path)
    return ValidationResult(track.name, band, tuple(runs), tuple(skipped), {o.name: o.unit for o in outputs})


def _floor_comfort(run, floor: list, y: np.ndarray, span: tuple, s: np.ndarray, grid: np.ndarray, keep: slice,
                   band: tuple, dt: float) -> tuple:
    """Ride comfort (:mod:`.comfort`) at the floor positions ``floor`` over a run's stretch:
    the simulated accelerations ``y`` (time, position) and the measured ones, where a floor
    accelerometer is and valid, filtered alike to the recording's wavelengths on distance and
    taken back to the samples whose distance lies in the compared part ``grid[keep]``."""
    i0, i1 = span
    inside = (s >= grid[keep][0]) & (s <= grid[keep][-1])

    def in_band(a):
        return np.interp(s, grid, _bandpass_distance(np.interp(grid, s, a - a.mean()), band))[inside]

    out = []
    for k, o in enumerate(floor):
        measured = None
        if o.name in run.channels and run.valid[o.name][i0:i1].all():
            measured = in_band(run.channels[o.name][i0:i1])
        c = floor_comfort(o.name, o.x, 1.0 / dt, in_band(y[:, k]), measured)
        if c is not None:
            out.append(c)
    return tuple(out)
