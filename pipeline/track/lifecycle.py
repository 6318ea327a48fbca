"""Track storage and lifecycle: TENTATIVE -> CONFIRMED -> LOST -> DORMANT -> deleted (SR-TRK-4).

Tracks live in fixed-capacity struct-of-arrays slots (``track.max_tracks`` live slots plus
``track.max_dormant`` dormant ones), so per-cycle work is bounded by configuration (SR-TIM-3).
Transitions, applied to all slots at once after association:

* a TENTATIVE track becomes CONFIRMED after ``confirm_hits`` hits and is deleted on its first
  miss (a tentative track is only a hypothesis);
* a CONFIRMED track becomes LOST after ``lost_after_misses`` consecutive misses (it is still
  predicted and associated) and back to CONFIRMED on a hit;
* a LOST track becomes DORMANT after ``dormant_after_misses`` consecutive misses when
  re-identification is enabled, else it is deleted. A dormant track keeps its ID, its last
  posterior and its histories but is no longer predicted every cycle;
* a DORMANT track is deleted after ``dormant_timeout_frames`` cycles, or earlier, oldest
  first, when more than ``max_dormant`` tracks are dormant;
* re-identification (source material): a detection left over after the cascade matches a
  dormant track when it lies inside the gates widened by ``dormant_gate_factor`` around the
  track's last posterior predicted ahead by ``min(elapsed, dormant_prediction_cap_s)``, and its
  box width and length are each within ``dormant_size_tolerance_frac`` of the track's mean
  size. The track then returns CONFIRMED with its ID and histories.

IDs come from a counter that only increases: an ID is never reused (SR-TRK-4).
"""

from __future__ import annotations

import numpy as np

from pipeline.config import TrackSection
from pipeline.types import BoolArray, FloatArray, IntArray, TrackStatus

__all__ = ["FREE", "TrackStore", "size_compatible"]

FREE = -1  # status of an unused slot


