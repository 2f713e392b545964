"""`compare`: the model against every measurement at its own stamp; per-channel errors and failure regions.

A failure region is a stretch of time where some channel's error exceeds 3 sigma in a good
share of that channel's own samples (isolated 3-sigma samples are noise: 0.3 % of them
exceed it by chance), whatever the other channels do -- a depth gauge at 2 Hz off by
6 sigma among load pins at 10 Hz that agree is a failure -- described by what the plant
was doing: payout, the share of lowering, hoisting, shifting and standing within it (a
region may span many moves), tension state, and which channels and cables miss in which
direction. Times are seconds from the start of the recording. Where a channel's prediction is ill-conditioned on the
lengths (analysis.conditioning), that is said too: an error there blames the encoders'
millimetres as much as the model.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..effects import PlantModel
from ..model.statics.result import Solution
from .bagfields import BagFields
from .conditioning import IllConditioned, ill_conditioned
from .data import Dataset
from .evaluate import ChannelStats, Evaluator, channel_stats, noise
from .follows import Finding, what_follows
from .motion import describe, motions, shares
from .unsolved import require_solved

THRESHOLD = 3.0    # [sigma]
MERGE_GAP = 1.0    # [s] exceedances closer than this (or than 3 of the channel's sample intervals) join
MIN_SAMPLES = 3    # a channel's stretch has at least this many exceeding values ...
MIN_DENSITY = 0.3  # ... and this share of the channel's own samples in it exceeding
MAX_REGIONS = 20


@dataclass
class Comparison:
    bag: str
    model: PlantModel
    data: Dataset
    predicted: np.ndarray
    noise: np.ndarray
    noise_source: dict[str, str]
    solutions: list[Solution]
    channels: dict[str, ChannelStats] = field(default_factory=dict)
    score: float = float("nan")
    regions: list[dict[str, Any]] = field(default_factory=list)
    ill_conditioned: list[IllConditioned] = field(default_factory=list)  # where the lengths do not determine a channel
    follows: list[Finding] = field(default_factory=list)
    follows_notes: list[str] = field(default_factory=list)
    unsolved: Counter[str] = field(default_factory=Counter)  # rows the model gives no pose, by why

    @property
    def residuals(self) -> np.ndarray:
        return self.data.measured - self.predicted


def compare(model: PlantModel, data: Dataset, fields: BagFields | None = None) -> Comparison:
    """Solve the model at every row and compare with what was measured; rank what the error follows
    (among the bag's other topics' `fields` too, where given)."""
    sigma, source = noise(model, data)
    evaluator = Evaluator(data)
    reasons = require_solved(data.bag, evaluator.solutions(model), "compare")
    predicted = evaluator.predicted(model)
    result = Comparison(data.bag, model, data, predicted, sigma, source, evaluator.solutions(model), unsolved=reasons)
    result.channels = channel_stats(result.residuals, data.measured, sigma, data.channels)
    result.score = evaluator.score(model, sigma)
    result.regions = failure_regions(result)
    result.ill_conditioned = ill_conditioned(model, data, sigma)
    result.follows = what_follows(data, result.residuals, sigma, fields=fields, channels=model.channels)
    result.follows_notes = fields.remarks() if fields else []
    return result


def _describe(c: Comparison, rows: np.ndarray, exceed: np.ndarray) -> dict[str, Any]:
    data = c.data
    payout = data.lengths[rows].mean(axis=1)
    speed = float(np.nanmean(data.speeds[rows]))
    motion = shares(motions(data.speeds[rows]))
    states = Counter(c.solutions[k].tension_state for k in rows)
    z = c.residuals[rows] / c.noise
    misses: list[dict[str, Any]] = []
    for ch, name in enumerate(data.channels):
        hits = exceed[:, ch] & np.isfinite(z[:, ch])
        if hits.any():
            sign = "above" if np.mean(z[hits, ch]) > 0 else "below"
            misses.append({"channel": name, "count": int(hits.sum()), "mean_sigma": float(np.mean(z[hits, ch])),
                           "measured": sign + " model"})
    unsolved = int((exceed & ~np.isfinite(z)).any(axis=1).sum())
    start, end = data.times[rows[0]] - data.times[0], data.times[rows[-1]] - data.times[0]
    text = (f"{start:.1f}-{end:.1f} s from the start: payout {payout.min():.1f}-{payout.max():.1f} m, "
            f"{describe(motion)} (mean {speed:+.2f} m/s), {states.most_common(1)[0][0]}; "
            + ", ".join([f"{m['channel']} {m['measured']} by {abs(m['mean_sigma']):.1f} sigma" for m in misses]
                        + ([f"{unsolved} rows not solved"] if unsolved else [])))
    return {"start": float(start), "end": float(end),
            "payout": [float(payout.min()), float(payout.max())], "speed": speed, "motion": motion,
            "tension_state": states.most_common(1)[0][0], "channels": misses, "unsolved_rows": unsolved,
            "severity": float(np.nansum(np.abs(z[exceed]))), "description": text}


def _channel_spans(times: np.ndarray, seen: np.ndarray, exceed: np.ndarray) -> list[tuple[float, float]]:
    """(start, end) times of one channel's stretches where its error exceeds the threshold: exceeding
    samples closer than its merge gap joined, kept with MIN_SAMPLES of them and MIN_DENSITY of the
    channel's own samples in the stretch."""
    mine = times[seen]
    hits = np.flatnonzero(exceed[seen])
    if hits.size < MIN_SAMPLES:
        return []
    gap = max(MERGE_GAP, 3.0 * float(np.median(np.diff(mine)))) if mine.size > 1 else MERGE_GAP
    breaks = np.flatnonzero(np.diff(mine[hits]) > gap)
    spans = []
    for first, last in zip(np.r_[0, breaks + 1], np.r_[breaks, hits.size - 1]):
        count, samples = last - first + 1, hits[last] - hits[first] + 1
        if count >= MIN_SAMPLES and count / samples >= MIN_DENSITY:
            spans.append((float(mine[hits[first]]), float(mine[hits[last]])))
    return spans


def failure_regions(c: Comparison) -> list[dict[str, Any]]:
    """Time intervals where some channel's error exceeds THRESHOLD sigma over a stretch (each channel judged
    on its own samples; overlapping stretches of several channels are one region), most severe first."""
    z = np.abs(c.residuals) / c.noise
    measured = np.isfinite(c.data.measured)
    exceed = measured & ~(z <= THRESHOLD)  # unsolvable rows exceed too
    times = c.data.times
    spans = sorted((*span, ch) for ch in range(measured.shape[1]) for span in
                   _channel_spans(times, measured[:, ch], exceed[:, ch]))
    joined: list[tuple[float, float, set[int]]] = []
    for start, end, ch in spans:
        if joined and start <= joined[-1][1] + MERGE_GAP:
            joined[-1] = (joined[-1][0], max(joined[-1][1], end), joined[-1][2] | {ch})
        else:
            joined.append((start, end, {ch}))
    regions = []
    for start, end, failing in joined:  # a channel's isolated exceedances in another's region are noise
        rows = np.flatnonzero((times >= start) & (times <= end))
        mask = np.zeros(measured.shape[1], bool)
        mask[list(failing)] = True
        regions.append(_describe(c, rows, exceed[rows] & mask))
    return sorted(regions, key=lambda r: -r["severity"])[:MAX_REGIONS]
