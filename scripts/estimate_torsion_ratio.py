"""How far can a carbody's second torsion come down towards its first? A lead for seed Figure 5
(issue 4), whose assumed typing asks 18.50 / 11.18 = 1.65 of the torsion pair while the box
model, uniform along the car, keeps about 2 (a free-free torsion bar's ratio).

A free-free bar of the carbody's length (uniform torsional inertia) whose end zones, where a
Shinkansen car has its vestibule doors in both sides, are softer in torsion than the middle:
the first torsion twists most at the middle, the second at the quarter points, so soft ends
lower the second relative to the first. Prints f2 / f1 for zone lengths and rigidity ratios,
and for rotary inertia added at the middle (the first torsion's node). Finite elements,
500 of them; the exact uniform value is 2. The box model does not follow the bar: softened
side walls at its door zones move its torsion pair's ratio only from 2.00 to 1.92
(``check_figure5_credible.py --side-end-zone``; README, issue 4's figures).

    python scripts/estimate_torsion_ratio.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import scipy.linalg

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from calibration.models.box.shinkansen import Geometry  # noqa: E402

LENGTH = Geometry().length  # [m] the Shinkansen-type carbody's length
ELEMENTS = 500


def torsion_ratio(end_rigidity: float, zone: float, middle_inertia: float = 0.0) -> float:
    """f2 / f1 of the free-free bar: torsional rigidity ``end_rigidity`` (relative to the
    middle's) over ``zone`` metres at each end; ``middle_inertia``: rotary inertia added at
    the middle, as a share of the bar's own."""
    n = ELEMENTS + 1
    h = LENGTH / ELEMENTS
    xm = (np.arange(ELEMENTS) + 0.5) * h
    rigidity = np.where((xm < zone) | (xm > LENGTH - zone), end_rigidity, 1.0)
    K = np.zeros((n, n))
    for i, k in enumerate(rigidity / h):
        K[i:i + 2, i:i + 2] += k * np.array([[1.0, -1.0], [-1.0, 1.0]])
    m = np.full(n, h)
    m[[0, -1]] = h / 2
    m[n // 2] += middle_inertia * LENGTH
    w2 = scipy.linalg.eigh(K, np.diag(m), eigvals_only=True, subset_by_index=[0, 2])
    return float(np.sqrt(w2[2] / w2[1]))


def main() -> int:
    ratios = (1.0, 0.7, 0.5, 0.35, 0.25)
    print("end-zone torsional rigidity / middle's: " + "  ".join(f"{r:5.2f}" for r in ratios))
    for zone in (2.0, 3.0, 4.0, 5.0):
        print(f"end zones of {zone:.0f} m: f2/f1 =               "
              + "  ".join(f"{torsion_ratio(r, zone):5.3f}" for r in ratios))
    print("uniform, rotary inertia at the middle (share of the bar's) 0.05, 0.1, 0.2: f2/f1 = "
          + ", ".join(f"{torsion_ratio(1.0, 0.0, m):.3f}" for m in (0.05, 0.1, 0.2)))
    print("seed Figure 5's assumed typing asks 18.50 / 11.18 = 1.655")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