class TrackStore:
    """Fixed-capacity struct of arrays holding every live and dormant track."""

    def __init__(self, config: TrackSection) -> None:
        self.config = config
        cap = config.max_tracks + config.max_dormant
        h, s = config.history_frames, config.size_variance_frames
        self.capacity = cap
        self.status = np.full(cap, FREE, dtype=np.int64)
        self.track_id = np.full(cap, -1, dtype=np.int64)
        self.x = np.zeros((cap, 4))
        self.p = np.zeros((cap, 4, 4))
        self.x_post = np.zeros((cap, 4))
        self.p_post = np.zeros((cap, 4, 4))
        self.last_update_s = np.zeros(cap)
        self.hits = np.zeros(cap, dtype=np.int64)
        self.misses = np.zeros(cap, dtype=np.int64)
        self.age_frames = np.zeros(cap, dtype=np.int64)
        self.dormant_frames = np.zeros(cap, dtype=np.int64)
        self.reid_count = np.zeros(cap, dtype=np.int64)
        self.detection_index = np.full(cap, -1, dtype=np.int64)
        # Histories are shift buffers, newest last; unused entries are NaN.
        self.hist_xy = np.full((cap, h, 2), np.nan)
        self.hist_t = np.full((cap, h), np.nan)
        self.hist_speed = np.full((cap, h), np.nan)
        self.hist_len = np.zeros(cap, dtype=np.int64)
        self.hist_end = np.full((cap, h, 4), np.nan)
        self.hist_occ = np.full((cap, h, 2), np.nan)
        self.size_wl = np.full((cap, s, 2), np.nan)
        self.size_len = np.zeros(cap, dtype=np.int64)
        # Largest box width and length seen since birth: a part-view of a large object (a
        # fork tip, a mast past an occluder) keeps the size the track once showed.
        self.max_wl = np.full((cap, 2), np.nan)
        # Heading in the tracking frame (NaN unknown) and whether motion fixed its direction
        # (pipeline/track/heading.py); not part of the Tracks snapshot.
        self.heading = np.full(cap, np.nan)
        self.heading_resolved = np.zeros(cap, dtype=bool)
        self.next_id = 0

    # -- queries ---------------------------------------------------------------------------
    def mask(self, *statuses: TrackStatus) -> BoolArray:
        """Slots whose status is one of ``statuses``."""
        return np.isin(self.status, [int(s) for s in statuses])

    @property
    def live(self) -> BoolArray:
        """Slots predicted and associated every cycle (tentative, confirmed, lost)."""
        live: BoolArray = (self.status >= 0) & (self.status != TrackStatus.DORMANT)
        return live

    def mean_size(self, slots: IntArray) -> FloatArray:
        """Mean (width, length) over each slot's size history, (k, 2)."""
        sizes = self.size_wl[slots]
        count = np.maximum(self.size_len[slots], 1)[:, None]
        mean: FloatArray = np.where(np.isnan(sizes), 0.0, sizes).sum(axis=1) / count
        return mean

    # -- mutations -------------------------------------------------------------------------
    def create(
        self,
        x: FloatArray,
        p: FloatArray,
        stamp_s: float,
        wl_m: FloatArray,
        det: IntArray,
        ends: tuple[FloatArray, FloatArray],
    ) -> IntArray:
        """Put new TENTATIVE tracks in the lowest free slots; returns their slots."""
        k = x.shape[0]
        slots = np.flatnonzero(self.status == FREE)[:k]
        if slots.shape[0] != k:
            raise RuntimeError(f"TrackStore.create: {k} tracks requested, {slots.shape[0]} free")
        self.status[slots] = TrackStatus.TENTATIVE
        self.track_id[slots] = np.arange(self.next_id, self.next_id + k)
        self.next_id += k
        self.x[slots], self.p[slots] = x, p
        self.x_post[slots], self.p_post[slots] = x, p
        self.last_update_s[slots] = stamp_s
        self.hits[slots] = 1
        self.misses[slots] = 0
        self.age_frames[slots] = 0
        self.dormant_frames[slots] = 0
        self.reid_count[slots] = 0
        self.detection_index[slots] = det
        self.hist_xy[slots] = np.nan
        self.hist_t[slots] = np.nan
        self.hist_speed[slots] = np.nan
        self.hist_len[slots] = 0
        self.hist_end[slots] = np.nan
        self.hist_occ[slots] = np.nan
        self.size_wl[slots] = np.nan
        self.size_len[slots] = 0
        self.max_wl[slots] = np.nan
        self.heading[slots] = np.nan
        self.heading_resolved[slots] = False
        self.record(slots, stamp_s, wl_m, *ends)
        return slots

    def record(
        self,
        slots: IntArray,
        stamp_s: float,
        wl_m: FloatArray,
        end_xy_m: FloatArray,
        end_occluded: FloatArray,
    ) -> None:
        """Append each slot's posterior centroid, speed, box size and its detection's ends
        (``end_xy_m`` (k, 4), ``end_occluded`` (k, 2) as 1.0 / 0.0 / NaN) to its histories."""
        if slots.shape[0] == 0:
            return
        self.hist_xy[slots, :-1] = self.hist_xy[slots, 1:]
        self.hist_t[slots, :-1] = self.hist_t[slots, 1:]
        self.hist_speed[slots, :-1] = self.hist_speed[slots, 1:]
        self.hist_end[slots, :-1] = self.hist_end[slots, 1:]
        self.hist_occ[slots, :-1] = self.hist_occ[slots, 1:]
        self.hist_end[slots, -1] = end_xy_m
        self.hist_occ[slots, -1] = end_occluded
        self.hist_xy[slots, -1] = self.x_post[slots, :2]
        self.hist_t[slots, -1] = stamp_s
        self.hist_speed[slots, -1] = np.hypot(self.x_post[slots, 2], self.x_post[slots, 3])
        self.hist_len[slots] = np.minimum(self.hist_len[slots] + 1, self.hist_xy.shape[1])
        self.size_wl[slots, :-1] = self.size_wl[slots, 1:]
        self.size_wl[slots, -1] = wl_m
        self.size_len[slots] = np.minimum(self.size_len[slots] + 1, self.size_wl.shape[1])
        self.max_wl[slots] = np.fmax(self.max_wl[slots], wl_m)

    def delete(self, slots: IntArray) -> None:
        """Free slots (their IDs are retired for good)."""
        self.status[slots] = FREE
        self.track_id[slots] = -1

    def advance(self, hit: BoolArray, reidentified: BoolArray) -> tuple[int, int, int]:
        """Apply the lifecycle transitions after association; returns deletions by reason.

        ``hit``: slots updated this cycle (re-identified ones included). Returns counts of
        (tentative tracks dropped, tracks timed out or evicted from dormancy, lost tracks
        deleted because re-identification is off).
        """
        c = self.config
        used = self.status != FREE
        self.age_frames[used] += 1
        self.misses[hit] = 0
        self.hits[hit] += 1
        tentative = self.status == TrackStatus.TENTATIVE
        self.status[hit & tentative & (self.hits >= c.confirm_hits)] = TrackStatus.CONFIRMED
        self.status[hit & (self.status == TrackStatus.LOST)] = TrackStatus.CONFIRMED
        self.status[reidentified] = TrackStatus.CONFIRMED
        self.dormant_frames[reidentified] = 0
        missed = self.live & ~hit
        self.misses[missed] += 1
        dropped = np.flatnonzero(missed & tentative)
        self.delete(dropped)
        confirmed = self.status == TrackStatus.CONFIRMED
        self.status[missed & confirmed & (self.misses >= c.lost_after_misses)] = TrackStatus.LOST
        going = np.flatnonzero(
            missed & (self.status == TrackStatus.LOST) & (self.misses >= c.dormant_after_misses)
        )
        n_lost_deleted = 0
        dormant = self.status == TrackStatus.DORMANT
        self.dormant_frames[dormant & ~reidentified] += 1
        expired = np.flatnonzero(dormant & (self.dormant_frames >= c.dormant_timeout_frames))
        self.delete(expired)
        if c.reid_enabled and c.max_dormant > 0:
            self.status[going] = TrackStatus.DORMANT
            self.dormant_frames[going] = 0
        else:
            self.delete(going)
            n_lost_deleted = int(going.shape[0])
        dormant_slots = np.flatnonzero(self.status == TrackStatus.DORMANT)
        excess = dormant_slots.shape[0] - c.max_dormant
        n_evicted = 0
        if excess > 0:
            # Oldest first: earliest last update, then lowest ID.
            order = np.lexsort((self.track_id[dormant_slots], self.last_update_s[dormant_slots]))
            self.delete(dormant_slots[order[:excess]])
            n_evicted = excess
        return int(dropped.shape[0]), int(expired.shape[0]) + n_evicted, n_lost_deleted


def size_compatible(
    track_wl_m: FloatArray, det_wl_m: FloatArray, tolerance_frac: float, floor_m: float
) -> BoolArray:
    """(tracks x detections) mask: width and length each within the relative tolerance.

    ``|a - b| <= tolerance_frac * max(a, b, floor_m)`` for width and for length.
    """
    a = track_wl_m[:, None, :]
    b = det_wl_m[None, :, :]
    scale = np.maximum(np.maximum(a, b), floor_m)
    ok: BoolArray = np.all(np.abs(a - b) <= tolerance_frac * scale, axis=2)
    return ok
