"""Acceptance check (issue 3): what validation leaves on an effect-free campaign is measurement noise.

The same journeys (one seed) are synthesised five times: with every noise source of the
truth simulator, with none, and with each group alone (accelerometer and gyro noise;
GPS and Doppler speed errors; track recording noise). Each is validated with the TRUE
parameters, so the model is exact and only measurement imperfections remain, and with the
calibrated parameters, which adds the parameter error along undetermined directions.
For the sensor-noise variant the residual is compared with the simulator's own white noise
pushed through the identical processing (resampling on distance, band-pass 3-25 m).

    python scripts/check_validate_noise.py [--seed 7] [--journeys 4]
"""
from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

from calibration.calibrate import calibrate_car, search_from_priors
from calibration.data.campaign import open_campaign
from calibration.identification.in_service import identify_in_service, prior_parameters
from calibration.models.parameters import CarParameters
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec
from calibration.validation.in_service import STEP_M, _bandpass_distance, validate

QUIET = dict(axle_acc_noise=0.0, bogie_acc_noise=0.0, gyro_noise_raw=0.0, gps_error=0.0, gps_jitter=0.0,
             speed_noise=0.0, recording_noise=0.0)


def processed_noise_rms(campaign, result, channel: str, sigma: float, rng) -> float:
    """rms of white noise of std ``sigma`` on each run's time grid after the validation's processing."""
    out = []
    for r in result.runs:
        run = campaign.read_run(r.run_id)
        t = run.time
        sel = np.flatnonzero((run.distance >= r.distance_range[0] - 5) & (run.distance <= r.distance_range[1] + 5))
        s = np.linspace(r.distance_range[0], r.distance_range[1], sel.size)  # uniform speed suffices here
        noise = rng.normal(0.0, sigma, sel.size)
        grid = np.arange(s[0], s[-1], STEP_M)
        x = _bandpass_distance(np.interp(grid, s, noise), result.band_m)
        out.append(np.sqrt(np.mean(x**2)))
        del t
    return float(np.median(out))


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--journeys", type=int, default=4)
    args = ap.parse_args()
    base = InServiceSettings(journeys=args.journeys, line=LineSpec(length=40_000.0), gap_probability=0.0,
                             nan_probability=0.0)
    variants = {
        "all noise (default)": base,
        "no noise": dataclasses.replace(base, **QUIET),
        "accelerometer and gyro noise only": dataclasses.replace(base, **{**QUIET, "bogie_acc_noise": base.bogie_acc_noise,
                                                                          "gyro_noise_raw": base.gyro_noise_raw,
                                                                          "axle_acc_noise": base.axle_acc_noise}),
        "GPS and speed errors only": dataclasses.replace(base, **{**QUIET, "gps_error": base.gps_error,
                                                                  "gps_jitter": base.gps_jitter,
                                                                  "speed_noise": base.speed_noise}),
        "track recording noise only": dataclasses.replace(base, **{**QUIET, "recording_noise": base.recording_noise}),
    }
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        rows = {}
        for name, settings in variants.items():
            root = Path(tmp) / name.replace(" ", "_")
            truth = synth_in_service(root, seed=args.seed, settings=settings, fmt="parquet")
            campaign = open_campaign(root)
            p_true = CarParameters(**truth["parameters"])
            res = validate(campaign, p_true)
            rows[name] = (res.summary(), truth, campaign, res)
            print(f"\n{name}: validated with the true parameters")
            for ch, v in res.summary().items():
                print(f"  {ch:18s} NRMSE {v['nrmse']:.4f}  PSD {v['psd_log_error_db']:.3f} dB  "
                      f"residual {v['residual_rms']:.4g}  measured {v['measured_rms']:.4g} (SI)")
        # the budget: each group's part = sqrt(residual^2 - floor^2); parts add in quadrature
        print("\nresidual budget with the true parameters (rms, SI):")
        for ch in ("bogie1_acc_z", "bogie1_gyro_pitch"):
            floor = rows["no noise"][0][ch]["residual_rms"]
            parts = {name: float(np.sqrt(max(rows[name][0][ch]["residual_rms"] ** 2 - floor**2, 0.0)))
                     for name in list(variants)[2:]}
            total = float(np.sqrt(floor**2 + sum(v**2 for v in parts.values())))
            _, truth, campaign, res = rows["accelerometer and gyro noise only"]
            expected = processed_noise_rms(campaign, res, ch, truth["noise_rms_si"][ch], rng)
            print(f"  {ch}: method floor (no noise) {floor:.4g}; "
                  + "; ".join(f"{k}: {v:.4g}" for k, v in parts.items())
                  + f"; quadrature sum {total:.4g} against all noise {rows['all noise (default)'][0][ch]['residual_rms']:.4g}")
            sensor = parts["accelerometer and gyro noise only"]
            print(f"    sensor-noise part {sensor:.4g} against the simulator's noise after the same processing "
                  f"{expected:.4g} (ratio {sensor / expected:.2f})")
        # the default campaign with the calibrated model
        summary, truth, campaign, _ = rows["all noise (default)"]
        ident = identify_in_service(campaign)
        targets = {m.label: m.frequency_hz for m in ident.modes}
        cal = calibrate_car(targets, search_from_priors(campaign.meta.priors), base=prior_parameters(campaign),
                            runs=3, seed=args.seed, refine_result=True)
        res = validate(campaign, cal.parameters)
        print("\nall noise (default), validated with the CALIBRATED parameters:")
        for ch, v in res.summary().items():
            print(f"  {ch:18s} NRMSE {v['nrmse']:.4f}  PSD {v['psd_log_error_db']:.3f} dB  "
                  f"residual {v['residual_rms']:.4g}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
