"""Modal identification of an in-service campaign: ``railcal identify`` for kind in_service.

Two estimates of every rigid-body mode, from the same random 2 km segments:

* **seed-faithful FDD** (:mod:`.fdd`): the analyses of seed Table 3, summed first
  singular values, peak picking. Output-only; on bogie sensors the carbody modes barely
  rise above the rail input, and the wheelbase filter (a notch at v / 4 L_b sweeping
  across 4-10 Hz with speed) pulls the heavily damped bogie bounce peak low.
* **segmental input-output** (when the instrumented bogie has axle-box accelerometers and
  the geometry is known): with the wheelsets on the rail, the axle boxes measure the
  rail's acceleration, the input. The trailing bogie runs over the same rail 2 L_v later,
  so its input is the measured one delayed in distance. A two-input H1 estimate over
  segments at many speeds separates the bogie's response to its own rail from its
  response to the trailing bogie's rail, which travels only through the carbody and
  carries nothing but the carbody modes. Rational-fraction fits
  (:func:`.frf.fit_poles`) give natural frequency and damping of each mode.

Labels: bogie bounce from the bogie-centre acceleration's own-rail FRF, bogie pitch
from the gyro's FRF to the rail pitch, carbody bounce and pitch from the trailing-rail
FRF, told apart by the sign of their quasi-static contribution: raising the trailing
bogie lifts the whole carbody in bounce (+) and lowers its front in pitch (-). Without
axle-box sensors, FDD peaks are labelled by frequency order against the prior model.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

import warnings

from .. import checks
from ..data.campaign import Campaign
from ..data.errors import CampaignError
from ..data.outputs import result_label, result_number, result_rows
from ..data.units import SI_UNIT
from ..models.car2d import build_car, frequencies_by_label, undamped_modes
from ..models.channel_shapes import response_channels
from ..models.parameters import CAR_PARAMETER_SPECS, CarParameters, ParameterError
from ..models.vehicles import INTERCITY_TRAILER
from ..signals.noise_floor import NoiseFloorSettings, WelchSums
from ..signals.resample import regular_run
from ..signals.spectral_lines import LineSettings, LineWindowCollector, SpectralLine
from .fdd import (Analysis, FDDSettings, SegmentalFDD, SegmentalFDDAccumulator, derived_channels, fdd_peaks,
                  plan_analyses, plan_segments)
from .data_quality import noise_band, run_report
from .frf import Pole, fit_poles, h1
from .prior_range import damping_outside, outside, prior_damping_ranges, prior_frequency_ranges
from .shapes import SHAPE_ANALYSIS, ModeShape, mode_shape, shape_analysis

RIGID_LABELS = ("carbody_bounce", "carbody_pitch", "bogie_bounce", "bogie_pitch")
#: Above this damping ratio a mode's response has no resonance peak (a single degree of
#: freedom's displacement FRF peaks only below 1 / sqrt(2)), so a fitted pole's frequency
#: rests on the FRF's flanks alone: on the independent truth, Pioneer R's near-critically
#: damped bogie modes came out 8-35 % off.
NO_PEAK_DAMPING = 1 / np.sqrt(2)
IO_ANALYSIS = "input_output"


@dataclass(frozen=True)
class IdentifySettings:
    fdd: FDDSettings = FDDSettings()
    lines: LineSettings = LineSettings()
    noise: NoiseFloorSettings = NoiseFloorSettings()  # channels' noise floors, above the FDD band
    carbody_band: tuple[float, float] = (0.4, 4.0)  # [Hz]
    bogie_band: tuple[float, float] = (2.5, 20.0)  # [Hz]
    extra_poles: int = 1  # computational poles that absorb what lies outside the band
    # A bogie mode is fitted over its prior frequency divided and multiplied by this: a
    # bogie bounce damped 0.5 still transmits 85 % of its peak at half its frequency and
    # 40 % at twice it, and a fixed 2.5-20 Hz band cut the lower flank of a 4.3 Hz one.
    bogie_band_factor: float = 2.5
    # A bogie pole is taken from the lowest fit order at which it stays within this fraction
    # of its frequency at the next order (up to ``extra_poles + max_extra_order`` extra
    # poles): a carbody bending or equipment mode in the band takes a pole of its own.
    order_stability: float = 0.01
    max_extra_order: int = 3
    peak_prominence: float = 0.1  # [decades] of a summed-singular-value peak, at least
    min_coherence: float = 0.5  # FRF bins below this are not fitted
    # Random segments (possibly overlapping, from all runs) averaged by the input-output
    # estimate, whose variance falls with each (docs/methods/identification-in-service.md).
    io_segments: int = 200
    # Least median over the carbody band of 1 - |coherence of the two inputs|^2, the share
    # of the trailing rail that is not the leading rail's delayed copy; below it the
    # two-input estimate is not used (the same document gives the campaigns behind 0.3).
    min_separability: float = 0.3
    # A mode whose jackknife standard error over the journeys exceeds this share of its
    # frequency is reported undetermined: the data fix it less well than a calibration
    # target needs (carbody modes, bogie modes; 1.0 turns the check off).
    max_relative_std: tuple[float, float] = (0.03, 0.02)

    def __post_init__(self):
        checks.increasing(self, "carbody_band", "bogie_band", low=0.0)
        checks.whole(self, "extra_poles", minimum=0)
        checks.whole(self, "max_extra_order", minimum=1)
        checks.positive(self, "order_stability")
        checks.above(self, "bogie_band_factor", bound=1.0)
        checks.whole(self, "io_segments")
        checks.non_negative(self, "peak_prominence")
        checks.fraction(self, "min_coherence", "min_separability", closed=True)
        v = self.max_relative_std
        if not (isinstance(v, tuple) and len(v) == 2
                and all(isinstance(x, (int, float)) and 0 < x <= 1 for x in v)):
            raise ValueError(f"IdentifySettings.max_relative_std must be a tuple of two shares in (0, 1] "
                             f"(carbody, bogie), got {v!r}")


@dataclass(frozen=True)
class IdentifiedMode:
    label: str
    frequency_hz: float  # natural frequency
    damping_ratio: float | None
    damped_frequency_hz: float | None
    method: str  # 'input_output_fit' | 'fdd_peak'
    source: str  # which analysis / FRF
    fdd_peak_hz: float | None  # the seed-faithful FDD estimate, where a peak was found
    prior_hz: float | None  # the prior model's frequency, for reference
    frequency_std_hz: float | None = None  # delete-one-journey jackknife standard error
    shape: ModeShape | None = None  # at the response channels, :mod:`.shapes`

    def to_json(self) -> dict:
        return {**self.__dict__, "shape": None if self.shape is None else self.shape.to_json()}

    @classmethod
    def from_json(cls, row: dict, where: str) -> "IdentifiedMode":
        """A mode of an identification file read back (``where``: its key there, for errors)."""
        label = result_label(row, where)
        number = {k: result_number(row, k, where, optional=k != "frequency_hz", positive=k != "damping_ratio")
                  for k in ("frequency_hz", "damping_ratio", "damped_frequency_hz", "fdd_peak_hz", "prior_hz")}
        std = result_number(row, "frequency_std_hz", where, optional=True)
        return cls(label=label, method=str(row.get("method", "")), source=str(row.get("source", "")),
                   frequency_std_hz=std, shape=ModeShape.from_json(row.get("shape"), f"{where}.shape"), **number)


def identified_modes_from_json(data: dict) -> tuple[IdentifiedMode, ...]:
    """The modes of an identification file read back."""
    return tuple(IdentifiedMode.from_json(r, f"modes[{i}]") for i, r in enumerate(result_rows(data, "modes")))


@dataclass(frozen=True)
class RejectedPeak:
    frequency_hz: float
    analysis: str
    reason: str
    wavelength_m: float | None = None

    def to_json(self) -> dict:
        return {k: v for k, v in self.__dict__.items() if v is not None or k != "wavelength_m"}


@dataclass(frozen=True)
class UndeterminedMode:
    """A rigid-body mode the campaign's data cannot determine, and why."""

    label: str
    reason: str

    def to_json(self) -> dict:
        return {"label": self.label, "frequency_hz": None, "reason": self.reason}


