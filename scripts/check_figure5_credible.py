"""Check (issue 4): can a *credible* Shinkansen-type carbody carry the seed's Figure 5
frequencies with the mode types we assume (scripts/data/rtri_figure5_targets.toml)?

It runs the pipeline of ``railcal calibrate --targets`` (``calibrate_box``) on the credible
factor set (``CREDIBLE_FACTORS`` in ``calibration/models/box/shinkansen.py``, the CLI's default
for typed targets), or on the variants below, and says more about the answer. Unlike the
grouped set (the truth simulator's twelve), the in-plane shear of roof, floor and sides is a
factor of its own (14 factors), each in a range fixed *before* the fit by what is physically
credible for an aluminium double-skin carbody:

* in-plane normal rigidity 0.5-2 (material and skin thickness are fairly well known);
* in-plane shear 0.1-2 (window and door openings, extrusions' shear flexibility);
* bending 0.25-4 (smeared core depth); the end walls 0.1-4 (gangway openings);
* joint rotational springs 0.25-20 and translational 0.1-10 (artificial, hardly known).

The seed's swarm (MAC pairing with the type's floor pattern, modes at least half carbody
by kinetic energy, a pairing counting only with MAC >= 0.8 and its own partner, as the
CLI) runs on log factors, then the CasADi refinement; the answer
is re-solved on the full model. Prints each factor (flagging those on a range limit) and
each target's model frequency, error and MAC. Target of issue 4: max error <= 0.5 %.
``--orthotropic`` makes each roof, floor and side rigidity along, across and in shear a
factor of its own (23 factors, see ``ORTHOTROPIC``). ``--side-end-zone METRES`` adds one
factor more: the side walls' in-plane shear over that length at each end of the car, where a
Shinkansen car has its vestibule doors in both sides (credible 0.05-1 of the nominal side
shear: an opening can only soften; the rest of each side keeps ``side_shear``). A free-free
bar with such soft ends brings the second torsion down towards the first
(``scripts/estimate_torsion_ratio.py``), which the assumed typing asks (1.65, not 2).

``--all-joints``: after the swarm and the refinement, the polish (``--polish``) also moves the
four joint springs (``POLISH_JOINT_FACTORS``) from nominal: the end walls' joints (to roof,
floor and sides) and the joints between the three floor panels, in the joint ranges above;
with ``--polish 30`` this is the CLI's credible set. (A swarm over all 18 factors, 200 x 200,
ended at 1.45 %, these four on their limits.)

``--probe`` asks, at the answer, what holds the error there: the minimax of the frequencies
linearised with the full model's exact eigen-derivatives (d f / d log p_i =
p_i x^T K_i x / (8 pi^2 f)) within +-5 % of the factors, then steps of halving length
towards it, each re-solved on the full model with its MACs.

``--polish STEPS`` goes on from the refinement's answer with the sequential LP on the full
model that keeps every MAC above the floor (``polish_box``, as the CLI's typed targets): where
the floor binds, the CasADi refinement, which fits frequencies only, has every round refused.

``--describe`` says what each partner mode does above the floor (the floor patterns name the
types, but a pattern can come from more than one motion): at 12 sections along the car, the
largest of each section quantity, relative to the largest of all: floor and roof tilt and the
roof's lateral motion relative to the floor's (as rotations times the 1.5 m half-width; all
three equal for a rigid section's twist), the section's mean lateral and vertical motion,
the floor's and the roof's centre against their edges, and the roof against the floor.

    python scripts/check_figure5_credible.py [--particles 200] [--iterations 200] [--seed 0] [--targets TOML]
        [--orthotropic] [--all-joints] [--side-end-zone 3.5] [--polish 30] [--probe] [--describe]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

from calibration.calibrate import read_targets
from calibration.calibrate_box import PairingSettings, RefineSettings, SwarmSettings, box_search, calibrate_box
from calibration.swarm_defaults import TYPED_MIN_MAC
from calibration.data.campaign import Sensor
from calibration.models.box import FactorSet, assemble, shinkansen_vehicle
from calibration.models.box.assembly import StiffnessParameter
from calibration.models.box.fit import BoxFit, sensor_operator
from calibration.models.box.mode_types import MODE_TYPES, typed_targets
from calibration.models.box.parametric_basis import full_modes
from calibration.models.box.shinkansen import CREDIBLE_FACTORS, POLISH_JOINT_FACTORS, Geometry
from calibration.optimisers.base import bounds
from calibration.optimisers.minimax import linearised_minimax
from calibration.optimisers.pso import PSOSettings
from calibration.models.box.rig import SENSOR_GRID

TARGETS = Path(__file__).parent / "data" / "rtri_figure5_targets.toml"
#: ``--orthotropic``: each roof, floor and side rigidity along and across the car a factor of
#: its own (the seed's panels are anisotropic); A12 and D12 stay nominal (nu = 0.3 gives
#: A12^2 = 0.09 A11 A22 and D12^2 = 0.09 D11 D22), so the lower limits 0.5 and 0.35 keep
#: every panel's rigidity matrix positive definite (product of two factors above 0.09).
ORTHOTROPIC = tuple(
    (StiffnessParameter(f"{g}_{name}", "panel", g, terms, f"{g} {text}"), limits)
    for g in ("roof", "floor", "side")
    for name, terms, text, limits in (
        ("A11", ("A11",), "in-plane normal along", (0.5, 2.0)),
        ("A22", ("A22",), "in-plane normal across", (0.5, 2.0)),
        ("A66", ("A66",), "in-plane shear", (0.1, 2.0)),
        ("D11", ("D11",), "bending along", (0.35, 4.0)),
        ("D22", ("D22",), "bending across", (0.35, 4.0)),
        ("D66", ("D66",), "twisting", (0.3, 4.0)))
) + tuple(c for c in CREDIBLE_FACTORS if c[0].kind == "joint" or c[0].group == "end")  # end walls, joints as before


def probe(fit: BoxFit, p, low, high, trust: float = 0.05, steps: int = 8) -> None:
    """What holds the full-model error at ``p`` (see the module docstring, ``--probe``)."""
    check, G = fit.frequency_gradient(p)  # d (f / f_target) / d log p
    q = np.log(p)
    d, t = linearised_minimax(check["frequency_hz"] / fit.f_target, G, q, np.log(low), np.log(high), trust)
    print(f"probe: the frequencies linearised within +-{100 * trust:g} % of the factors reach {100 * t:.3f} %; "
          f"steps towards that, on the full model:")
    for k in range(steps):
        step = fit.full_check(np.exp(q + d / 2**k))
        print(f"  {100 / 2**k:7.3f} % of the step: max error {step['max_error_pct']:8.3f} % (penalties included), "
              f"frequencies {np.max(np.abs(step['error_pct'])):.3f} %, MAC {' '.join(f'{v:.3f}' for v in step['mac'])}")


def describe(fit: BoxFit, p, g: Geometry = Geometry(), half: float = 1.5) -> None:
    """What each target's partner mode does above the floor (``--describe``)."""
    check = fit.full_check(p)
    _, X = full_modes(fit.model, p, fit.n_modes)
    H = g.roof_z - g.floor_z
    points = (("floor", "z", half, g.floor_z), ("floor", "z", -half, g.floor_z), ("roof", "z", half, g.roof_z),
              ("roof", "z", -half, g.roof_z), ("floor", "y", 0.0, g.floor_z), ("roof", "y", 0.0, g.roof_z),
              ("floor", "z", 0.0, g.floor_z), ("roof", "z", 0.0, g.roof_z))
    xs = np.linspace(-0.45 * g.length, 0.45 * g.length, 12)
    O = sensor_operator(fit.model, [Sensor("probe", "displacement", "m", body, d, (float(x), y, z))
                                    for x in xs for body, d, y, z in points])
    print("partner modes above the floor (largest over 12 sections, relative to the largest quantity):")
    for t, k, fk in zip(fit.targets, check["index"], check["frequency_hz"]):
        fz, fzm, rz, rzm, fy, ry, fc, rc = (O @ X[:, k]).reshape(len(xs), len(points)).T
        q = {"floor tilt": (fz - fzm) / 2, "roof tilt": (rz - rzm) / 2, "roof sway": -(ry - fy) * half / H,
             "lateral": (fy + ry) / 2, "vertical": (fc + rc) / 2, "floor centre-edge": fc - (fz + fzm) / 2,
             "roof centre-edge": rc - (rz + rzm) / 2, "roof-floor": rc - fc}
        top = max(np.abs(v).max() for v in q.values())
        print(f"  {t.label:20s} {fk:6.2f} Hz: " + ", ".join(f"{n} {np.abs(v).max() / top:.2f}" for n, v in q.items()))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--particles", type=int, default=200)
    ap.add_argument("--iterations", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=20, help="CasADi refinement rounds")
    ap.add_argument("--targets", type=Path, default=TARGETS,
                    help="typed targets (TOML as scripts/data/rtri_figure5_targets.toml)")
    ap.add_argument("--orthotropic", action="store_true",
                    help="roof, floor and side rigidities along, across and in shear as factors of their own (23)")
    ap.add_argument("--all-joints", action="store_true",
                    help="the polish also moves the end walls' and the floor panels' joints (4 factors more)")
    ap.add_argument("--min-mac", type=float, default=TYPED_MIN_MAC,
                    help="a pairing counts only with MAC >= this (as the CLI; 0: every pairing, as before 2026-11-25)")
    ap.add_argument("--probe", action="store_true", help="at the answer: what holds the error there")
    ap.add_argument("--polish", type=int, default=0, metavar="STEPS",
                    help="after the refinement: a MAC-constrained sequential LP on the full model")
    ap.add_argument("--describe", action="store_true", help="what the partner modes do above the floor")
    ap.add_argument("--side-end-zone", type=float, default=0.0, metavar="METRES",
                    help="a factor more: the side walls' in-plane shear over this length at each end (doors)")
    args = ap.parse_args()
    credible = ORTHOTROPIC if args.orthotropic else CREDIBLE_FACTORS
    if args.side_end_zone > 0:
        credible = credible + ((StiffnessParameter("side_end_shear", "panel", "side", ("A66",),
                                                   "side in-plane shear at the door zones",
                                                   end_zone=args.side_end_zone), (0.05, 1.0)),)

    targets = read_targets(args.targets, labels=tuple(MODE_TYPES), model="the box model (mode types)")
    g = Geometry()
    typed = typed_targets(targets, SENSOR_GRID, g.length, g.width)
    staged = POLISH_JOINT_FACTORS if args.all_joints else ()
    credible = credible + staged
    factors = FactorSet.from_pairs("check", credible, len(staged))
    search = box_search(factors=factors)
    t0 = time.perf_counter()
    pso = PSOSettings(particles=args.particles, iterations=args.iterations, target=0.5)
    cal = calibrate_box(typed, SENSOR_GRID, search, factors=factors,
                        swarm=SwarmSettings(pso=pso, seed=args.seed, log_factors=True),
                        refinement=RefineSettings(rounds=args.rounds, polish_steps=args.polish),
                        pairing=PairingSettings(min_mac=args.min_mac), progress=lambda m: print(" ", m, flush=True))
    ref, pol = cal.refinement, cal.refinement.get("polish")
    print(f"swarm {args.particles} x {cal.pso['iterations']} on log factors over {len(cal.pso['factors'])} factors: "
          f"{cal.pso['best_full_pct']:.3f} % (full model), {cal.pso['wall_s']:.0f} s")
    print(f"after {ref['rounds']} refinement rounds: max error "
          f"{(pol['start_max_error_pct'] if pol else ref['end_max_error_pct']):.3f} % (target 0.5 %)")
    if pol:
        print(f"after {pol['steps']} polishing steps over {len(pol['factors'])} factors ({pol['kept']} kept): "
              f"max error {pol['end_max_error_pct']:.3f} % (target 0.5 %)")
    print(f"{time.perf_counter() - t0:.0f} s in all")
    p = np.array([cal.parameters[n] for n in factors.names])
    for (q, (lo, hi)), v in zip(credible, p):
        limit = " ON A LIMIT" if min(abs(np.log(v / lo)), abs(np.log(v / hi))) < 0.02 else ""
        print(f"  {q.name:16s} {v:7.3f}   credible {lo:g}-{hi:g}{limit}")
    for row in cal.fit:  # re-solved on the full model by calibrate_box
        print(f"  {row['label']:20s} {row['measured_hz']:6.2f} Hz -> {row['model_hz']:7.3f} Hz "
              f"({row['error_pct']:+.2f} %), MAC {row['mac']:.2f}{'' if row['sound'] else ' UNSOUND'}")
    if args.describe or args.probe:  # the full model at the answer, once more
        model = assemble(shinkansen_vehicle(parameters=factors.parameters))
        fit = BoxFit(model, sensor_operator(model, SENSOR_GRID), typed, 
                     min_mac=args.min_mac)
        fit.rebuild(p)
        if args.describe:
            describe(fit, p)
        if args.probe:
            probe(fit, p, *bounds(search))
    return 0 if cal.max_error_pct <= 0.5 else 1


if __name__ == "__main__":
    sys.exit(main())
