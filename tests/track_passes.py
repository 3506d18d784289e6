"""A pass of the 2D car's own response over a known profile, for the track-inference tests:
their inverses' code is checked on data their own model made (evidence on independent
data is the exudyn-truth bench, scripts/bench_infer_track.py)."""
import numpy as np
import scipy.signal

from calibration.models.car2d import Output, build_car, state_space, wheelset_positions
from calibration.models.simulate import simulate
from calibration.models.track_irregularity import german_vertical_psd, synthesise_profile
from calibration.models.vehicles import VEHICLES
from calibration.track_inference.passes import Channel, Pass

STEP = 0.25  # [m] the pass grid
FS = 500.0  # [Hz] the logger
NOISE = {"bogie_acc": 0.02, "gyro": 3e-4}  # [m/s^2], [rad/s] white, rms at FS


def own_pass(length: float, seed: int = 1):
    """The intercity car at 35 +- 3 m/s over a German low-disturbance profile: its bogie
    accelerometer and pitch gyro with white noise, low-passed at 30 Hz and read on the grid.
    Returns the pass and the true profile (s, z)."""
    p = VEHICLES["intercity"]
    rng = np.random.default_rng(seed)
    sx, zx = synthesise_profile(german_vertical_psd, length + 500.0, 0.05, rng, min_wavelength=1.0,
                                max_wavelength=200.0)
    sx = sx - 100.0
    fs, v0 = FS, 35.0
    t = np.arange(0, length / v0, 1 / fs)
    v = v0 + 3 * np.sin(2 * np.pi * t / 40)
    s = np.concatenate([[0], np.cumsum(0.5 * (v[1:] + v[:-1]) / fs)])
    xw = wheelset_positions(p)
    outs = [Output("acc", "acceleration", "bogie1", p.L_v + 0.45), Output("gyro", "pitch_rate", "bogie1")]
    slope = np.gradient(zx, sx)
    w = np.empty((t.size, 8))
    for j in range(4):
        w[:, j] = np.interp(s + xw[j], sx, zx)
        w[:, 4 + j] = v * np.interp(s + xw[j], sx, slope)
    y = simulate(state_space(build_car(p), outs), w, 1 / fs, x0="static")
    y[:, 0] += rng.normal(0, NOISE["bogie_acc"], t.size)
    y[:, 1] += rng.normal(0, NOISE["gyro"], t.size)
    y[:, 0] += 9.80665  # the accelerometer's gravity offset, which the inverse must ignore
    grid = np.arange(s[0], s[-1], STEP)
    tg = np.interp(grid, s, t)
    sos = scipy.signal.butter(4, 30, fs=fs, output="sos")
    chans = (Channel("acc", "bogie_acc", np.interp(tg, t, scipy.signal.sosfiltfilt(sos, y[:, 0])), x=p.L_v + 0.45),
             Channel("gyro", "gyro", np.interp(tg, t, scipy.signal.sosfiltfilt(sos, y[:, 1]))))
    ps = Pass("own", grid, tg, np.interp(tg, t, v), np.interp(tg, t, np.gradient(v, t)), chans)
    return p, ps, (sx, zx)
