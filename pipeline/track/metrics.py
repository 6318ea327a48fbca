"""Tracking quality against ground truth, for any scan source (requirement SR-TRK-5).

Inputs are plain per-frame arrays (:class:`PositionsFrame`: object IDs and positions), so the same
functions score the tracker on the synthetic sequences of the tests, on simulator scenarios
and on labelled logs. Metrics:

* CLEAR-MOT (Bernardin and Stiefelhagen 2008), in py-motmetrics' reading: per frame, each
  truth keeps the hypothesis of its last match (even across frames where it was missed)
  while that hypothesis is present and within ``match_threshold_m``; the remaining truths and
  hypotheses are matched by minimum total distance (Hungarian) within the threshold. ID
  switches count truths matched to a different hypothesis ID than at their last match; MOTA
  ``1 - (misses + false positives + ID switches) / truths``; MOTP the mean matched distance.
  py-motmetrics gives the same counts on the same frames (a cross-check of SR-TRK-8, -9).
* Fragmentation: for each truth, the number of times its tracked segments are interrupted
  and later resume (segments - 1), summed.
* Position RMSE over all matched pairs.
* GOSPA (Rahmathullah et al. 2017) per frame with cut-off ``gospa_c_m``, order ``gospa_p``
  and alpha 2, averaged over frames.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from pipeline.config import TrackSection, overridden, validate_config
from pipeline.track.tracker import Detections, Tracker
from pipeline.types import FloatArray, IntArray, Tracks, TrackStatus, frozen_array

__all__ = [
    "PositionsFrame",
    "TrackingQuality",
    "compare_reid",
    "evaluate",
    "frame_from_tracks",
    "gospa",
    "run_tracker",
]


@dataclass(frozen=True, slots=True)
class PositionsFrame:
    """Objects at one instant: integer IDs and positions ``xy_m`` (n, 2) in metres."""

    ids: IntArray
    xy_m: FloatArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "ids", frozen_array(self.ids, np.int64))
        xy = frozen_array(self.xy_m).reshape(-1, 2)
        object.__setattr__(self, "xy_m", xy)
        if xy.shape[0] != self.ids.shape[0]:
            raise ValueError(f"PositionsFrame: {self.ids.shape[0]} ids but {xy.shape[0]} positions")
        if np.unique(self.ids).shape[0] != self.ids.shape[0]:
            raise ValueError(f"PositionsFrame: ids must be unique, got {self.ids.tolist()}")


@dataclass(frozen=True, slots=True)
class TrackingQuality:
    """Scores of a hypothesis sequence against the truth (counts and metres)."""

    n_frames: int
    n_truth: int
    n_matches: int
    n_misses: int
    n_false_positives: int
    id_switches: int
    fragmentations: int
    mota: float
    motp_m: float
    position_rmse_m: float
    gospa_mean_m: float
    n_truth_ids: int
    n_hypothesis_ids: int


def gospa(
    truth_xy_m: FloatArray, hyp_xy_m: FloatArray, c_m: float = 2.0, p: float = 2.0
) -> tuple[float, int]:
    """GOSPA distance (alpha = 2) between two point sets, and the number of pairs closer than c.

    ``d = (sum over assigned pairs of min(d, c)^p + c^p / 2 * ||X| - |Y||)^(1/p)``, with the
    assignment minimizing that sum.
    """
    n_t, n_h = truth_xy_m.shape[0], hyp_xy_m.shape[0]
    total = 0.5 * c_m**p * abs(n_t - n_h)
    n_close = 0
    if n_t and n_h:
        d = np.hypot(
            truth_xy_m[:, None, 0] - hyp_xy_m[None, :, 0],
            truth_xy_m[:, None, 1] - hyp_xy_m[None, :, 1],
        )
        cost = np.minimum(d, c_m) ** p
        r, col = linear_sum_assignment(cost)
        total += float(cost[r, col].sum())
        n_close = int(np.count_nonzero(d[r, col] < c_m))
    return float(total ** (1.0 / p)), n_close


def evaluate(
    truth: Sequence[PositionsFrame],
    hypotheses: Sequence[PositionsFrame],
    match_threshold_m: float = 1.0,
    gospa_c_m: float = 2.0,
    gospa_p: float = 2.0,
) -> TrackingQuality:
    """CLEAR-MOT, fragmentation, RMSE and mean GOSPA of ``hypotheses`` against ``truth``."""
    if len(truth) != len(hypotheses):
        raise ValueError(f"evaluate: {len(truth)} truth frames but {len(hypotheses)} hypotheses")
    last_match: dict[int, int] = {}  # truth id -> hypothesis id at its last match
    tracked_before: dict[int, bool] = {}
    segments: dict[int, int] = {}
    n_truth = n_matches = n_fp = n_switches = 0
    sq_sum = dist_sum = gospa_sum = 0.0
    truth_ids: set[int] = set()
    hyp_ids: set[int] = set()
    thr2 = match_threshold_m * match_threshold_m
    for gt, hy in zip(truth, hypotheses, strict=True):
        g_ids, h_ids = gt.ids.tolist(), hy.ids.tolist()
        truth_ids.update(g_ids)
        hyp_ids.update(h_ids)
        g_pos = {g: i for i, g in enumerate(g_ids)}
        h_pos = {h: j for j, h in enumerate(h_ids)}
        d2 = (gt.xy_m[:, None, 0] - hy.xy_m[None, :, 0]) ** 2 + (
            gt.xy_m[:, None, 1] - hy.xy_m[None, :, 1]
        ) ** 2
        pairs: dict[int, int] = {}
        for g in g_ids:
            h = last_match.get(g)
            if (
                h is not None
                and h in h_pos
                and h not in pairs.values()
                and d2[g_pos[g], h_pos[h]] <= thr2
            ):
                pairs[g] = h
        used_h = set(pairs.values())
        free_g = [i for i, g in enumerate(g_ids) if g not in pairs]
        free_h = [j for j, h in enumerate(h_ids) if h not in used_h]
        # Minimum total distance (not squared distance), as CLEAR-MOT and py-motmetrics.
        feasible = d2[np.ix_(free_g, free_h)] <= thr2
        if feasible.any():
            sub = np.sqrt(d2[np.ix_(free_g, free_h)])
            # Dearer than any assignment of feasible pairs, so none of them is given up.
            big = (float(sub[feasible].max()) + 1.0) * (min(sub.shape) + 1.0)
            r, col = linear_sum_assignment(np.where(feasible, sub, big))
            for a, b in zip(r.tolist(), col.tolist(), strict=True):
                if feasible[a, b]:
                    pairs[g_ids[free_g[a]]] = h_ids[free_h[b]]
        for g, h in pairs.items():
            if g in last_match and last_match[g] != h:
                n_switches += 1
            last_match[g] = h
            dd = float(d2[g_pos[g], h_pos[h]])
            sq_sum += dd
            dist_sum += float(np.sqrt(dd))
        for g in g_ids:
            tracked = g in pairs
            if tracked and not tracked_before.get(g):
                segments[g] = segments.get(g, 0) + 1
            tracked_before[g] = tracked
        n_truth += len(g_ids)
        n_matches += len(pairs)
        n_fp += len(h_ids) - len(pairs)
        gospa_sum += gospa(gt.xy_m, hy.xy_m, gospa_c_m, gospa_p)[0]
    n_misses = n_truth - n_matches
    n_frames = len(truth)
    return TrackingQuality(
        n_frames=n_frames,
        n_truth=n_truth,
        n_matches=n_matches,
        n_misses=n_misses,
        n_false_positives=n_fp,
        id_switches=n_switches,
        fragmentations=sum(max(s - 1, 0) for s in segments.values()),
        mota=1.0 - (n_misses + n_fp + n_switches) / n_truth if n_truth else math.nan,
        motp_m=dist_sum / n_matches if n_matches else math.nan,
        position_rmse_m=float(np.sqrt(sq_sum / n_matches)) if n_matches else math.nan,
        gospa_mean_m=gospa_sum / n_frames if n_frames else math.nan,
        n_truth_ids=len(truth_ids),
        n_hypothesis_ids=len(hyp_ids),
    )


REPORTED = (TrackStatus.CONFIRMED, TrackStatus.LOST)


def frame_from_tracks(
    tracks: Tracks, statuses: tuple[TrackStatus, ...] = REPORTED
) -> PositionsFrame:
    """The tracker's output as a :class:`PositionsFrame` (by default confirmed and lost tracks)."""
    keep = tracks.with_status(*statuses)
    return PositionsFrame(tracks.track_id[keep], tracks.state[keep, :2])


