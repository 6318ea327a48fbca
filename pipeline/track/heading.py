"""Each track's heading: the detections' box axes, smoothed, with the 180 deg flip resolved
(SR-TRK-7).

A detection's box gives an *axis*: the direction of its longer side modulo pi
(:class:`pipeline.types.Clusters`), and a rectangle's sides are only known modulo pi/2 when a
partial view makes the seen length shorter than the width. The track turns axes into a heading
in [-pi, pi) against a reference direction:

* the track's velocity, when its speed is at least ``track.heading_flip_speed_mps`` and at
  least :data:`CERTAIN_SIGMAS` standard deviations of the filter's velocity estimate, and it
  points along the box's axis within :data:`ALONG_AXIS_RAD` (a vehicle moves along its
  heading; the flip is then *resolved*). A new track's uncertain velocity, a parked vehicle's
  noise, a centroid sliding as an occluder passes, resolve nothing; nor does the velocity of a
  track that has not settled yet, whose centroid still moves as more of the object comes into
  view;
* else the velocity too, when it is that certain and at least ``track.heading_side_speed_mps``
  but slower than the flip speed or across the axis: it chooses the side (a vehicle seen end-on
  shows its back as its longer side), its direction turned to the heading history's half-plane,
  without resolving the flip;
* else the track's own smoothed heading so far (its heading history: a slow or stopped
  vehicle keeps the direction it had);
* else (a new track) the axis itself, unresolved.

Of the four directions ``axis + k pi/2`` the one nearest the reference is taken, and the track's
heading moves towards it by the gain ``track.heading_smoothing`` (exponential smoothing on the
circle). The first time the velocity resolves the flip, the heading jumps to that direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import TrackSection
from pipeline.types import BoolArray, FloatArray, IntArray, freeze_fields

__all__ = [
    "ALONG_AXIS_RAD",
    "CERTAIN_SIGMAS",
    "TrackHeadings",
    "nearest_side",
    "update_headings",
    "wrap_pi",
]

CERTAIN_SIGMAS = 2.0
"""How many standard deviations of the velocity estimate the speed must exceed before its
direction counts (one-sided, about 98 % for a Gaussian)."""

ALONG_AXIS_RAD = 0.5
"""How far (about 29 deg) the velocity may point from the box's axis (modulo pi) and still
resolve the flip: a vehicle drives along its long side. A velocity across the box comes from a
view that changes (an occluder passing, more of the object coming into sight) or from a box
whose long side is not the one seen; it resolves nothing."""


@dataclass(frozen=True, slots=True)
class TrackHeadings:
    """The heading of each track of one snapshot (same rows and order as its
    :class:`pipeline.types.Tracks`): ``heading_rad`` in [-pi, pi) in the tracking frame (NaN
    while no detection carried an axis), ``resolved`` True once the velocity has fixed the
    direction (else the heading may be off by pi)."""

    track_id: IntArray
    heading_rad: FloatArray
    resolved: BoolArray

    def __post_init__(self) -> None:
        freeze_fields(self, ("track_id",), np.int64)
        freeze_fields(self, ("heading_rad",), np.float64)
        freeze_fields(self, ("resolved",), np.bool_)
        n = self.track_id.shape
        if self.heading_rad.shape != n or self.resolved.shape != n:
            raise ValueError(f"TrackHeadings: heading_rad and resolved must have shape {n}")


def wrap_pi(angle: FloatArray) -> FloatArray:
    """Angles in [-pi, pi)."""
    wrapped: FloatArray = np.mod(angle + math.pi, 2.0 * math.pi) - math.pi
    return wrapped


def nearest_side(axis_rad: FloatArray, reference_rad: FloatArray) -> FloatArray:
    """Of ``axis + k pi/2`` (k integer), the direction nearest ``reference_rad``, in [-pi, pi)."""
    quarter = 0.5 * math.pi
    k = np.round(wrap_pi(reference_rad - axis_rad) / quarter)
    return wrap_pi(axis_rad + k * quarter)


def update_headings(
    heading_rad: FloatArray,
    resolved: BoolArray,
    axis_rad: FloatArray,
    velocity_mps: FloatArray,
    velocity_std_mps: FloatArray,
    settled: BoolArray,
    config: TrackSection,
) -> tuple[FloatArray, BoolArray]:
    """New ``(heading_rad, resolved)`` of tracks updated by detections with box axes
    ``axis_rad`` (NaN: no axis, heading kept), given their filtered velocities (k, 2) and the
    largest standard deviation of each; only ``settled`` tracks' velocities count (module
    docstring)."""
    speed = np.hypot(velocity_mps[:, 0], velocity_mps[:, 1])
    certain = settled & (speed >= CERTAIN_SIGMAS * velocity_std_mps) & (speed > 0.0)
    steers = certain & (speed >= config.heading_side_speed_mps)
    moving = certain & (speed >= config.heading_flip_speed_mps)
    have = ~np.isnan(axis_rad)
    known = ~np.isnan(heading_rad)
    course = np.arctan2(velocity_mps[:, 1], velocity_mps[:, 0])
    across = np.abs(wrap_pi(2.0 * (course - np.where(have, axis_rad, course)))) / 2.0
    moving &= across <= ALONG_AXIS_RAD
    # Steering keeps the direction the history has: it picks the side, not the flip.
    behind = known & (
        np.abs(wrap_pi(course - np.where(known, heading_rad, course))) > 0.5 * math.pi
    )
    steer = np.where(behind, course + math.pi, course)
    history = np.where(known, heading_rad, axis_rad)
    reference = np.where(moving, course, np.where(steers, steer, history))
    side = nearest_side(np.where(have, axis_rad, 0.0), np.where(have, reference, 0.0))
    jump = (moving & ~resolved) | ~known
    smoothed = wrap_pi(heading_rad + config.heading_smoothing * wrap_pi(side - heading_rad))
    new = np.where(have, np.where(jump, side, smoothed), heading_rad)
    new_resolved: BoolArray = np.where(have, resolved | moving, resolved)
    return new, new_resolved