@dataclass(frozen=True)
class FRF:
    name: str
    frequency: np.ndarray  # [Hz]
    H: np.ndarray  # complex, dimensionless (acceleration / acceleration)
    coherence: np.ndarray
    description: str


@dataclass(frozen=True)
class InServiceIdentification:
    campaign: str
    modes: tuple[IdentifiedMode, ...]
    rejected_peaks: tuple[RejectedPeak, ...]
    spectral_lines: tuple[SpectralLine, ...]
    fdd: SegmentalFDD = field(repr=False)
    fdd_peaks: dict = field(repr=False)
    frfs: dict = field(repr=False)
    prior_frequencies: dict = field(default_factory=dict)
    runs: tuple = ()  # what was read: per run samples, duration, gaps, invalid samples
    psd: object = field(default=None, repr=False)  # ChannelPSDs by speed class
    undetermined: tuple[UndeterminedMode, ...] = ()
    noise_floors: tuple = ()  # NoiseFloor of each channel

    def mode(self, label: str) -> IdentifiedMode:
        for m in self.modes:
            if m.label == label:
                return m
        raise KeyError(label)

    def plot(self, path, spectra=None, *, truth: dict | None = None):
        """The identification figure at ``path`` (dotted lines at ``truth`` frequencies by
        label, when given) and the channels' spectra at ``spectra`` (default: beside it,
        ``_spectra.png``). Returns both paths (the second None when there is nothing to draw)."""
        from pathlib import Path

        from .plots import plot_identification, plot_spectra

        path = Path(path)
        spectra = path.with_name(path.stem + "_spectra.png") if spectra is None else spectra
        return plot_identification(self, path, truth=truth), plot_spectra(self, spectra)

    def to_json(self) -> dict:
        segs = self.fdd.outcomes
        return {
            "campaign": self.campaign,
            "kind": "in_service",
            "modes": [m.to_json() for m in self.modes],
            "undetermined_modes": [u.to_json() for u in self.undetermined],
            "rejected_peaks": [p.to_json() for p in self.rejected_peaks],
            "spectral_lines": [ln.to_json() for ln in self.spectral_lines],
            "fdd": {
                name: {"channels": list(r.analysis.channels), "n_fdds_summed": r.n_used,
                       "peaks": [{"frequency_hz": fr, "prominence_decades": pr}
                                 for fr, pr in self.fdd_peaks.get(name, [])],
                       "segment_speed_range_m_s": [float(r.speeds.min()), float(r.speeds.max())]}
                for name, r in self.fdd.results.items()
            },
            "segments": {"drawn": len(segs), "used": sum(o.used for o in segs),
                         "rejected": [{"run": o.segment.run_id, "start_m": o.segment.start, "reason": o.reason}
                                      for o in segs if not o.used]},
            "prior_frequencies_hz": self.prior_frequencies,
            "data": {"runs": list(self.runs), "gaps": sum(len(r["gaps"]) for r in self.runs),
                     "noise_floors": [n.to_json() for n in self.noise_floors]},
            "psd_by_speed": None if self.psd is None else self.psd.to_json(),
            "settings": {"segment_length_m": self.fdd.settings.segment_length,
                         "band_hz": list(self.fdd.settings.band), "filter_order": self.fdd.settings.order,
                         "seed": self.fdd.settings.seed},
        }


