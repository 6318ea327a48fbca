"""The multi-object tracker: one call per scan, clusters in, tracks out (SR-TRK-3..5, SR-TIM-3).

A cycle: check the clock, cap the detections (nearest kept), predict every live track with the
batched Kalman filter, gate and assign by cascade (confirmed and lost tracks, then tentative),
re-identify dormant tracks from the leftovers, update the matched tracks in one batch, apply
the lifecycle transitions, start tentative tracks on what is left (while live slots remain),
and report a :class:`pipeline.types.Tracks` snapshot with the per-track features (centroid
history, deceleration estimate, size variance). Every array is bounded by ``track.max_tracks``,
``track.max_dormant`` and ``track.max_detections``, so the cycle's work is bounded.

The associator is the configured one (``track.association``): the Hungarian cascade, or JPDA
where confirmed tracks share gated detections (:mod:`pipeline.track.jpda`, SR-TRK-8), whose
tracks are updated with every gated detection at once. Each track also keeps a heading from its
detections' box axes (:mod:`pipeline.track.heading`, SR-TRK-7), reported beside the snapshot
(:attr:`Tracker.last_headings`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pipeline.config import TrackSection
from pipeline.frames import Pose, checked_pose, to_parent
from pipeline.roles import Associator, SoftAssociator
from pipeline.track import kalman
from pipeline.track.associate import CascadeAssociator, assign, gated_costs
from pipeline.track.heading import TrackHeadings, update_headings, wrap_pi
from pipeline.track.jpda import JpdaAssociator, pda_update
from pipeline.track.lifecycle import FREE, TrackStore, size_compatible
from pipeline.types import (
    Clusters,
    CycleCounts,
    Detections,
    FloatArray,
    IntArray,
    TrackerError,
    Tracks,
    TrackStatus,
)

__all__ = [
    "SETTLED_HITS_FACTOR",
    "CycleCounts",
    "Detections",
    "Tracker",
    "TrackerError",
    "associator_for",
    "detections_in_frame",
    "reid_reach_m",
]
# CycleCounts, Detections and TrackerError live in pipeline.types (shared with the roles).

SETTLED_HITS_FACTOR = 2
"""A track's velocity may resolve its heading's flip once it has this many times
``track.confirm_hits`` updates: a new track's first centroids move as more of the object comes
into view, which gives a parked vehicle a confident but false velocity."""


def detections_in_frame(clusters: Clusters, pose: Pose) -> Detections:
    """The clusters' centroids and ends moved from the scan's frame into the tracking frame.

    ``pose`` places the scan's frame in the tracking frame at the scan's stamp (odometry at run
    time, the simulator's ground truth in training); box sizes and occlusion flags are
    unchanged by a rigid motion. Raises :class:`pipeline.frames.FrameError` for a pose that is
    not finite.
    """
    pose = checked_pose(pose)
    local = Detections.from_clusters(clusters)
    assert local.end_xy_m is not None  # from_clusters always carries the ends
    # Centroids and both ends as one (n, 3, 2) block of points, moved by the same rotation.
    xy = np.concatenate(
        [np.stack([local.x_m, local.y_m], axis=1)[:, None, :], local.end_xy_m.reshape(-1, 2, 2)],
        axis=1,
    )
    moved = np.stack(to_parent(pose, xy[..., 0], xy[..., 1]), axis=2)
    heading = None if local.heading_rad is None else local.heading_rad + pose[2]
    return replace(
        local,
        x_m=moved[:, 0, 0],
        y_m=moved[:, 0, 1],
        end_xy_m=moved[:, 1:].reshape(-1, 4),
        heading_rad=heading,
    )


def reid_reach_m(horizon_s: FloatArray, size_m: FloatArray, config: TrackSection) -> FloatArray:
    """How far [m] from its constant-velocity prediction a dormant track's detection may lie
    after ``horizon_s`` (n,) seconds: an object accelerating at most
    ``track.reid_max_accel_mps2`` reaches ``0.5 * a * h^2``, a view of another side moves the
    centroid by up to half its largest size ``size_m`` (n,), plus ``track.reid_slack_m``
    (SR-AVL-7)."""
    a = config.reid_max_accel_mps2
    reach: FloatArray = 0.5 * a * horizon_s * horizon_s + 0.5 * size_m + config.reid_slack_m
    return reach


def associator_for(config: TrackSection) -> Associator:
    """The association component ``track.association`` names (SR-TRK-8)."""
    if config.association == "jpda":
        return JpdaAssociator(config)
    return CascadeAssociator()


class Tracker:
    """Stateful tracker over one scan stream (configured by the ``track`` section)."""

    def __init__(self, config: TrackSection, associator: Associator | None = None) -> None:
        self.config = config
        self.associator: Associator = (
            associator if associator is not None else associator_for(config)
        )
        self.store = TrackStore(config)
        self.last_stamp_s: float | None = None
        self.last_counts: CycleCounts | None = None
        self.last_headings: TrackHeadings | None = None

    def reset(self) -> None:
        """Forget every track and the clock (and the associator's learned state)."""
        self.store = TrackStore(self.config)
        self.last_stamp_s = None
        self.last_counts = None
        self.last_headings = None
        reset = getattr(self.associator, "reset", None)
        if callable(reset):
            reset()

    def step(self, detections: Detections) -> Tracks:
        """Run one cycle on ``detections`` (stamped in seconds) and return the snapshot."""
        c, st = self.config, self.store
        stamp = float(detections.stamp_s)
        if not np.isfinite(stamp):
            raise TrackerError(f"Tracker.step: stamp_s must be finite, got {stamp!r}")
        if self.last_stamp_s is not None and stamp < self.last_stamp_s:
            raise TrackerError(
                f"Tracker.step: stamp_s {stamp!r} is before the previous cycle's "
                f"{self.last_stamp_s!r}; expected a clock that does not run backwards"
            )
        dt = 0.0 if self.last_stamp_s is None else stamp - self.last_stamp_s
        det_xy = np.stack([detections.x_m, detections.y_m], axis=1)
        det_wl = np.stack([detections.width_m, detections.length_m], axis=1)
        if not (np.all(np.isfinite(det_xy)) and np.all(np.isfinite(det_wl))):
            raise TrackerError("Tracker.step: detections must be finite (x, y, width, length)")
        det_end, det_occ = detections.ends()
        det_axis = (
            np.full(detections.n, np.nan)
            if detections.heading_rad is None
            else np.asarray(detections.heading_rad)
        )
        det_index = np.arange(detections.n)
        n_dropped = 0
        if detections.n > c.max_detections:
            nearest = np.argsort(np.hypot(det_xy[:, 0], det_xy[:, 1]), kind="stable")
            det_index = np.sort(nearest[: c.max_detections])
            n_dropped = detections.n - c.max_detections
            det_xy, det_wl = det_xy[det_index], det_wl[det_index]
            det_end, det_occ = det_end[det_index], det_occ[det_index]
            det_axis = det_axis[det_index]

        live = np.flatnonzero(st.live)
        if live.shape[0] and dt > 0.0:
            st.x[live], st.p[live] = kalman.predict(
                st.x[live], st.p[live], np.full(live.shape[0], dt), c.process_accel_std_mps2
            )
        s, s_inv = kalman.innovation(st.p[live], c.measurement_std_m)
        cost = gated_costs(
            st.x[live, :2], s_inv, det_xy, c.gate_euclidean_m, c.gate_mahalanobis_chi2
        )
        status = st.status[live]
        confirmed = (status == TrackStatus.CONFIRMED) | (status == TrackStatus.LOST)
        groups = [confirmed, status == TrackStatus.TENTATIVE]
        pda = np.zeros(live.shape[0], dtype=bool)
        if isinstance(self.associator, SoftAssociator):
            det_s = s[:, 0, 0] * s[:, 1, 1] - s[:, 0, 1] * s[:, 1, 0]
            log_norm = -np.log(2.0 * np.pi) - 0.5 * np.log(det_s)
            soft = self.associator.associate_soft(cost, groups, log_norm)
            match, free, pda = soft.match, soft.free, soft.pda
            if pda.any():
                # Every JPDA track is updated with all its gated detections (weights beta).
                rows = live[pda]
                st.x[rows], st.p[rows], _ = pda_update(
                    st.x[rows], st.p[rows], det_xy, soft.beta[pda], c.measurement_std_m
                )
        else:
            match, free = self.associator.associate(cost, groups)
        hit_slots = live[match >= 0]
        hit_dets = match[match >= 0]
        n_confirmed_hits = int(np.count_nonzero(confirmed & (match >= 0)))

        reid_slots, reid_dets, reid_widen = self._reidentify(stamp, det_xy, det_wl, free)
        free[reid_dets] = False
        slots = np.concatenate([hit_slots, reid_slots])
        dets = np.concatenate([hit_dets, reid_dets])
        kalman_rows = ~pda[match >= 0]
        st.detection_index[st.status != FREE] = -1
        if reid_slots.shape[0]:
            st.x[reid_slots], st.p[reid_slots] = kalman.reacquire(
                st.x[reid_slots],
                st.p[reid_slots],
                det_xy[reid_dets],
                np.hypot(c.measurement_std_m, 0.5 * st.mean_size(reid_slots).max(axis=1)),
                reid_widen,
            )
        ks, kd = hit_slots[kalman_rows], hit_dets[kalman_rows]
        if ks.shape[0]:
            st.x[ks], st.p[ks] = kalman.update(st.x[ks], st.p[ks], det_xy[kd], c.measurement_std_m)
        if slots.shape[0]:
            st.x_post[slots] = st.x[slots]
            st.p_post[slots] = st.p[slots]
            st.last_update_s[slots] = stamp
            st.detection_index[slots] = det_index[dets]
            st.record(slots, stamp, det_wl[dets], det_end[dets], det_occ[dets])
            st.heading[slots], st.heading_resolved[slots] = update_headings(
                st.heading[slots],
                st.heading_resolved[slots],
                det_axis[dets],
                st.x[slots, 2:],
                kalman.largest_std(st.p[slots, 2:, 2:]),
                st.hits[slots] >= SETTLED_HITS_FACTOR * c.confirm_hits,
                c,
            )
        hit = np.zeros(st.capacity, dtype=bool)
        hit[slots] = True
        reidentified = np.zeros(st.capacity, dtype=bool)
        reidentified[reid_slots] = True
        st.reid_count[reid_slots] += 1
        n_tentative_dropped, n_dormant_deleted, n_lost_deleted = st.advance(hit, reidentified)

        leftover = np.flatnonzero(free)
        room = max(c.max_tracks - int(np.count_nonzero(st.live)), 0)
        if leftover.shape[0] > room:
            by_range = np.argsort(np.hypot(det_xy[leftover, 0], det_xy[leftover, 1]), kind="stable")
            leftover = np.sort(leftover[by_range[:room]])
        n_refused = int(np.count_nonzero(free)) - leftover.shape[0]
        if leftover.shape[0]:
            x0, p0 = kalman.initiate(det_xy[leftover], c.measurement_std_m, c.init_velocity_std_mps)
            ends = (det_end[leftover], det_occ[leftover])
            born = st.create(x0, p0, stamp, det_wl[leftover], det_index[leftover], ends)
            st.heading[born] = wrap_pi(det_axis[leftover])

        self.last_stamp_s = stamp
        self.last_counts = CycleCounts(
            n_detections=detections.n,
            n_detections_dropped=n_dropped,
            n_matched_confirmed=n_confirmed_hits,
            n_matched_tentative=int(hit_slots.shape[0]) - n_confirmed_hits,
            n_reidentified=int(reid_slots.shape[0]),
            n_born=int(leftover.shape[0]),
            n_births_refused=n_refused,
            n_tentative_dropped=n_tentative_dropped,
            n_dormant_deleted=n_dormant_deleted,
            n_lost_deleted=n_lost_deleted,
            n_live=int(np.count_nonzero(st.live)),
            n_dormant=int(np.count_nonzero(st.status == TrackStatus.DORMANT)),
        )
        return self.snapshot()

    def _reidentify(
        self, stamp: float, det_xy: FloatArray, det_wl: FloatArray, free: np.ndarray
    ) -> tuple[IntArray, IntArray, FloatArray]:
        """Match dormant tracks to leftover detections within the domain's reach
        (:func:`reid_reach_m`); primes the matched slots with their prediction and returns
        them, their detections and the velocity widening [m/s] for :func:`kalman.reacquire`."""
        c, st = self.config, self.store
        empty = np.empty(0, dtype=np.int64)
        dormant = np.flatnonzero(st.status == TrackStatus.DORMANT)
        cols = np.flatnonzero(free)
        if not c.reid_enabled or dormant.shape[0] == 0 or cols.shape[0] == 0:
            return empty, empty, np.empty(0)
        horizon = np.minimum(stamp - st.last_update_s[dormant], c.dormant_prediction_cap_s)
        xd, pd = kalman.predict(
            st.x_post[dormant], st.p_post[dormant], horizon, c.process_accel_std_mps2
        )
        _, s_inv = kalman.innovation(pd, c.measurement_std_m)
        factor = c.dormant_gate_factor
        cost = gated_costs(
            xd[:, :2],
            s_inv,
            det_xy[cols],
            c.gate_euclidean_m * factor,
            c.gate_mahalanobis_chi2 * factor * factor,
        )
        mean_size = st.mean_size(dormant)
        sized = size_compatible(
            mean_size, det_wl[cols], c.dormant_size_tolerance_frac, c.reid_size_floor_m
        )
        reach = reid_reach_m(horizon, mean_size.max(axis=1), c)
        deviation = np.hypot(
            det_xy[cols, 0][None, :] - xd[:, 0, None], det_xy[cols, 1][None, :] - xd[:, 1, None]
        )
        reachable = deviation <= reach[:, None]
        rows, picked = assign(np.where(sized & reachable, cost, np.inf))
        room = max(c.max_tracks - int(np.count_nonzero(st.live)), 0)
        if rows.shape[0] > room:
            # A re-identified track is live again: never more live tracks than max_tracks.
            best = np.argsort(cost[rows, picked], kind="stable")[:room]
            rows, picked = rows[np.sort(best)], picked[np.sort(best)]
        slots = dormant[rows]
        st.x[slots], st.p[slots] = xd[rows], pd[rows]
        return slots, cols[picked], c.reid_max_accel_mps2 * horizon[rows]

    def snapshot(self) -> Tracks:
        """The current tracks (live and dormant) ordered by ID, with their features."""
        c, st = self.config, self.store
        slots = np.flatnonzero(st.status != FREE)
        slots = slots[np.argsort(st.track_id[slots], kind="stable")]
        last_t = st.hist_t[slots, -1:]
        window = st.hist_t[slots] >= last_t - c.decel_window_s - 1e-9
        t = np.where(window, st.hist_t[slots] - last_t, 0.0)
        v = np.where(window, st.hist_speed[slots], 0.0)
        k = window.sum(axis=1)
        kk = np.maximum(k, 1)
        t_mean = t.sum(axis=1) / kk
        v_mean = v.sum(axis=1) / kk
        dt_c = np.where(window, t - t_mean[:, None], 0.0)
        sxx = (dt_c * dt_c).sum(axis=1)
        sxy = (dt_c * np.where(window, v - v_mean[:, None], 0.0)).sum(axis=1)
        decel = np.where((k >= 2) & (sxx > 0.0), -sxy / np.where(sxx > 0.0, sxx, 1.0), 0.0)
        sizes = st.size_wl[slots]
        have = ~np.isnan(sizes)
        n_size = np.maximum(have[:, :, 0].sum(axis=1), 1)[:, None]
        mean = np.where(have, sizes, 0.0).sum(axis=1) / n_size
        dev = np.where(have, sizes - mean[:, None, :], 0.0)
        size_var = (dev * dev).sum(axis=1).sum(axis=1) / n_size[:, 0]
        latest_wl = mean if slots.shape[0] == 0 else sizes[:, -1, :]
        dormant = st.status[slots] == TrackStatus.DORMANT
        self.last_headings = TrackHeadings(
            st.track_id[slots], st.heading[slots], st.heading_resolved[slots]
        )
        return Tracks(
            stamp_s=self.last_stamp_s if self.last_stamp_s is not None else 0.0,
            track_id=st.track_id[slots],
            status=st.status[slots],
            state=np.where(dormant[:, None], st.x_post[slots], st.x[slots]),
            covariance=np.where(dormant[:, None, None], st.p_post[slots], st.p[slots]),
            detection_index=st.detection_index[slots],
            age_frames=st.age_frames[slots],
            hits=st.hits[slots],
            misses=st.misses[slots],
            last_update_s=st.last_update_s[slots],
            width_m=latest_wl[:, 0],
            length_m=latest_wl[:, 1],
            size_variance_m2=size_var,
            decel_mps2=decel,
            history_xy_m=st.hist_xy[slots],
            history_speed_mps=st.hist_speed[slots],
            history_t_s=st.hist_t[slots],
            history_len=st.hist_len[slots],
            max_width_m=st.max_wl[slots, 0],
            max_length_m=st.max_wl[slots, 1],
            reid_count=st.reid_count[slots],
            history_end_xy_m=st.hist_end[slots],
            history_end_occluded=st.hist_occ[slots],
        )

    def correct(self, track_id: IntArray, state: FloatArray, covariance: FloatArray) -> int:
        """Replace the filtered state and covariance of the live tracks ``track_id`` by ones
        another sensor refined at this cycle's stamp (the radar's Doppler and position updates,
        SR-FUS-7), so the refinement persists into the next prediction; returns how many were
        written. Dormant and unknown IDs are left alone. A track updated by this cycle's scan
        keeps the refined state as its last posterior too."""
        st = self.store
        ids = np.asarray(track_id, dtype=np.int64)
        live = np.flatnonzero(st.live)
        slot_of = dict(zip(st.track_id[live].tolist(), live.tolist(), strict=True))
        rows = [(k, slot_of[i]) for k, i in enumerate(ids.tolist()) if i in slot_of]
        if not rows:
            return 0
        k, slots = (np.array(v, dtype=np.int64) for v in zip(*rows, strict=True))
        st.x[slots], st.p[slots] = state[k], covariance[k]
        now = self.last_stamp_s
        updated = slots[st.last_update_s[slots] == now]
        st.x_post[updated], st.p_post[updated] = st.x[updated], st.p[updated]
        return int(slots.shape[0])
