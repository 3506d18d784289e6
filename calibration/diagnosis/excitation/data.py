"""The measured side of an excitation-test diagnosis: the training / held-out split of the
campaign's runs, and the H1 FRFs of each part in the comparison band with the variance of
their logarithm."""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace

import numpy as np

from ...data.campaign import Campaign, Run
from ...identification import ema


@dataclass(frozen=True)
class Part:
    """A view of some runs of a campaign (whole, or a [start, stop) fraction of each), with
    the interface :func:`calibration.identification.excitation.identify_excitation` reads:
    ``meta``, ``root``, ``iter_runs``."""

    campaign: Campaign
    runs: tuple[str, ...]
    fraction: tuple[float, float] = (0.0, 1.0)
    without: tuple[str, ...] = ()  # channels left out

    @property
    def meta(self):
        meta = self.campaign.meta
        if not self.without:
            return meta
        return replace(meta, sensors=tuple(x for x in meta.sensors if x.name not in self.without))

    @property
    def root(self):
        return self.campaign.root

    @property
    def label(self) -> list[str]:
        """The runs as the result names them (``run_001``, or ``run_001[0:0.5]`` for a half)."""
        if self.fraction == (0.0, 1.0):
            return list(self.runs)
        return [f"{r}[{self.fraction[0]:g}:{self.fraction[1]:g}]" for r in self.runs]

    def iter_runs(self) -> Iterator[Run]:
        for run_id in self.runs:
            run = self.campaign.read_run(run_id)
            if self.fraction != (0.0, 1.0):
                run = slice_run(run, *self.fraction)
            yield run


def slice_run(run: Run, a: float, b: float) -> Run:
    """The samples of ``run`` from fraction ``a`` to fraction ``b`` of its length, with its
    blocks and gaps cut to match."""
    n = len(run)
    i, j = int(round(a * n)), int(round(b * n))
    blocks = tuple((max(s, i) - i, min(e, j) - i) for s, e in run.blocks if min(e, j) > max(s, i))
    return replace(run, time=run.time[i:j], channels={k: v[i:j] for k, v in run.channels.items()},
                   valid={k: v[i:j] for k, v in run.valid.items()}, blocks=blocks,
                   gaps=tuple(g for g in run.gaps if run.time[i] <= g.after_time < run.time[j - 1]))


def split_campaign(campaign: Campaign, without: tuple[str, ...] = ()) -> tuple[Part, Part]:
    """Training and held-out parts: odd and even runs (``run_001`` trains, ``run_002`` is
    held out), or the first and second halves of a single run; ``without``: channels left
    out of both."""
    runs = tuple(campaign.run_ids)
    if len(runs) >= 2:
        return Part(campaign, runs[0::2], without=without), Part(campaign, runs[1::2], without=without)
    return Part(campaign, runs, (0.0, 0.5), without), Part(campaign, runs, (0.5, 1.0), without)


@dataclass(frozen=True, eq=False)
class MeasuredFRF:
    """H1 of one part in the comparison band, with the variance of log H.

    frequency : (n_f,) [Hz]
    H : (n_f, n_s) accelerance [(m/s^2)/N]
    sigma2 : (n_f, n_s) variance of log|H| (and of the phase) [-]: (1 - gamma^2) / (2 n gamma^2)
        for coherence gamma^2 over n Welch segments (Bendat & Piersol 1993, ch. 9)
    averages : n, the Welch segments averaged
    """

    frequency: np.ndarray
    H: np.ndarray
    sigma2: np.ndarray
    averages: int

    def every(self, step: int) -> "MeasuredFRF":
        """Every ``step``-th line (a coarser grid for a scan)."""
        return replace(self, frequency=self.frequency[::step], H=self.H[::step], sigma2=self.sigma2[::step])


def measured_frf(frf: ema.FRFEstimate, band: tuple[float, float]) -> MeasuredFRF:
    """The lines of ``frf`` in ``band`` [Hz]; the coherence is clipped to [1e-6, 1 - 1e-9]
    so that the variance stays finite and positive."""
    sel = (frf.frequency >= band[0]) & (frf.frequency <= band[1])
    g2 = np.clip(frf.coherence[sel], 1e-6, 1 - 1e-9)
    return MeasuredFRF(frf.frequency[sel], frf.H[sel], (1 - g2) / (2 * frf.n_averages * g2), frf.n_averages)