def prior_parameters(campaign: Campaign) -> CarParameters:
    """The campaign's prior knowledge as a car: prior nominals and geometry over the catalogue."""
    meta = campaign.meta
    toml = campaign.root / "campaign.toml"
    for k in sorted(set(meta.priors) - set(CAR_PARAMETER_SPECS)):
        warnings.warn(f"{toml}: prior '{k}' is not a parameter of the 2D car model; ignored "
                      f"(known: {', '.join(CAR_PARAMETER_SPECS)})", stacklevel=2)
    values = {k: p.nominal for k, p in meta.priors.items() if k in CAR_PARAMETER_SPECS}
    if "bogie_semi_spacing" in meta.geometry:
        values["L_v"] = meta.geometry["bogie_semi_spacing"]
    if "semi_wheelbase" in meta.geometry:
        values["L_b"] = meta.geometry["semi_wheelbase"]
    try:
        return INTERCITY_TRAILER.replace(**values)
    except ParameterError as e:
        raise CampaignError(f"priors and vehicle geometry do not make a valid car: {e}", path=toml,
                            key="priors / vehicle") from None


def _static_sign(pole: Pole, f: np.ndarray, H: np.ndarray) -> float:
    """Sign of a mode's quasi-static contribution, from a one-pole fit of H near the pole."""
    lam = pole.eigenvalue
    sel = np.abs(f - pole.frequency_hz) < max(2.5 * pole.damping_ratio * pole.frequency_hz, 3 * (f[1] - f[0]))
    s = 1j * 2 * np.pi * f[sel]
    # H ~ R/(s - lam) + conj(R)/(s - conj(lam)) + c0 near the pole
    A = np.column_stack([1 / (s - lam) + 1 / (s - np.conj(lam)), 1j / (s - lam) - 1j / (s - np.conj(lam)),
                         np.ones_like(s), 1j * np.ones_like(s)])
    Ar = np.vstack([A.real, A.imag])
    br = np.concatenate([H[sel].real, H[sel].imag])
    x, *_ = np.linalg.lstsq(Ar, br, rcond=None)
    R = x[0] + 1j * x[1]
    return float(np.sign(np.real(-2 * R / lam)))


