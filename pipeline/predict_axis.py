"""Reach regions along a vehicle's body axis, either way (SR-PRED-4).

A slow vehicle's velocity says little about where it will go (its direction is mostly the
noise of the filter), but its body does: a vehicle moves along its body axis, forwards or
backwards, turning by at most the cone's half-angle ``alpha`` (``predict.cone_half_angle_deg``)
within the horizon. The track's heading ``h`` (:class:`pipeline.track.heading.TrackHeadings`)
gives that axis; which way the vehicle faces is not trusted (a slow vehicle's heading is
flipped in 13-26 % of samples, docs/findings/tracking-airside.md), so both ways are kept.

If every velocity of the object over the horizon has speed at most ``s`` and points within
``alpha`` of ``h`` or of ``h + pi``, its displacement after a time ``t <= H`` is ``t`` times the
mean of those velocities, which lies in the convex hull of the two sectors of radius ``s``
about ``h`` and ``h + pi`` (both hold the origin, and a mean of points of a set lies in its
hull). So the reference point stays in the hull of the two sectors of radius ``s H`` about its
position: :func:`axis_points`. The region is symmetric about its apex and, for ``alpha`` below
90 deg, a small part of the disc of radius ``s H`` that the same track gets without an axis.

Which tracks may use their axis: :func:`body_axes`.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.config import PredictSection
from pipeline.constructive import sector_points
from pipeline.roles import HeadingRows
from pipeline.types import BoolArray, FloatArray

__all__ = ["axis_points", "body_axes"]


def body_axes(
    headings: HeadingRows | None, person_compatible: BoolArray, section: PredictSection
) -> FloatArray:
    """Per track: the body axis [rad] the prediction may use, NaN where it may not.

    NaN everywhere with ``predict.heading_source = "motion"``, without headings, or with a cone
    of 90 deg or more (the sectors are then discs already); NaN for a track whose heading is
    unknown and for a track that may be a person (``person_compatible``: a person has no body
    axis and turns on the spot, SR-CLS-8). ``headings`` has the tracks' rows.
    """
    n = person_compatible.shape[0]
    cone = math.radians(section.cone_half_angle_deg)
    if section.heading_source != "track" or headings is None or cone >= 0.5 * math.pi:
        return np.full(n, np.nan)
    axes: FloatArray = np.where(person_compatible, np.nan, headings.heading_rad)
    return axes


def axis_points(
    cx: FloatArray,
    cy: FloatArray,
    axis_rad: FloatArray,
    half_angle_rad: float,
    radius_m: FloatArray,
    arc_step_rad: float,
    disc_sides: int,
) -> FloatArray:
    """(n, 2 (m + 2), 2) counter-clockwise vertices of the hull of the two circular sectors
    (apex ``(cx, cy)``, radius ``radius_m``, half-angle ``half_angle_rad``) about ``axis_rad`` and
    ``axis_rad + pi``; ``m = ceil(2 half / arc_step_rad)`` (at least 1) arc pieces per sector.

    Each sector's arc is drawn as :func:`pipeline.constructive.sector_points` draws it (tangent
    lines, so the polygon holds the arc); the apex lies on the segment between the two arcs'
    start points and is left out. ``axis_rad`` must be finite and the half-angle in [0, 90 deg).
    """
    if not 0.0 <= half_angle_rad < 0.5 * math.pi:
        raise ValueError(f"axis_points: half-angle {half_angle_rad} rad not in [0, pi/2)")
    if not np.isfinite(axis_rad).all():
        raise ValueError("axis_points: every axis must be finite")
    n = cx.shape[0]
    half = np.full(n, half_angle_rad)
    ahead = sector_points(cx, cy, axis_rad, half, radius_m, arc_step_rad, disc_sides)
    behind = sector_points(cx, cy, axis_rad + math.pi, half, radius_m, arc_step_rad, disc_sides)
    # sector_points lists the apex, the arc's start, its pieces' outer points and its end.
    pieces = max(math.ceil(2.0 * half_angle_rad / arc_step_rad), 1)
    arc = slice(1, pieces + 3)
    points: FloatArray = np.concatenate([ahead[:, arc], behind[:, arc]], axis=1)
    return points
