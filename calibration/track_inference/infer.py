"""``infer_track``: a campaign's passes through the Kalman filter, combined into the
section's profile, with the summary the command writes beside it."""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from .. import checks
from ..data.campaign import Campaign
from ..models.car2d import CarExtras, wheelset_positions, with_campaign_geometry
from ..models.parameters import CarParameters
from .inertial import blend
from .kalman import KalmanSettings, PassProfile, fit_noise, infer_pass
from .passes import Pass, read_passes
from .profile import BANDS, Change, SectionProfile, best_offset, changes, combine, interp_gapped

#: D2 is written where its standard deviation is under this fraction of the level's rms
D2_USABLE = 0.5


@dataclass(frozen=True)
class InferSettings:
    """axle_boxes: use the leading bogie's axle boxes too; fit: choose the spectrum's level
    and the channels' noise on the longest pass (:func:`~.kalman.fit_noise`), over its first
    ``fit_length`` [m]; draws: error draws per pass for the standard deviations;
    max_offset [m]: how far passes may be shifted to align them; crossover [m]: with axle
    boxes, the wavelength under which their double integral replaces the filter's level
    (:func:`~.inertial.blend`; 8 m, the middle of D1 on a log scale)."""

    kalman: KalmanSettings = field(default_factory=KalmanSettings)
    axle_boxes: bool = False
    fit: bool = True
    fit_length: float = 800.0
    draws: int = 8
    max_offset: float = 10.0
    min_length: float = 200.0
    crossover: float = 8.0

    def __post_init__(self):
        checks.positive(self, "fit_length", "max_offset", "min_length", "crossover")
        checks.whole(self, "draws", minimum=0)


@dataclass(frozen=True)
class TrackResult:
    section: SectionProfile
    passes: tuple[Pass, ...]
    profiles: tuple[PassProfile, ...]
    settings: KalmanSettings
    fitted: bool
    sensors: tuple[str, ...]
    wall_s: float
    changes: tuple[Change, ...] | None = None
    compared_offset: float | None = None

    def d2_usable(self) -> tuple[bool, float, float]:
        """(usable, median std, rms of the level) of the D2 band."""
        ok = self.section.passes["D2"] > 0
        if not ok.any():
            return False, float("nan"), float("nan")
        std = float(np.median(self.section.std["D2"][ok]))
        rms = float(np.sqrt(np.mean(self.section.level["D2"][ok] ** 2)))
        return bool(std < D2_USABLE * rms), std, rms

    def to_json(self) -> dict:
        s, k = self.section, self.settings
        aligned = [s.offsets[q] for q in s.offsets if np.isfinite(s.correlation.get(q, np.nan))]
        bands = {}
        for band in BANDS:
            ok = s.passes[band] > 0
            bands[band] = None if not ok.any() else {
                "from_m": float(s.distance[ok][0]), "to_m": float(s.distance[ok][-1]),
                "level_rms_mm": 1e3 * float(np.sqrt(np.mean(s.level[band][ok] ** 2))),
                "std_median_mm": 1e3 * float(np.median(s.std[band][ok])),
                "std_max_mm": 1e3 * float(np.max(s.std[band][ok])),
                "passes_max": int(s.passes[band].max())}
        usable, std, rms = self.d2_usable()
        if bands["D2"] is not None:
            bands["D2"]["written"] = usable
            bands["D2"]["reason"] = (f"its median standard deviation {1e3 * std:.3g} mm is "
                                     f"{'under' if usable else 'not under'} {D2_USABLE:g} x its level's rms "
                                     f"{1e3 * rms:.3g} mm")
        out = {
            "method": "Kalman filter in distance with a fixed-lag smoother (calibration/track_inference)",
            "sensors": list(self.sensors), "step_m": k.step, "lag_m": k.lag,
            "prior": {"spectrum": k.spectrum, "roughness": k.roughness, "fitted": self.fitted},
            "noise": {kind: k.noise[kind] for kind in sorted({c.kind for p in self.passes for c in p.channels})},
            "bands": bands,
            # the section sits at the aligned passes' mean GPS position: its standard error (unknown
            # for one pass, whose GPS error nothing here measures)
            "position_std_m": (float(np.std(aligned, ddof=1) / np.sqrt(len(aligned))) if len(aligned) >= 2
                               else None),
            "passes": [{"run_id": p.run_id, "from_m": float(p.s[0]), "to_m": float(p.s[-1]),
                        "mean_speed_m_s": float(np.mean(p.v)), "offset_m": s.offsets.get(p.run_id),
                        "correlation_with_reference": _finite(s.correlation.get(p.run_id)),
                        "innovation_ratio": pr.innovation_ratio}
                       for p, pr in zip(self.passes, self.profiles)],
            "wall_s": self.wall_s,
        }
        if self.changes is not None:
            out["changes"] = [c.to_json() for c in self.changes]
            out["compared_offset_m"] = self.compared_offset
        return out