def _strongest(poles: list[Pole], n: int) -> list[Pole]:
    return sorted(sorted(poles, key=lambda p: -p.residue_magnitude)[:n], key=lambda p: p.frequency_hz)


def identify_in_service(campaign: Campaign, *, settings: IdentifySettings = IdentifySettings(),
                        progress=None) -> InServiceIdentification:
    meta = campaign.meta
    toml = campaign.root / "campaign.toml"
    if meta.sampling_rate <= 2.5 * settings.fdd.band[1]:
        raise CampaignError(f"{meta.sampling_rate:g} Hz is too slow for the analysis band up to "
                            f"{settings.fdd.band[1]:g} Hz (needs more than {2.5 * settings.fdd.band[1]:g} Hz)",
                            path=toml, key="sampling.rate")
    prior = prior_parameters(campaign)
    prior_f = frequencies_by_label(undamped_modes(build_car(prior)))
    analyses = list(plan_analyses(meta))
    derived = derived_channels(meta)
    io_channels = ("rail_bounce_bogie1", "rail_bounce_bogie2_from_bogie1", "bogie1_centre_acc_z",
                   "rail_pitch_bogie1")
    gyro = [s.name for s in meta.sensors if s.body == "bogie1" and s.quantity == "angular_velocity"
            and s.direction == "pitch"]
    have_io = all(c in derived for c in io_channels) and bool(gyro)
    if have_io:
        analyses.append(Analysis(IO_ANALYSIS, io_channels + (gyro[0],), settings.io_segments, "input_output",
                                 "bogie1"))
    if not analyses:
        raise CampaignError("no vertical accelerometer on an axle box or bogie and no bogie pitch gyro: "
                            "nothing the in-service identification can use", path=toml, key="sensors")
    responses = response_channels(meta.sensors, L_v=prior.L_v, L_b=prior.L_b)
    shapes = shape_analysis(responses, max(a.n_fdds for a in analyses))  # the same segments as the rest
    analyses += [shapes] if shapes else []
    # one streaming pass: each run is read once for the FDD segments and the line windows
    plan = plan_segments(campaign, max(a.n_fdds for a in analyses), settings.fdd)
    acc = SegmentalFDDAccumulator(meta, tuple(analyses), plan, settings.fdd)
    collector = LineWindowCollector(tuple(s.name for s in meta.sensors), meta.sampling_rate, settings.lines)
    noise = WelchSums(tuple(s.name for s in meta.sensors), meta.sampling_rate,
                      round(settings.noise.segment_s * meta.sampling_rate))
    runs = []
    for path in campaign.run_paths:
        run = campaign.read_run(path.stem)
        n = acc.add_run(run)
        collector.add_run(run)
        noise.add_run(regular_run(run, meta.sampling_rate))
        runs.append(run_report(run))
        if progress:
            progress(f"{path.stem}: {n} segments, {len(collector.windows)} steady-speed windows so far")
        del run
    fdd = acc.result()
    lines = collector.classify()
    if not fdd.results:
        longest = max((r["distance_m"][1] - r["distance_m"][0]) for r in runs if r["distance_m"]) if any(
            r["distance_m"] for r in runs) else 0.0
        reasons = sorted({o.reason for o in fdd.outcomes if not o.used}) or ["no run is long enough"]
        raise CampaignError(f"no usable {settings.fdd.segment_length:g} m segment in any run (longest run "
                            f"{longest:.0f} m; {'; '.join(reasons)})", path=campaign.root)
    have_io = have_io and IO_ANALYSIS in fdd.results
    peaks = {}
    for name, r in fdd.results.items():
        if name in (IO_ANALYSIS, SHAPE_ANALYSIS):
            continue
        peaks[name] = fdd_peaks(r.frequency, r.singular_values[0], settings.peak_prominence)

    def fdd_estimate(analysis_role: str, band) -> tuple[float, float] | None:
        cands = [(fr, pr) for name, r in fdd.results.items() if r.analysis.role == analysis_role
                 for fr, pr in peaks.get(name, []) if band[0] <= fr <= band[1]]
        return max(cands, key=lambda x: x[1]) if cands else None

    modes: list[IdentifiedMode] = []
    frfs: dict = {}
    why_not: dict[str, str] = {}
    if have_io:
        r = fdd.results[IO_ANALYSIS]
        fitted, frfs, why_not = _fit_input_output(r.frequency, r.csd, settings, prior_f)
        # delete-one-journey jackknife: refit without each journey's segments. Journeys differ
        # in speed mix and noise, the campaign-level variability that segment-level spreads
        # (all sharing the same journeys) miss: on seed 4 interleaved batch means said 0.08 %
        # for a carbody-bounce error of 1.84 %.
        spread: dict[str, list[float]] = {}
        parts = r.csd_parts.values() if len(r.csd_parts) >= 3 else ()  # a jackknife needs 3 journeys
        for part in parts:
            part_fit, _, _ = _fit_input_output(r.frequency, r.csd - part, settings, prior_f)
            for lbl, (p, _src) in part_fit.items():
                spread.setdefault(lbl, []).append(p.frequency_hz)
        for lbl in RIGID_LABELS:
            if lbl not in fitted:
                continue
            p, src = fitted[lbl]
            role = "bogie_pitch" if lbl == "bogie_pitch" else "bogie_bounce"
            near = [fr for name, pk in peaks.items() for fr, _ in pk
                    if abs(fr / p.frequency_hz - 1) < 0.1 and fdd.results[name].analysis.role == role]
            fdd_hz = min(near, key=lambda fr: abs(fr - p.frequency_hz)) if near else None
            est = np.array(spread.get(lbl, []))
            n = est.size  # jackknife standard error: sqrt((n - 1) / n * sum (x_i - mean)^2)
            std = float(np.sqrt((n - 1) / n * np.sum((est - est.mean()) ** 2))) if n >= 3 else None
            modes.append(IdentifiedMode(lbl, p.frequency_hz, p.damping_ratio, p.damped_frequency_hz,
                                        "input_output_fit", src, fdd_hz, prior_f.get(lbl), std))
    # what the input-output fit could not give (or, without axle boxes, everything) comes
    # from the seed-faithful FDD peaks, labelled by the prior model's frequency order
    # (a peak within 5 % of a mode already identified is that mode, as in _rejected)
    missing = [lbl for lbl in RIGID_LABELS if lbl not in {m.label for m in modes}]
    est = {"bogie_pitch": fdd_estimate("bogie_pitch", settings.bogie_band),
           "bogie_bounce": fdd_estimate("bogie_bounce", settings.bogie_band)}
    cands = sorted([(fr, pr) for name, r in fdd.results.items() if r.analysis.role == "bogie_bounce"
                    for fr, pr in peaks.get(name, []) if settings.carbody_band[0] <= fr <= settings.carbody_band[1]],
                   key=lambda x: -x[1])[:2]
    order = [lbl for lbl in sorted(("carbody_bounce", "carbody_pitch"), key=lambda k: prior_f[k]) if lbl in missing]
    if len(order) == 2:  # frequency order labels a pair only when neither was fitted
        for lbl, c in zip(order, sorted(cands)):
            est[lbl] = c
    est = {lbl: e for lbl, e in est.items()
           if e and not any(abs(e[0] / m.frequency_hz - 1) < 0.05 for m in modes)}
    undetermined = []
    for lbl in missing:
        if est.get(lbl):
            modes.append(IdentifiedMode(lbl, est[lbl][0], None, None, "fdd_peak", "fdd", est[lbl][0],
                                        prior_f.get(lbl)))
        else:
            reason = why_not.get(lbl, "no input-output fit (no axle-box sensors or geometry)" if not have_io
                                 else "the input-output fit found no pole for it")
            undetermined.append(UndeterminedMode(lbl, f"{reason}; no FDD peak stands in for it"))
    ranges = prior_frequency_ranges(campaign, prior)
    damping = prior_damping_ranges(campaign, prior)
    for m in list(modes):
        why = (outside(m.label, m.frequency_hz, ranges) or damping_outside(m.label, m.damping_ratio, damping)
               or _no_peak(m) or _unsteady(m, settings))
        if why:
            modes.remove(m)
            undetermined.append(UndeterminedMode(m.label, why))
    modes, undetermined = unpaired_carbody(modes, undetermined)
    if SHAPE_ANALYSIS in fdd.results:
        shaped = fdd.results[SHAPE_ANALYSIS]
        modes = [replace(m, shape=mode_shape(shaped, responses, m.frequency_hz)) for m in modes]
    modes.sort(key=lambda m: RIGID_LABELS.index(m.label))
    undetermined.sort(key=lambda u: RIGID_LABELS.index(u.label))
    rejected = _rejected(peaks, fdd, modes, lines)
    units = {s.name: SI_UNIT[s.quantity] for s in meta.sensors}
    psd = collector.psd_by_speed(units=units)
    band = noise_band(settings.fdd.band[1], meta.sampling_rate, settings.noise)
    floors = () if band is None else tuple(noise.floors(units, band, settings.noise.percentile))
    return InServiceIdentification(str(campaign.root), tuple(modes), tuple(rejected), tuple(lines), fdd, peaks,
                                   frfs, {k: float(v) for k, v in prior_f.items()}, tuple(runs), psd,
                                   tuple(undetermined), floors)


