"""Benchmark: the EN 12299 / ISO 2631 weightings against ISO 8041-1 Annex B (issue 32 target:
within 0.1 dB at the tabulated frequencies), printed per weighting, with the EN 12299 Wb
against its second implementation from poles and zeros.

    python scripts/bench_comfort.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_comfort import ANNEX_B, ANNEX_B_HZ, _zpk_magnitude  # noqa: E402  (the tables live with the tests)

from calibration.signals.comfort import WB_EN  # noqa: E402


def main() -> None:
    for name, (w, table) in ANNEX_B.items():
        err = 20 * np.log10(w.magnitude(ANNEX_B_HZ) / np.array(table))
        print(f"{w.name:18s} vs ISO 8041-1 Annex B, {ANNEX_B_HZ.size} frequencies 0.1-400 Hz: "
              f"max |error| {np.max(np.abs(err)):.4f} dB")
    f = np.geomspace(0.05, 500.0, 400)
    err = 20 * np.log10(WB_EN.magnitude(f) / _zpk_magnitude(WB_EN, f))
    print(f"{WB_EN.name:18s} vs its poles-and-zeros form, 400 frequencies 0.05-500 Hz: "
          f"max |error| {np.max(np.abs(err)):.1e} dB")


if __name__ == "__main__":
    main()