def _finite(x):
    return None if x is None or not np.isfinite(x) else float(x)


def infer_track(campaign: Campaign, p: CarParameters, *, extras: CarExtras | None = None, bogie_dx: float = 0.0,
                gyro_gain: float = 1.0, settings: InferSettings = InferSettings(), progress=None) -> TrackResult:
    """The level under the campaign's leading bogie, every pass combined."""
    t0 = time.perf_counter()
    p, geometry = with_campaign_geometry(p, campaign.meta.geometry)
    if geometry:
        warnings.warn(f"{campaign.root / 'campaign.toml'}: the calibration's geometry differs from the campaign's "
                      f"[vehicle]; using the campaign's {geometry}", stacklevel=2)
    k = settings.kalman
    passes = read_passes(campaign, step=k.step, axle_boxes=settings.axle_boxes, bogie_dx=bogie_dx,
                         min_length=settings.min_length, progress=progress)
    if settings.fit:
        k, _ = fit_noise(max(passes, key=lambda q: q.s.size), p, k, extras=extras, gyro_gain=gyro_gain,
                         length=settings.fit_length)
        if progress:
            kinds = sorted({c.kind for c in passes[0].channels})
            progress(f"infer-track: spectrum level x{k.roughness:.3g}, noise "
                     + ", ".join(f"{c} {k.noise[c]:.3g}" for c in kinds))
    profiles = []
    for i, ps in enumerate(passes):
        pr = infer_pass(ps, p, k, extras=extras, gyro_gain=gyro_gain, draws=settings.draws, seed=i)
        if settings.axle_boxes:
            pr = blend(pr, ps, wheelset_positions(p), settings.crossover)
        profiles.append(pr)
        if progress:
            progress(f"infer-track: {ps.run_id} {ps.s[-1] - ps.s[0]:.0f} m inferred")
    section = combine(profiles, k.step, max_offset=settings.max_offset)
    sensors = tuple(dict.fromkeys(c.name for ps in passes for c in ps.channels))
    return TrackResult(section, tuple(passes), tuple(profiles), k, settings.fit, sensors,
                       time.perf_counter() - t0)


def compare(result: TrackResult, distance: np.ndarray, level: np.ndarray, *, max_offset: float = 10.0,
            threshold: float = 6.0) -> TrackResult:
    """``result`` with the changes from an earlier D1 profile (``distance``, ``level`` [m])."""
    s = result.section
    ok = s.passes["D1"] > 0
    lo, hi = max(distance[0], s.distance[ok][0]), min(distance[-1], s.distance[ok][-1])
    if hi - lo < 10 * max_offset:
        raise ValueError(f"the earlier profile ({distance[0]:.0f}-{distance[-1]:.0f} m) overlaps this one "
                         f"({s.distance[ok][0]:.0f}-{s.distance[ok][-1]:.0f} m) by less than {10 * max_offset:g} m")
    offset, _ = best_offset(distance, level, s.distance[ok], s.level["D1"][ok], s.distance[1] - s.distance[0],
                            max_offset)
    before = interp_gapped(s.distance, distance - offset, level)
    found, _ = changes(s.distance, before, np.where(ok, s.level["D1"], np.nan), s.distance[1] - s.distance[0],
                       threshold=threshold)
    return replace(result, changes=tuple(found), compared_offset=offset)