def _no_peak(m: IdentifiedMode) -> str | None:
    if m.damping_ratio is None or m.damping_ratio <= NO_PEAK_DAMPING:
        return None
    return (f"the fitted pole at {m.frequency_hz:.3g} Hz is damped {m.damping_ratio:.2f}, above "
            f"{NO_PEAK_DAMPING:.2f}: its response has no resonance peak to fix the frequency")


def _unsteady(m: IdentifiedMode, settings: IdentifySettings) -> str | None:
    limit = settings.max_relative_std[0 if m.label.startswith("carbody") else 1]
    if m.frequency_std_hz is None or m.frequency_std_hz <= limit * m.frequency_hz:
        return None
    return (f"its frequency ({m.frequency_hz:.3g} Hz) varies with the journeys: its jackknife standard error, "
            f"{100 * m.frequency_std_hz / m.frequency_hz:.2f} %, exceeds {100 * limit:.3g} %")


def unpaired_carbody(modes: list[IdentifiedMode], undetermined: list[UndeterminedMode]):
    """(modes, undetermined) with a carbody mode that lost its partner made undetermined.

    Both carbody modes come from one fit of the trailing-rail response, two poles in the
    carbody band. When only one of them stands (the other not fitted, or fitted outside the
    range the priors allow, i.e. the fit spent a pole on another resonance), the one left
    stood in for two heavily damped modes a few tenths of a hertz apart, and its frequency
    is neither's: on the independent truth such a pole fell between the two (carbody pitch
    -15 % and -18 % on two vehicles)."""
    left = [m for m in modes if m.source == "trailing_rail"]
    if len(left) != 1:
        return modes, undetermined
    m = left[0]
    other = "carbody_pitch" if m.label == "carbody_bounce" else "carbody_bounce"
    why = next((u.reason for u in undetermined if u.label == other), "no pole")
    reason = (f"the trailing-rail fit resolved one carbody pole ({m.frequency_hz:.3g} Hz), not two ({other}: {why}); "
              "one pole standing in for both modes is neither's frequency")
    return [x for x in modes if x is not m], [*undetermined, UndeterminedMode(m.label, reason)]


