"""What the in-service diagnosis reads from a campaign: gap-free records of rail input,
response and axle-box consistency, and their band-averaged spectral statistics.

The model's input is measured: wheelsets on a rigid rail move with the rail, so the
vertical axle-box accelerations of a wheelset (the mean of its left and right boxes) are
the rail acceleration under it. The trailing bogie's wheelsets, when they carry no
sensors, run over the same rail 2 L_v later in distance; their input is the leading
wheelset's (the round one's, when the diagnosis found the other out of round: its axle
boxes carry its polygon), delayed by distance (the distance comes from integrating the speed signal,
whose short-term error is far smaller than GPS distance's) and scaled by the squared speed
ratio (a rail curvature z'' gives an acceleration v^2 z''). Every other sensor (bogie and
carbody accelerometers, pitch gyros) is a response the model predicts.

The *consistency* channel compares the two wheelsets of the leading bogie: wheelset 2
runs over the rail wheelset 1 ran over 2 L_b earlier, so on a rigid rail with round
wheels ``axle2(t) - (v(t)/v(t*))^2 axle1(t*)`` with d(t*) = d(t) - 2 L_b is noise. What
one wheelset carries and the other does not (an out-of-round wheel) stays in it.

Records are resampled to ``fs`` (200 Hz by default) and cut into segments of
``segment_s`` seconds (a Hann ``window`` by default) overlapping by ``overlap_fraction``.
Not rectangular segments: their leakage falls off only as 1/f^2, and the axle boxes carry
metres per second squared of sleeper and weld content where the two wheelsets are
unrelated, so a rectangular window moves that content into the lowest bands of the
wheelsets' difference, where the model's gain (a bogie's pitch rate per unit rail
acceleration goes as 1/f) is largest: the prediction then holds power the response does
not, and the residual reads as coherent with the input (the false alarms this caused are
in docs/CHANGELOG.md, "Hann windows"). The taper also softens the edges of each segment,
where the response to input before the segment is not predicted. Each segment stands for
its hop in the seconds kept, so a cell's seconds are its data's (a record shorter than a
segment plus a hop counts for a little less). Cross-spectra of all channels are summed
over bins into bands of relative width ``rel_width`` (and at least ``min_bins`` bins): a
linear model's residual energy is then a quadratic form in these sums, so fitting a model
costs a few hundred small matrix products, whatever the campaign's length. Sums are kept
per (run, speed bin) so held-out runs and speed-frequency maps come from the same
statistics.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np
import scipy.interpolate
import scipy.signal

from ...data.campaign import Campaign, Sensor
from ...data.errors import CampaignError
from ...models.car2d import Output


@dataclass(frozen=True, kw_only=True)
class RecordSettings:
    """How records are read and turned into band statistics (scipy.signal's meanings)."""

    fs: float = 200.0  # [Hz] analysis sampling rate
    segment_s: float = 60.0  # [s] length of one FFT segment
    window: str = "hann"  # scipy.signal.get_window name of the segments' taper
    overlap_fraction: float = 0.5  # share of a segment overlapping the next, in [0, 1)
    band: tuple[float, float] = (0.3, 60.0)  # [Hz] analysis band
    rel_width: float = 0.012  # band width relative to its centre frequency
    min_bins: int = 2  # least periodogram bins in a band
    speed_bin: float = 1.0  # [m/s]: narrow, so lines fixed in wavenumber stay sharp in each bin
    min_length_s: float = 80.0  # [s] shortest usable gap-free stretch

    def __post_init__(self):
        for name in ("fs", "segment_s", "rel_width", "speed_bin", "min_length_s"):
            if not getattr(self, name) > 0:
                raise ValueError(f"RecordSettings.{name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.overlap_fraction < 1.0:
            raise ValueError(f"RecordSettings.overlap_fraction must be in [0, 1), got {self.overlap_fraction}")
        if not 0 < self.band[0] < self.band[1]:
            raise ValueError(f"RecordSettings.band must be (low, high) with 0 < low < high [Hz], got {self.band}")
        if self.min_bins < 1:
            raise ValueError(f"RecordSettings.min_bins must be at least 1, got {self.min_bins}")
        scipy.signal.get_window(self.window, 8)  # an unknown window name raises here, naming it


#: Bogie centres' spacing as a share of the carbody length, for a campaign that gives no
#: length: 0.70 for the seed's intercity car (16 m of 23 m), 0.72 for the Manchester
#: benchmark coach (19 m of 26.4 m), 0.69-0.86 over the independent truth's library.
BOGIE_SPACING_SHARE = 0.7


@dataclass(frozen=True)
class Layout:
    """Which sensor plays which part: the axle-box accelerometers of each wheelset (the rail
    input; a wheelset without any takes its leading counterpart's, delayed), and the bogie
    and carbody sensors the model predicts."""

    axle: dict  # "axle1".. "axle4" -> tuple of channel names (empty: no sensor on that wheelset)
    responses: tuple[Output, ...]  # model outputs at the sensors' declared positions
    response_sensors: tuple[Sensor, ...]  # the campaign's sensors behind ``responses``
    L_v: float  # [m] bogie semi-spacing
    L_b: float  # [m] bogie semi-wheelbase
    length: float  # [m] carbody length (the shape of its bending)
    length_assumed: bool = False  # campaign.toml gives none: BOGIE_SPACING_SHARE assumed
    out_of_round: int | None = None  # leading wheelset (1 or 2) found out of round (:meth:`rail_sources`)

    @property
    def carbody_sensed(self) -> bool:
        """Does a carbody (floor) sensor take part?"""
        return any(o.body == "carbody" for o in self.responses)

    def rail_sources(self) -> tuple[tuple[str, str | None, float], ...]:
        """Where each wheelset's rail input comes from: (wheelset, leading wheelset whose
        axle boxes it is taken from, None for its own, and the delay [m]). A trailing
        wheelset without axle boxes sees the rail a leading one measured, 2 L_v earlier; when
        a leading wheelset is out of round its axle boxes carry its polygon, which the
        trailing wheelsets do not have, so both take the round one's rail."""
        v, b = 2 * self.L_v, 2 * self.L_b
        if self.out_of_round == 1:
            trailing = (("axle3", "axle2", v - b), ("axle4", "axle2", v))
        elif self.out_of_round == 2:
            trailing = (("axle3", "axle1", v), ("axle4", "axle1", v + b))
        else:
            trailing = (("axle3", "axle1", v), ("axle4", "axle2", v))
        return (("axle1", None, 0.0), ("axle2", None, 0.0)) + trailing

    @property
    def input_names(self) -> tuple[str, ...]:
        return ("rail_acc_1", "rail_acc_2", "rail_acc_3", "rail_acc_4")

    @property
    def response_names(self) -> tuple[str, ...]:
        return tuple(o.name for o in self.responses)

    @property
    def channels(self) -> tuple[str, ...]:
        """Order of the spectral statistics: inputs, responses, consistency, axle means."""
        return self.input_names + self.response_names + ("consistency", "axle1_mean", "axle2_mean")


def layout(campaign: Campaign) -> Layout:
    """The campaign's sensors sorted into rail input and responses (:class:`CampaignError`
    naming campaign.toml's key when the diagnosis cannot work with them)."""
    meta = campaign.meta
    toml = campaign.root / "campaign.toml"
    if meta.kind != "in_service":
        raise CampaignError(f"diagnosis of {meta.kind} campaigns is not implemented here; in_service expected",
                            path=toml, key="kind")
    L_v, L_b = meta.geometry.get("bogie_semi_spacing"), meta.geometry.get("semi_wheelbase")
    if L_v is None or L_b is None:
        raise CampaignError("the diagnosis needs [vehicle] bogie_semi_spacing and semi_wheelbase", path=toml,
                            key="vehicle")
    acc_z = [s for s in meta.sensors if s.quantity == "acceleration" and s.direction == "z"]
    axle = {a: tuple(s.name for s in acc_z if s.body == a) for a in ("axle1", "axle2", "axle3", "axle4")}
    if not axle["axle1"] or not axle["axle2"]:
        raise CampaignError("the diagnosis needs vertical axle-box accelerometers on wheelsets 1 and 2 "
                            "(the rail input)", path=toml, key="sensors")
    responses, sensors = [], []
    for s in meta.sensors:
        if s.body in ("bogie1", "bogie2", "carbody") and s.quantity == "acceleration" and s.direction == "z":
            responses.append(Output(s.name, "acceleration", s.body, float(s.position[0])))
        elif s.body in ("bogie1", "bogie2", "carbody") and s.quantity == "angular_velocity" and s.direction == "pitch":
            responses.append(Output(s.name, "pitch_rate", s.body))
        else:
            continue
        sensors.append(s)
    if not responses:
        raise CampaignError("no bogie or carbody sensor: nothing for the model to predict", path=toml, key="sensors")
    length = meta.geometry.get("length")
    return Layout(axle, tuple(responses), tuple(sensors), float(L_v), float(L_b),
                  float(length) if length is not None else 2 * float(L_v) / BOGIE_SPACING_SHARE, length is None)


@dataclass(frozen=True)
class Record:
    """One gap-free stretch at the analysis rate; rows of ``z`` follow ``Layout.channels``."""

    run_id: str
    t0: float
    speed: np.ndarray  # [m/s]
    distance: np.ndarray  # [m] integrated speed
    z: np.ndarray  # (n_channels, n)


def _delayed(x: np.ndarray, t: np.ndarray, d: np.ndarray, v: np.ndarray, delay: float):
    """x seen ``delay`` metres later: x(t*) (v(t)/v(t*))^2 with d(t*) = d(t) - delay.
    Returns the values and the first valid index."""
    target = d - delay
    i0 = int(np.searchsorted(target, d[0]))
    tstar = np.interp(target[i0:], d, t)
    spline = scipy.interpolate.CubicSpline(t, x)
    vstar = np.interp(tstar, t, v)
    out = np.zeros_like(x)
    out[i0:] = spline(tstar) * (v[i0:] / vstar) ** 2
    return out, i0


def read_records(campaign: Campaign, lay: Layout, settings: RecordSettings = RecordSettings(), *,
                 runs=None, progress=None) -> list[Record]:
    """The gap-free stretches (every used sensor valid for ``settings.min_length_s`` or
    more) of ``runs`` (default: all), at ``settings.fs``, rows in ``lay.channels`` order."""
    fs_in = campaign.meta.sampling_rate
    ratio = Fraction(settings.fs / fs_in).limit_denominator(200)
    records = []
    used = [c for names in lay.axle.values() for c in names] + [s.name for s in lay.response_sensors]
    for run_id in (campaign.run_ids if runs is None else runs):
        run = campaign.read_run(run_id)
        if run.speed is None and run.distance is None:
            raise CampaignError("run has neither speed nor distance", path=run.path)
        ok = np.ones(len(run), bool)
        for c in used:
            ok &= run.valid[c]
        n_rec = 0
        for a, b in run.blocks:
            good = ok[a:b]
            # contiguous valid stretches inside the block
            edges = np.flatnonzero(np.diff(np.concatenate([[0], good.astype(int), [0]])))
            for s0, s1 in zip(edges[::2], edges[1::2]):
                i0, i1 = a + s0, a + s1
                t = run.time[i0:i1]
                if t.size < 4 or t[-1] - t[0] < settings.min_length_s:
                    continue
                rec = _record(run, i0, i1, lay, fs_in, ratio, settings)
                if rec is not None:
                    records.append(rec)
                    n_rec += 1
        if progress:
            progress(f"{run_id}: {n_rec} gap-free records")
    if not records:
        raise CampaignError(f"no gap-free stretch of {settings.min_length_s:g} s with every sensor valid",
                            path=campaign.root)
    return records


def _smooth(x: np.ndarray, n: int) -> np.ndarray:
    """Moving average over n samples with the ends reflected (no lag)."""
    n = max(1, min(n, x.size // 2 * 2 - 1))
    pad = np.pad(x, n // 2 + 1, mode="reflect")
    c = np.cumsum(np.concatenate([[0.0], pad]))
    out = (c[n:] - c[:-n]) / n
    start = (out.size - x.size) // 2
    return out[start:start + x.size]


def _record(run, i0, i1, lay: Layout, fs_in, ratio, settings) -> Record | None:
    t = run.time[i0:i1]
    if run.speed is not None:
        v = run.speed[i0:i1]
    else:
        v = np.gradient(run.distance[i0:i1], t)
    # The speed enters as (v(t)/v(t*))^2 times a broadband rail acceleration: its noise
    # would modulate that into every band (a 0.2 % Doppler jitter at 5 Hz swamps the
    # carbody's 1 Hz response). A train changes speed over tens of seconds: smooth over 10 s.
    v = np.maximum(_smooth(v, int(10.0 * fs_in)), 0.5)
    d = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    mean = {k: np.mean([run.channels[c][i0:i1] for c in names], axis=0) if names else None
            for k, names in lay.axle.items()}
    rails, first = [], 0
    for k, src, delay in lay.rail_sources():
        if mean[k] is not None:
            rails.append(mean[k])
        else:
            x, f0 = _delayed(mean[src], t, d, v, delay)
            rails.append(x)
            first = max(first, f0)
    cons, f0 = _delayed(mean["axle1"], t, d, v, 2 * lay.L_b)
    first = max(first, f0)
    cons = mean["axle2"] - cons
    resp = []
    for o in lay.responses:
        x = run.channels[o.name][i0:i1]
        resp.append(x)
    z = np.vstack(rails + resp + [cons, mean["axle1"], mean["axle2"]])[:, first:]
    v, d, t = v[first:], d[first:], t[first:]
    if t[-1] - t[0] < settings.min_length_s:
        return None
    z = z - z.mean(axis=1, keepdims=True)
    z = scipy.signal.resample_poly(z, ratio.numerator, ratio.denominator, axis=1)
    n = z.shape[1]
    tt = t[0] + np.arange(n) / settings.fs
    return Record(run.run_id, float(t[0]), np.interp(tt, t, v), np.interp(tt, t, d), z)


# ------------------------------------------------------------------ spectral statistics
def band_edges(settings: RecordSettings) -> np.ndarray:
    """Band edges [Hz]: width max(min_bins / segment_s, rel_width x f)."""
    lo, hi = settings.band
    df = settings.min_bins / settings.segment_s
    edges = [lo]
    while edges[-1] < hi:
        edges.append(edges[-1] + max(df, settings.rel_width * edges[-1]))
    return np.array(edges)


@dataclass(frozen=True)
class Statistics:
    """Sums of cross-spectra per (run, speed bin): ``S[key]`` is (n_band, n_ch, n_ch) of
    mean-square contributions (so a channel's diagonal summed over bands is its mean square
    in the band) times the seconds of data, ``seconds[key]`` the seconds.

    Sums over a selection of keys run in the statistics' own order (:meth:`ordered`): a
    set of (run id, speed) keys iterates in an order that changes with Python's string
    hash seed, and a fit on sums taken in that order gives another answer in each process.
    """

    channels: tuple[str, ...]
    edges: np.ndarray
    centres: np.ndarray
    segment_s: float  # [s] FFT segment length
    S: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)

    def ordered(self, keys) -> list:
        """The keys among ``keys``, in the statistics' order."""
        return [k for k in self.S if k in keys]

    def seconds_of(self, keys) -> float:
        """Seconds of data [s] under ``keys``."""
        return float(sum(self.seconds[k] for k in self.ordered(keys)))

    def total(self, keep=lambda key: True) -> tuple[np.ndarray, float]:
        keys = [k for k in self.S if keep(k)]
        if not keys:
            return np.zeros_like(next(iter(self.S.values()))), 0.0
        return sum(self.S[k] for k in keys), float(sum(self.seconds[k] for k in keys))

    @property
    def runs(self) -> tuple[str, ...]:
        return tuple(sorted({k[0] for k in self.S}))

    @property
    def speed_bins(self) -> tuple[float, ...]:
        return tuple(sorted({k[1] for k in self.S}))


def statistics(records: list[Record], channels: tuple[str, ...],
               settings: RecordSettings = RecordSettings()) -> Statistics:
    """Band sums of the cross-spectra of ``channels`` (the rows of each record's ``z``) per
    (run, speed bin), from tapered segments overlapping as ``settings`` say."""
    edges = band_edges(settings)
    nw = int(round(settings.segment_s * settings.fs))
    hop = max(1, int(round(nw * (1.0 - settings.overlap_fraction))))
    taper = scipy.signal.get_window(settings.window, nw)  # periodic
    # one-sided scaling so that a stationary signal's bins sum to its mean square
    scale = np.sqrt(2.0 / (nw * np.sum(taper * taper)))
    seconds = hop / settings.fs  # each segment stands for its hop: the cells' seconds are the data's
    freqs = np.fft.rfftfreq(nw, 1.0 / settings.fs)
    band = np.searchsorted(edges, freqs, side="right") - 1
    inside = (band >= 0) & (band < len(edges) - 1)
    idx, which = np.flatnonzero(inside), band[inside]
    centres = np.sqrt(edges[:-1] * edges[1:])
    st = Statistics(channels, edges, centres, settings.segment_s)
    for rec in records:
        n = rec.z.shape[1]
        for a in range(0, n - nw + 1, hop):
            X = np.fft.rfft(rec.z[:, a:a + nw] * taper, axis=1)[:, idx] * scale
            P = np.einsum("if,jf->fij", X, X.conj())
            S = np.zeros((len(edges) - 1, len(channels), len(channels)), complex)
            np.add.at(S, which, P)
            vbin = settings.speed_bin * np.floor(rec.speed[a:a + nw].mean() / settings.speed_bin)
            key = (rec.run_id, float(vbin))
            st.S[key] = st.S.get(key, 0) + S * seconds
            st.seconds[key] = st.seconds.get(key, 0.0) + seconds
    if not st.S:
        raise ValueError(f"no record is one {settings.segment_s:g} s segment long")
    return st