def run_tracker(
    frames: Iterable[tuple[Detections, PositionsFrame]],
    config: TrackSection,
    statuses: tuple[TrackStatus, ...] = REPORTED,
) -> tuple[list[PositionsFrame], list[PositionsFrame]]:
    """Track a sequence of (detections, truth) pairs; returns (truth frames, hypotheses)."""
    tracker = Tracker(config)
    truths: list[PositionsFrame] = []
    hyps: list[PositionsFrame] = []
    for detections, truth in frames:
        tracks = tracker.step(detections)
        truths.append(truth)
        hyps.append(frame_from_tracks(tracks, statuses))
    return truths, hyps


def compare_reid(
    frames: Sequence[tuple[Detections, PositionsFrame]],
    config: TrackSection | None = None,
    match_threshold_m: float = 1.0,
) -> dict[str, TrackingQuality]:
    """Score the same sequence with re-identification on and off (SR-TRK-5).

    Returns ``{"reid_on": ..., "reid_off": ...}``; every other setting is ``config``'s.
    """
    base = config if config is not None else validate_config({}).track
    out: dict[str, TrackingQuality] = {}
    for name, enabled in (("reid_on", True), ("reid_off", False)):
        section = overridden(
            validate_config({"track": base.model_dump()}), {"track": {"reid_enabled": enabled}}
        ).track
        truths, hyps = run_tracker(frames, section)
        out[name] = evaluate(truths, hyps, match_threshold_m)
    return out