def _fit_input_output(f: np.ndarray, G: np.ndarray, settings: IdentifySettings, prior_f: dict):
    """Modes from the input-output CSD matrix (channels: rail bounce under bogie 1, the same
    rail under bogie 2, bogie-1 centre acceleration, rail pitch, bogie-1 pitch rate).
    Returns ({label: (Pole, source)}, {name: FRF}, {label: why it was not fitted})."""
    # Bins are weighted by the inverse standard deviation of the two-input estimate, which
    # grows as 1 / sqrt(1 - gamma_ab^2): below ~0.6 Hz the delay 2 L_v / v turns the phase
    # too little across speeds to tell the two rails apart (measured on seed 1: carbody
    # bounce -1.96 % unweighted, -0.62 % weighted, noise-free data).
    separability = _separability(G, 0, 1)
    in_band = lambda band: (f >= band[0]) & (f <= band[1])  # noqa: E731
    sep_cb = float(np.median(separability[in_band(settings.carbody_band)]))
    sep_bb = float(np.median(separability[in_band(settings.bogie_band)]))
    why_not: dict[str, str] = {}
    H, coh = h1(G, [2], [0, 1])
    if sep_bb < settings.min_separability:
        # One speed: the trailing rail is the leading rail's delayed copy and the two-input
        # solve is ill-posed. In the bogie band the trailing rail reaches bogie 1 only through
        # the carbody, far above its modes, so the bogie's FRF to its own rail alone holds.
        H, coh = h1(G, [2], [0])
    # The bounce FRF takes the rail pitch as an input too: a sensor's gain error of a few per
    # cent mixes the bogie's pitch into its centre acceleration (an accelerometer less a
    # gyro's share), and with the rail bounce alone the pitch response correlated with it
    # reads as part of the bounce FRF. Rail bounce and pitch are two filters of one rail,
    # told apart only by the campaign's spread of speeds: bins are weighted by their
    # separability, and where it is too low over the band the one-input estimate stands.
    sep_bp = _separability(G, 0, 3)
    trailing = [1] if H.shape[2] == 2 else []
    Hb, cohb, w_bp = H[:, :, :1], coh, 1.0
    if float(np.median(sep_bp[in_band(settings.bogie_band)])) >= settings.min_separability:
        Hb, cohb = h1(G, [2], [0, 3] + trailing)
        w_bp = np.sqrt(sep_bp)
    Hp, cohp = h1(G, [4], [3])
    Hp_acc = Hp[:, 0, 0] * (1j * 2 * np.pi * f)  # pitch rate -> pitch acceleration
    frfs = {
        "own_rail": FRF("own_rail", f, Hb[:, 0, 0], cohb[:, 0],
                        "bogie-1 centre acceleration / rail acceleration under bogie 1"),
        "pitch": FRF("pitch", f, Hp_acc, cohp[:, 0], "bogie-1 pitch acceleration / rail pitch acceleration under bogie 1"),
    }
    if H.shape[2] == 2:
        frfs["trailing_rail"] = FRF("trailing_rail", f, H[:, 0, 1], coh[:, 0],
                                    "bogie-1 centre acceleration / rail acceleration under bogie 2 (via carbody)")
    gate = lambda c: (c >= settings.min_coherence).astype(float)  # noqa: E731
    w2 = gate(coh[:, 0]) * np.sqrt(separability)
    if sep_cb < settings.min_separability:
        cb = []
        reason = (f"the rails under the two bogies cannot be told apart (median separability {sep_cb:.3f} over "
                  f"{settings.carbody_band[0]:g}-{settings.carbody_band[1]:g} Hz, "
                  f"{settings.min_separability:g} needed): the segments' speeds are too alike")
        why_not = {"carbody_bounce": reason, "carbody_pitch": reason}
    else:
        cb = _strongest(fit_poles(f, H[:, 0, 1], settings.carbody_band, 2 + settings.extra_poles, weights=w2), 2)
    signs = {p: _static_sign(p, f, H[:, 0, 1]) for p in cb}
    bounce = [p for p in cb if signs[p] > 0]
    pitch = [p for p in cb if signs[p] < 0]
    if len(bounce) == 1 and len(pitch) == 1:
        cb_labels = {bounce[0]: "carbody_bounce", pitch[0]: "carbody_pitch"}
    else:  # signs inconclusive: each pole takes the nearest prior frequency, one pole per label
        pairs = sorted((abs(np.log(p.frequency_hz / prior_f[lbl])), i, lbl) for i, p in enumerate(cb)
                       for lbl in ("carbody_bounce", "carbody_pitch"))
        cb_labels = {}
        for _, i, lbl in pairs:
            if cb[i] not in cb_labels and lbl not in cb_labels.values():
                cb_labels[cb[i]] = lbl
    fitted = {lbl: (p, "trailing_rail") for p, lbl in cb_labels.items()}
    w_bb = gate(cohb[:, 0]) * w_bp * (np.sqrt(separability) if trailing else 1.0)
    for lbl, H_b, weights, source in (("bogie_bounce", Hb[:, 0, 0], w_bb, "own_rail"),
                                      ("bogie_pitch", Hp_acc, gate(cohp[:, 0]), "pitch")):
        band = (prior_f[lbl] / settings.bogie_band_factor, prior_f[lbl] * settings.bogie_band_factor)
        pole, why = _stable_bogie_pole(f, H_b, weights, band, settings)
        if pole is not None:
            fitted[lbl] = (pole, source)
        elif why:
            why_not[lbl] = why
    return fitted, frfs, why_not


