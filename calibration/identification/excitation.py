"""Modal identification of a stationary excitation test (RTRI seed, section 3.2).

From the force channel and the accelerometers of every run: H1 FRFs with coherence over
all gap-free blocks (:func:`~calibration.identification.ema.frf_h1_records`), the p-LSCF
stabilisation diagram in the analysis band, physical modes as clusters of poles alike in
frequency and shape across orders, with their complex shapes (the fraction's numerators
at the pole: for one force input, the residues), and peak picking beside them as the
baseline. Reported as rejected: poles too heavily damped to be structural, pole clusters
too weak to be a mode (found in fewer than ``min_fraction`` of the orders: e.g. a pair
closer than the test can resolve), and FRF peaks with no stable pole. Pole clusters whose
shape is no real mode's (phase collinearity under 0.7: the fraction's computational poles
near the band's edges) are not modes and not listed. A mode seen at one channel alone is a
resonance of that measurement point (a sensor on a resilient bracket, a loose mount), not
of the carbody: it is reported as a :class:`LocalResonance`, not as a mode to calibrate
to. The result does not depend on the BLAS thread count or the CPU's kernels beyond
round-off (:func:`ema.lscf`).

Each mode carries standard errors of its frequency and damping ratio from a delete-one-group
jackknife over the Welch segments (:mod:`.ema_jackknife`), and each channel a noise floor
(:mod:`calibration.signals.noise_floor`): the responses' power not coherent with the force.

Shapes are not re-fitted by LSFD over the band: with a dozen bogie and local panel modes
in 6-24 Hz that the floor grid barely sees, an LSFD restricted to the selected poles
smears the missing ones into the residues (MAC 0.3-0.6 against the truth on the synthetic
campaigns), while the numerator shapes match it with MAC >= 0.99.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..data.campaign import Campaign
from .. import checks
from ..data.errors import InputError
from ..data.outputs import result_label, result_number, result_rows
from ..data.units import SI_UNIT
from ..signals.modal import mac_matrix
from ..signals.noise_floor import (NON_COHERENT, SPECTRAL_FLOOR, NoiseFloor, NoiseFloorSettings, non_coherent_floor,
                                   spectral_floor)
from . import ema
from .data_quality import noise_band
from .ema_jackknife import GroupSpectra, ModeSpread, group_spectra, jackknife_modes


@dataclass(frozen=True)
class ExcitationIdentifySettings:
    band: tuple[float, float] = (6.0, 24.0)  # [Hz] analysis band, inside the force band
    nperseg: int = 4096  # 20.5 s at 200 Hz: 0.049 Hz lines
    orders: tuple[int, ...] = tuple(range(16, 97, 4))
    min_fraction: float = 0.4  # of the orders a mode's pole must be found (frequency-stable) in
    # Poles closer in frequency than the larger of cluster_tol and bandwidth_fraction x their
    # damping ratio (relative), and at least cluster_mac alike in shape, are one mode; the
    # values come from the pole scatter of a close pair (docs/methods/identification-excitation.md).
    cluster_tol: float = 0.002
    bandwidth_fraction: float = 0.25
    cluster_mac: float = 0.8
    max_damping: float = 0.10  # poles more damped than this are not structural modes here
    peak_separation_hz: float = 0.3
    # A mode with at least local_share of its shape's energy (|shape|^2) on one channel, in a
    # test of at least local_min_channels channels, is that measurement point's resonance: a
    # carbody mode below 30 Hz moves the floor points around a sensor with it. On 50 bench
    # campaigns carbody modes put at most 0.73 on one of 27 channels, a bracket's resonance
    # 0.93-1.00 (docs/methods/identification-excitation.md).
    local_share: float = 0.9
    local_min_channels: int = 6
    # Groups of contiguous Welch segments of the delete-one-group jackknife that gives each
    # mode's standard errors (each group costs one more identification, ~0.1 s)
    jackknife_groups: int = 10
    # whether to run that jackknife: a step that reads the modes but not their errors (the
    # diagnosis's splits, validation's re-identification) is spared its identifications
    standard_errors: bool = True
    noise: NoiseFloorSettings = NoiseFloorSettings()  # the percentile, and the force's band above the analysis band

    def __post_init__(self):
        checks.increasing(self, "band", low=0.0)
        checks.whole(self, "nperseg", minimum=16)
        if not self.orders or any(isinstance(o, bool) or not isinstance(o, int) or o < 2 for o in self.orders) \
                or list(self.orders) != sorted(set(self.orders)):
            raise ValueError(f"ExcitationIdentifySettings.orders must be increasing integers >= 2, got {self.orders!r}")
        checks.fraction(self, "min_fraction", "cluster_mac", "local_share", closed=True)
        checks.whole(self, "local_min_channels", minimum=2)
        checks.whole(self, "jackknife_groups", minimum=3)
        checks.positive(self, "cluster_tol", "bandwidth_fraction", "max_damping", "peak_separation_hz")


@dataclass(frozen=True, eq=False)
class ExcitationMode:
    label: str
    frequency_hz: float
    damping_ratio: float | None
    shape: np.ndarray  # (n_sensors,) complex, largest entry 1
    n_stable: int
    peak_picking_hz: float | None  # the baseline's nearest peak, if within 1 %
    frequency_std_hz: float | None = None  # delete-one-group jackknife standard error [Hz]
    damping_std: float | None = None  # the same of the damping ratio [-]
    replicates: int | None = None  # jackknife replicates that found the mode

    def to_json(self) -> dict:
        return {"label": self.label, "frequency_hz": self.frequency_hz, "damping_ratio": self.damping_ratio,
                "frequency_std_hz": self.frequency_std_hz, "damping_std": self.damping_std,
                "jackknife_replicates": self.replicates,
                "n_stable": self.n_stable, "peak_picking_hz": self.peak_picking_hz,
                "shape_real": self.shape.real.tolist(), "shape_imag": self.shape.imag.tolist()}

    @classmethod
    def from_json(cls, row: dict, where: str, n_sensors: int) -> "ExcitationMode":
        """A mode of an identification file read back (``where``: its key there, for errors)."""
        label = result_label(row, where)
        try:
            shape = np.asarray(row.get("shape_real"), float) + 1j * np.asarray(row.get("shape_imag"), float)
        except (TypeError, ValueError):
            shape = np.array([])
        if shape.shape != (n_sensors,) or not np.all(np.isfinite(shape)) or not np.any(shape):
            raise InputError(f"shape_real and shape_imag must be {n_sensors} finite numbers (one per sensor), "
                             "not all zero", key=where)
        n_stable, replicates = row.get("n_stable", 0), row.get("jackknife_replicates")
        return cls(label=label, frequency_hz=result_number(row, "frequency_hz", where, positive=True),
                   damping_ratio=result_number(row, "damping_ratio", where, optional=True), shape=shape,
                   n_stable=n_stable if isinstance(n_stable, int) else 0,
                   peak_picking_hz=result_number(row, "peak_picking_hz", where, optional=True),
                   frequency_std_hz=result_number(row, "frequency_std_hz", where, optional=True),
                   damping_std=result_number(row, "damping_std", where, optional=True),
                   replicates=replicates if isinstance(replicates, int) and not isinstance(replicates, bool) else None)


@dataclass(frozen=True)
class LocalResonance:
    """A stable pole whose shape lies on one channel: ``share`` of its energy (|shape|^2)."""

    frequency_hz: float
    damping_ratio: float | None
    channel: str
    share: float

    def to_json(self) -> dict:
        """The entry of ``rejected_peaks`` (docs/cli.md: ``frequency_hz`` and ``reason``)."""
        return {"frequency_hz": self.frequency_hz, "channel": self.channel, "share": self.share,
                "damping_ratio": self.damping_ratio,
                "reason": f"{self.share:.0%} of its shape at {self.channel} alone: a resonance of that measurement "
                          "point (its mounting, e.g. a resilient bracket), not a mode of the carbody"}


def local_channel(shape: np.ndarray, settings: ExcitationIdentifySettings) -> tuple[int, float] | None:
    """(channel index, share) when ``shape`` puts at least ``settings.local_share`` of its
    energy on one channel of at least ``settings.local_min_channels``, else None."""
    energy = np.abs(np.asarray(shape)) ** 2
    if energy.size < settings.local_min_channels or not energy.sum() > 0:
        return None
    k = int(np.argmax(energy))
    share = float(energy[k] / energy.sum())
    return (k, share) if share >= settings.local_share else None


@dataclass(frozen=True)
class IdentifiedShapes:
    """What calibration takes of an excitation test's identification: the sensors and the
    modes with their shapes there (an :class:`ExcitationIdentification`, or an identification
    file read back by :meth:`from_json`)."""

    sensors: tuple[str, ...]
    modes: tuple[ExcitationMode, ...]

    @classmethod
    def from_json(cls, data: dict) -> "IdentifiedShapes":
        sensors = data.get("sensors")
        if not isinstance(sensors, list) or not sensors or not all(isinstance(n, str) for n in sensors):
            raise InputError("expected the list of sensor names the shapes are given at", key="sensors")
        return cls(tuple(sensors), tuple(ExcitationMode.from_json(r, f"modes[{i}]", len(sensors))
                                         for i, r in enumerate(result_rows(data, "modes"))))


@dataclass(frozen=True, eq=False)
class ExcitationIdentification:
    sensors: tuple[str, ...]
    modes: tuple[ExcitationMode, ...]
    rejected: tuple[dict, ...]
    frf: ema.FRFEstimate
    stabilisation: ema.Stabilisation
    records: int
    settings: ExcitationIdentifySettings = field(repr=False, default_factory=ExcitationIdentifySettings)
    local: tuple[LocalResonance, ...] = ()  # resonances of one measurement point (also in ``rejected``)
    noise_floors: tuple[NoiseFloor, ...] = ()
    jackknife_groups: int = 0  # groups of Welch segments the standard errors come from (0: none)

    def plot(self, path, mac=None):
        """The stabilisation diagram at ``path`` and the modes' auto-MAC at ``mac`` (default:
        beside it, ``_mac.png``). Returns both paths."""
        from pathlib import Path

        from .plots import plot_mac, plot_stabilisation

        path = Path(path)
        mac = path.with_name(path.stem + "_mac.png") if mac is None else Path(mac)
        plot_stabilisation(self.stabilisation, self.frf.frequency, self.frf.H, path, modes=list(self.modes))
        labels = [f"{m.label} {m.frequency_hz:.2f}" for m in self.modes]
        plot_mac(self.auto_mac(), labels, labels, mac)
        return path, mac

    def auto_mac(self) -> np.ndarray:
        if not self.modes:
            return np.zeros((0, 0))
        shapes = np.column_stack([m.shape for m in self.modes])
        return mac_matrix(shapes, shapes)

    def to_json(self) -> dict:
        return {
            "kind": "stationary_excitation",
            "method": "H1 + p-LSCF stabilisation diagram (shapes: numerators at the poles); peak picking as baseline",
            "band_hz": list(self.settings.band),
            "sensors": list(self.sensors),
            "modes": [m.to_json() for m in self.modes],
            "rejected_peaks": list(self.rejected),
            "auto_mac": self.auto_mac().tolist(),
            "data": {"noise_floors": [n.to_json() for n in self.noise_floors]},
            "uncertainty": {"method": "delete-one-group jackknife: the Welch segments in time order split into "
                                      "contiguous groups, each left out in turn, H1 and p-LSCF identification repeated "
                                      "and the modes paired by frequency and MAC; a mode's standard errors come from "
                                      "the replicates that found it (jackknife_replicates), none from fewer than 3",
                            "groups": self.jackknife_groups},
            "frf": {"welch_segments": self.frf.n_averages, "records": self.records,
                    "resolution_hz": float(self.frf.frequency[1] - self.frf.frequency[0]),
                    "median_coherence_in_band": float(np.median(self.frf.coherence[
                        (self.frf.frequency >= self.settings.band[0])
                        & (self.frf.frequency <= self.settings.band[1])]))},
        }


def _records(campaign: Campaign, force: str, sensors: tuple[str, ...]):
    """(force, responses) of every gap-free stretch where all channels are valid."""
    for run in campaign.iter_runs():
        ok = np.all([run.valid[c] for c in (force,) + sensors], axis=0)
        for a, b in run.blocks:
            good = ok[a:b]
            edges = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(int), [0]])))
            for s, e in zip(edges[::2], edges[1::2]):
                yield (run.channels[force][a + s:a + e],
                       np.column_stack([run.channels[c][a + s:a + e] for c in sensors]))


def identify_excitation(campaign: Campaign, settings: ExcitationIdentifySettings = ExcitationIdentifySettings()
                        ) -> ExcitationIdentification:
    meta = campaign.meta
    toml = campaign.root / "campaign.toml"
    if meta.excitation is None:
        raise InputError("a stationary_excitation campaign needs [excitation] sensor = ...", path=toml,
                         key="excitation")
    force = meta.excitation.sensor
    sensors = tuple(s.name for s in meta.sensors if s.quantity == "acceleration")
    if not sensors:
        raise InputError("no acceleration sensor to identify modes from", path=toml, key="sensors")
    if not 0 < settings.band[0] < settings.band[1] < meta.sampling_rate / 2:
        raise InputError(f"analysis band {settings.band} Hz must lie below the Nyquist frequency "
                         f"{meta.sampling_rate / 2} Hz", path=toml, key="sampling.rate")
    records = list(_records(campaign, force, sensors))
    try:
        frf = ema.frf_h1_records(records, meta.sampling_rate, settings.nperseg)
    except ValueError as exc:
        raise InputError(f"{exc} (runs, after removing gaps and invalid samples)", path=campaign.root / "runs")
    stab = ema.lscf(frf.frequency, frf.H, settings.band, settings.orders, max_damping=1.0)
    n_orders = len(stab.orders)
    needed = settings.min_fraction * n_orders
    clusters = stab.select_modes(min_fraction=0.5 * settings.min_fraction, cluster_tol=settings.cluster_tol,
                                 cluster_mac=settings.cluster_mac,
                                 bandwidth_fraction=settings.bandwidth_fraction)  # the weak ones too, to report them
    candidates = [m for m in clusters if m.n_stable >= needed]
    weak = [{"frequency_hz": m.frequency_hz, "reason": f"poles alike in frequency and shape in only {m.n_stable} "
             f"of {n_orders} model orders (a mode needs {int(np.ceil(needed))}): not resolved by this test"}
            for m in clusters if m.n_stable < needed and 0 < m.damping_ratio <= settings.max_damping]
    keep = [m for m in candidates if m.damping_ratio is not None and 0 < m.damping_ratio <= settings.max_damping]
    rejected = [{"frequency_hz": m.frequency_hz, "reason": f"damping ratio {m.damping_ratio:.3f} above "
                 f"{settings.max_damping}: not a structural mode of the carbody"} for m in candidates if m not in keep]
    rejected += weak
    peaks = ema.peak_picking(frf.frequency, frf.H, settings.band, settings.peak_separation_hz,
                             quantity="acceleration")
    at_one = [local_channel(m.shape, settings) for m in keep]
    local = [LocalResonance(float(m.frequency_hz), float(m.damping_ratio), sensors[one[0]], one[1])
             for m, one in zip(keep, at_one) if one is not None]
    keep = [m for m, one in zip(keep, at_one) if one is None]
    rejected += [r.to_json() for r in local]
    spectra = group_spectra(records, meta.sampling_rate, settings.nperseg, settings.jackknife_groups)
    spread = mode_standard_errors(spectra, keep, settings)
    modes = []
    for k, (m, sd) in enumerate(zip(keep, spread)):
        near = [p.frequency_hz for p in peaks if abs(p.frequency_hz / m.frequency_hz - 1) < 0.01]
        nearest = float(min(near, key=lambda x: abs(x - m.frequency_hz))) if near else None
        modes.append(ExcitationMode(f"mode_{k + 1}", float(m.frequency_hz), float(m.damping_ratio), m.shape,
                                    int(m.n_stable), nearest, sd.frequency_std_hz, sd.damping_std, sd.replicates))
    poles = [m.frequency_hz for m in keep] + [r.frequency_hz for r in local]
    for p in peaks:
        if not any(abs(p.frequency_hz / hz - 1) < 0.01 for hz in poles):
            rejected.append({"frequency_hz": float(p.frequency_hz),
                             "reason": "peak in the FRF sum with no stable pole (not a clear mode)"})
    units = {s.name: SI_UNIT[s.quantity] for s in meta.sensors}
    floors = noise_floors(spectra, force, sensors, units, settings, meta.sampling_rate)
    return ExcitationIdentification(sensors, tuple(modes), tuple(rejected), frf, stab, len(records), settings,
                                    tuple(local), floors,
                                    spectra.counts.size if spectra.counts.size >= 3 and settings.standard_errors else 0)


def find_modes(frequency: np.ndarray, H: np.ndarray, settings: ExcitationIdentifySettings) -> list[ema.Mode]:
    """The modes of an FRF ``H`` (n_f, n_out) at ``frequency`` [Hz] as the identification
    keeps them: clusters of p-LSCF poles in enough orders, damped no more than a structure."""
    stab = ema.lscf(frequency, H, settings.band, settings.orders, max_damping=1.0)
    found = stab.select_modes(min_fraction=settings.min_fraction, cluster_tol=settings.cluster_tol,
                              cluster_mac=settings.cluster_mac, bandwidth_fraction=settings.bandwidth_fraction)
    return [m for m in found if m.damping_ratio is not None and 0 < m.damping_ratio <= settings.max_damping]


def mode_standard_errors(spectra: GroupSpectra, modes: list[ema.Mode], settings: ExcitationIdentifySettings
                         ) -> list[ModeSpread]:
    """Each of ``modes``' standard errors by the delete-one-group jackknife over ``spectra``
    (:mod:`.ema_jackknife`), each replicate identified by :func:`find_modes`."""
    if spectra.counts.size < 3 or not settings.standard_errors:
        return [ModeSpread(None, None, 0, int(spectra.counts.size))] * len(modes)
    return jackknife_modes(spectra, modes, lambda H: find_modes(spectra.frequency, H, settings),
                           cluster_tol=settings.cluster_tol, bandwidth_fraction=settings.bandwidth_fraction,
                           cluster_mac=settings.cluster_mac)


def noise_floors(spectra: GroupSpectra, force: str, sensors: tuple[str, ...], units: dict,
                 settings: ExcitationIdentifySettings, fs: float) -> tuple[NoiseFloor, ...]:
    """The responses' noise floors from their power not coherent with the force over the
    analysis band, and the force's (which nothing measured is coherent with but itself) as
    the spectral floor above the band, where the vehicle's modes are no longer analysed."""
    Gff, Gfy, Gyy, n = spectra.average()
    band = (float(settings.band[0]), float(settings.band[1]))
    out = []
    above = noise_band(settings.band[1], fs, settings.noise, resolution_hz=fs / settings.nperseg)
    if above is not None:
        psd = float(spectral_floor(spectra.frequency, Gff, above, n, settings.noise.percentile))
        out.append(NoiseFloor(force, units.get(force, "N"), psd, above, SPECTRAL_FLOOR, n))
    floors = non_coherent_floor(spectra.frequency, Gff, Gfy, Gyy, band, n, settings.noise.percentile)
    out += [NoiseFloor(name, units.get(name, ""), float(p), band, NON_COHERENT, n) for name, p in zip(sensors, floors)]
    return tuple(out)
