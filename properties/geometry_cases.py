"""Convex-polygon test data for SR-SAT-*: Hypothesis strategies, the hard-case corpus, and
the two benchmark workloads (aisle swept paths; random pairs in a small area).

Randomness enters as a seeded ``numpy.random.Generator`` or through Hypothesis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from hypothesis import strategies as st

from pipeline.types import ConvexPolygons, FloatArray
from safety.geometry.polygons import convex_polygons
from safety.geometry.swept import (
    Trajectories,
    candidate_trajectories,
    rectangle_footprint,
    swept_hulls,
)

__all__ = [
    "HARD_CASES",
    "AisleWorkload",
    "HardCase",
    "PairDraw",
    "aisle_workload",
    "convex_points",
    "polygon_pairs",
    "random_pairs_workload",
]


# ------------------------------------------------------------------------- strategies
def _ring(
    center: tuple[float, float], scale: float, angles: list[float], radii: list[float]
) -> FloatArray:
    pts = np.array(
        [[math.cos(a) * r, math.sin(a) * r] for a, r in zip(sorted(angles), radii, strict=True)]
    )
    out: FloatArray = pts * scale + np.asarray(center)
    return out


_SLOTS = 48


@st.composite
def convex_points(
    draw: st.DrawFn, *, min_scale_exp: float = -3.0, max_scale_exp: float = 3.0
) -> FloatArray:
    """Points of a convex-ish polygon (3-8 points on a jittered ring), any scale/position."""
    k = draw(st.integers(3, 8), label="k")
    # Distinct angular slots at least 2*pi/96 apart: unique floats alone allowed angles 1e-300
    # apart, i.e. coincident or collinear rings that are not polygons at all (the hard-case
    # corpus covers slivers and near-collinear vertices on purpose).
    slots = draw(
        st.lists(st.integers(0, _SLOTS - 1), min_size=k, max_size=k, unique=True), label="slots"
    )
    jitter = draw(st.lists(st.floats(0.0, 0.5), min_size=k, max_size=k), label="angular jitter")
    angles = [(s + j) * 2 * math.pi / _SLOTS for s, j in zip(slots, jitter, strict=True)]
    radii = draw(st.lists(st.floats(0.3, 1.0), min_size=k, max_size=k), label="radii")
    scale = 10.0 ** draw(st.floats(min_scale_exp, max_scale_exp), label="log10 scale")
    offset = 10.0 ** draw(st.floats(-3.0, 3.0), label="log10 offset")
    heading = draw(st.floats(0.0, 2 * math.pi), label="offset direction")
    centre = (offset * math.cos(heading), offset * math.sin(heading))
    ring: FloatArray = _ring(centre, scale, angles, radii)
    return ring


def _spread_ok(points: FloatArray) -> bool:
    # Reject rings whose points are (nearly) collinear: no polygon to test.
    centred = points - points.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    return bool(sv[-1] > 1e-6 * max(sv[0], 1e-300))


GAPS_M = (0.0, 0.0, 1e-12, -1e-12, 1e-7, -1e-7, 1e-3, -1e-3)


@dataclass(frozen=True)
class PairDraw:
    """Two convex polygons (as normalised (k, 2) vertex arrays) and how they were placed."""

    a: FloatArray
    b: FloatArray
    placement: str
    gap_m: float
    scale_m: float


@st.composite
def polygon_pairs(draw: st.DrawFn) -> PairDraw:
    """A pair of convex polygons at one scale (1e-3 m .. 1e3 m) and position.

    Placement: ``random`` (independent positions near each other), or ``contact``: B moved
    along a chosen edge normal of A so that the gap along it is one of ``GAPS_M`` (plus
    rounding), which puts many pairs within a hair of contact.
    """
    scale_exp = draw(st.floats(-3.0, 3.0), label="log10 scale")
    a_pts = draw(convex_points(min_scale_exp=scale_exp, max_scale_exp=scale_exp), label="A")
    b_pts = draw(convex_points(min_scale_exp=scale_exp, max_scale_exp=scale_exp), label="B")
    if not (_spread_ok(a_pts) and _spread_ok(b_pts)):
        b_pts = a_pts[::-1].copy() if _spread_ok(a_pts) else np.array([[0, 0], [1, 0], [0, 1.0]])
        a_pts = a_pts if _spread_ok(a_pts) else np.array([[0, 0], [1, 0], [0, 1.0]])
    polys = convex_polygons([a_pts, b_pts])
    a, b = polys.vertex_list(0), polys.vertex_list(1)
    scale = 10.0**scale_exp
    placement = draw(
        st.sampled_from(["random", "contact", "contact", "contact"]), label="placement"
    )
    gap = 0.0
    if placement == "random":
        shift = np.array(draw(st.tuples(st.floats(-2, 2), st.floats(-2, 2)), label="shift"))
        b = b - b.mean(axis=0) + a.mean(axis=0) + shift * scale
    else:
        edge = draw(st.integers(0, len(a) - 1), label="edge")
        gap = draw(st.sampled_from(GAPS_M), label="gap")
        p0, p1 = a[edge], a[(edge + 1) % len(a)]
        n = np.array([p1[1] - p0[1], p0[0] - p1[0]])
        n /= np.hypot(*n)
        slide = draw(st.floats(-0.5, 0.5), label="slide") * scale
        tangent = np.array([-n[1], n[0]])
        top = float(p0 @ n)
        low = float((b @ n).min())
        b = b + n * (top - low + gap) + tangent * slide
    polys = convex_polygons([a, b])
    return PairDraw(polys.vertex_list(0), polys.vertex_list(1), placement, gap, scale)


# ------------------------------------------------------------------------ hard cases
@dataclass(frozen=True)
class HardCase:
    """A named pair and what exact arithmetic says about it (``touch`` counts as overlap)."""

    name: str
    a: FloatArray
    b: FloatArray
    exact: str  # "overlap", "touch" or "clear"


def _box(x0: float, y0: float, x1: float, y1: float) -> FloatArray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]])


def _diamond(cx: float, cy: float, r: float) -> FloatArray:
    return np.array([[cx + r, cy], [cx, cy + r], [cx - r, cy], [cx, cy - r]])


def _hard_cases() -> list[HardCase]:
    unit = _box(0, 0, 1, 1)
    big = 1e5
    tiny = 1e-6
    return [
        HardCase("vertex touch", unit, _box(1, 1, 2, 2), "touch"),
        HardCase("edge touch", unit, _box(1, 0, 2, 1), "touch"),
        HardCase("edge touch, offset", unit, _box(1, 0.5, 2, 1.5), "touch"),
        HardCase("vertex on edge", unit, _diamond(1.5, 0.5, 0.5), "touch"),
        HardCase("gap 1e-7", unit, _box(1 + 1e-7, 0, 2, 1), "clear"),
        HardCase("gap 1e-12", unit, _box(1 + 1e-12, 0, 2, 1), "clear"),
        HardCase("overlap 1e-7", unit, _box(1 - 1e-7, 0, 2, 1), "overlap"),
        HardCase("overlap 1e-12", unit, _box(1 - 1e-12, 0, 2, 1), "overlap"),
        HardCase("diagonal vertex gap 1e-7", _diamond(0, 0, 1), _diamond(2 + 1e-7, 0, 1), "clear"),
        HardCase("diagonal vertex touch", _diamond(0, 0, 1), _diamond(2, 0, 1), "touch"),
        HardCase("corner-to-corner gap 1e-7", unit, _box(1 + 1e-7, 1 + 1e-7, 2, 2), "clear"),
        HardCase(
            "sliver crossing box",
            np.array([[-1.0, 0.5], [2.0, 0.5], [2.0, 0.5 + 1e-9]]),
            unit,
            "overlap",
        ),
        HardCase(
            "sliver tip gap 1e-7",
            np.array([[-1.0, 0.0], [0.0, 0.5], [-1.0, 0.5 + 1e-6]]),
            _box(1e-7, 0, 1, 1),
            "clear",
        ),
        HardCase(
            "slivers crossing",
            np.array([[-1.0, -1e-6], [1.0, 1e-6 - 1e-12], [1.0, 1e-6], [-1.0, -1e-6 + 1e-12]]),
            np.array([[-1e-6, -1.0], [1e-6, -1.0], [1e-6 + 1e-12, 1.0], [-1e-6 + 1e-12, 1.0]]),
            "overlap",
        ),
        HardCase(
            "nearly collinear vertex",
            np.array([[0.0, 0.0], [0.5, -1e-13], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
            _box(0.2, -1.0, 0.8, -1e-7),
            "clear",
        ),
        HardCase(
            "nearly collinear vertex touch",
            np.array([[0.0, 0.0], [0.5, -1e-13], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]),
            _box(0.2, -1.0, 0.8, -1e-13),
            "touch",
        ),
        HardCase(
            "huge coordinates gap 1e-7",
            _box(big, big, big + 1, big + 1),
            _box(big + 1 + 1e-7, big, big + 2, big + 1),
            "clear",
        ),
        HardCase(
            "huge coordinates overlap 1e-9",
            _box(big, big, big + 1, big + 1),
            _box(big + 1 - 1e-9, big, big + 2, big + 1),
            "overlap",
        ),
        HardCase(
            "huge coordinates touch",
            _box(big, big, big + 1, big + 1),
            _box(big + 1, big + 0.5, big + 2, big + 1.5),
            "touch",
        ),
        HardCase(
            "tiny polygons gap 1e-12",
            _box(0, 0, tiny, tiny),
            _box(tiny + 1e-12, 0, 2 * tiny, tiny),
            "clear",
        ),
        HardCase(
            "tiny polygons touch",
            _box(0, 0, tiny, tiny),
            _box(tiny, tiny, 2 * tiny, 2 * tiny),
            "touch",
        ),
        HardCase(
            "tiny next to huge, gap 1e-7",
            _box(0, 0, 1000, 1000),
            _box(1000 + 1e-7, 500, 1000 + 1e-7 + 1e-3, 500 + 1e-3),
            "clear",
        ),
        HardCase("identical", unit, unit.copy(), "overlap"),
        HardCase("nested", _box(-5, -5, 5, 5), _box(-1e-3, -1e-3, 1e-3, 1e-3), "overlap"),
        HardCase(
            "crossing bars (no vertex inside)",
            _box(-2, -0.1, 2, 0.1),
            _box(-0.1, -2, 0.1, 2),
            "overlap",
        ),
        HardCase("far apart", unit, _box(30, 30, 31, 31), "clear"),
    ]


HARD_CASES: tuple[HardCase, ...] = tuple(_hard_cases())


# ------------------------------------------------------------------------- workloads
@dataclass(frozen=True)
class AisleWorkload:
    """175 candidate trajectories of a robot in a warehouse aisle and 20 obstacle envelopes."""

    footprint: ConvexPolygons
    trajectories: Trajectories
    hulls: ConvexPolygons
    obstacles: ConvexPolygons


def _octagon(cx: float, cy: float, r: float) -> FloatArray:
    a = np.arange(8) * (np.pi / 4) + np.pi / 8
    return np.column_stack([cx + r * np.cos(a), cy + r * np.sin(a)])


def aisle_workload(rng: np.random.Generator) -> AisleWorkload:
    """Robot at the origin heading +x in a 2.5 m aisle lined by racks; 20 envelopes.

    Racks (1 m deep, 2.4-3 m long) line both sides from -6 m to 40 m, a reversing forklift's
    envelope and two people are in the aisle ahead; most pairs are far apart, a few racks
    are within reach of the sharpest turns.
    """
    shapes: list[FloatArray] = []
    xs = np.sort(rng.uniform(-6.0, 40.0, size=14))
    for i, x in enumerate(xs):
        side = 1.0 if i % 2 == 0 else -1.0
        length = rng.uniform(2.4, 3.0)
        y0 = side * (1.25 + rng.uniform(0.0, 0.15))
        y1 = y0 + side * 1.0
        shapes.append(_box(x, min(y0, y1), x + length, max(y0, y1)))
    shapes.append(_box(9.0, -0.9, 11.5, 0.5))  # reversing forklift, inflated 0.4 m
    shapes.append(_octagon(2.2, 0.9, 0.7))  # person, 0.3 m body + 0.4 m margin
    shapes.append(_octagon(16.0, -0.6, 0.7))
    shapes.append(_octagon(-3.0, 0.0, 0.7))  # person behind the robot
    shapes.append(_box(22.0, -0.4, 23.2, 0.4))  # pallet
    shapes.append(_octagon(30.0, 0.5, 1.0))  # near-reversal envelope (1.0 m margin)
    footprint = rectangle_footprint(0.7, 0.5)
    trajectories = candidate_trajectories(horizon_s=1.5, step_s=0.1)
    return AisleWorkload(
        footprint=footprint,
        trajectories=trajectories,
        hulls=swept_hulls(footprint, trajectories),
        obstacles=convex_polygons(shapes[:20]),
    )


def random_pairs_workload(
    rng: np.random.Generator, n: int = 3500, area_m: float = 3.0
) -> tuple[ConvexPolygons, ConvexPolygons]:
    """``n`` matched pairs of random convex polygons (3-8 vertices, radius 0.2-1 m) whose
    centres are uniform in an ``area_m`` square: many overlaps."""

    def batch() -> ConvexPolygons:
        k = rng.integers(3, 9, size=n)
        pts = np.zeros((n, 8, 2))
        for i in range(n):
            ang = np.sort(rng.uniform(0, 2 * np.pi, k[i]))
            r = rng.uniform(0.2, 1.0) * rng.uniform(0.5, 1.0, k[i])
            pts[i, : k[i]] = np.column_stack([np.cos(ang) * r, np.sin(ang) * r])
        pts += rng.uniform(0, area_m, size=(n, 1, 2))
        return convex_polygons(pts, k)

    return batch(), batch()