def _separability(G: np.ndarray, a: int, b: int) -> np.ndarray:
    """1 - |coherence of channels a and b|^2 per bin: the share of b that is not a filter of a."""
    return np.clip(1 - np.abs(G[:, a, b]) ** 2 / np.real(G[:, a, a] * G[:, b, b]), 0.0, 1.0)


def _stable_bogie_pole(f: np.ndarray, H: np.ndarray, weights: np.ndarray, band: tuple[float, float],
                       settings: IdentifySettings):
    """(pole, None) of the strongest pole in ``band`` [Hz], from the lowest fit order at
    which it moves by less than ``settings.order_stability`` at the next order; (None, why)
    when it never settles, (None, None) when no order finds one. A heavily damped pole is
    broad, and with too few poles it is pulled towards a neighbouring mode (a carbody
    bending 40 % above a bogie bounce damped 0.45 moved it 7 % on an exact FRF)."""
    first = 1 + settings.extra_poles
    found = []
    for n in range(first, first + settings.max_extra_order + 1):
        best = _strongest(fit_poles(f, H, band, n, weights=weights), 1)
        found.append(best[0] if best else None)
        a, b = found[-2:] if len(found) > 1 else (None, None)
        if a is not None and b is not None and abs(b.frequency_hz / a.frequency_hz - 1) < settings.order_stability:
            return a, None
    hz = [p.frequency_hz for p in found if p is not None]
    if not hz:
        return None, None
    return None, (f"its pole moved with the fit's order ({', '.join(f'{x:.3g}' for x in hz)} Hz with "
                  f"{first}-{first + settings.max_extra_order} poles), more than {settings.order_stability:.0%} "
                  "from one order to the next: the FRF holds more than the fit resolves")


def _rejected(peaks, fdd: SegmentalFDD, modes, lines) -> list[RejectedPeak]:
    out = []
    for name, pk in peaks.items():
        role = fdd.results[name].analysis.role
        for fr, _ in pk:
            match = [m for m in modes if abs(fr / m.frequency_hz - 1) < 0.05]
            if match and role != "axle_bounce":
                continue  # the FDD's view of an identified mode
            if role == "axle_bounce":
                reason = ("axle-box channels measure the rail's own motion (wheelsets on the rail): a peak here "
                          "is track content, not an axle mode")
                if match:
                    reason += f"; coincides with {match[0].label} seen through the primary suspension"
            else:
                reason = "not a rigid-body mode of the 2D car: no identified mode within 5 %"
            out.append(RejectedPeak(float(fr), name, reason))
    for ln in lines:
        if ln.kind == "speed_dependent":
            out.append(RejectedPeak(float(ln.frequency_hz), "spectral_lines",
                                    f"speed-dependent excitation: {ln.interpretation}", ln.wavelength_m))
        elif ln.kind == "speed_independent" and len(ln.channels) == 1:
            out.append(RejectedPeak(float(ln.frequency_hz), "spectral_lines",
                                    f"non-vehicle tone: {ln.interpretation}"))
    return out
