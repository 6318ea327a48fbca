"""A grown polygon is the convex hull of its Minkowski points, bit for bit (SR-PRED-1, SR-SAT-4).

:func:`safety.geometry.envelopes.grown_polygons` reads the polygon of a row whose reach is one
point (a still object's body, a pedestrian's disc) straight off its Minkowski points instead of
running the hull, when the disc is wide against rounding at the row's coordinates. Whatever
the batch (single points beside sectors and discs, any coordinates the hull accepts, radii
from a nanometre up, any number of sides the configuration allows), the result must be the
hull's: the same vertices in the same order and padding, the same counts and slack, and the
same error naming the same row where the hull refuses the batch.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.constructive import disc_points, minkowski, sector_points
from pipeline.errors import GeometryError
from pipeline.types import ConvexPolygons, FloatArray
from safety.geometry import envelopes
from safety.geometry.envelopes import ROUNDING_M, grown_polygons
from safety.geometry.polygons import convex_polygons

ENVELOPES = ["safety/geometry/envelopes.py"]


@st.composite
def reach_batches(draw: st.DrawFn) -> tuple[FloatArray, FloatArray, int]:
    """(reach (n, P, 2), radius_m (n,), sides): sector reach regions, a share of them single
    points (a zero-radius sector), at one scale from a centimetre to beyond the largest
    coordinate the hull accepts."""
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    n = draw(st.integers(1, 8))
    sides = draw(st.integers(6, 64))
    scale = 10.0 ** draw(st.floats(-2.0, 6.2))
    cx, cy = rng.uniform(-scale, scale, n), rng.uniform(-scale, scale, n)
    reach_r = 10.0 ** rng.uniform(-10.0, 1.0, n) * (rng.random(n) < 0.5)
    heading = np.where(rng.random(n) < 0.5, rng.uniform(-4.0, 4.0, n), np.nan)
    half = rng.uniform(0.0, 1.6, n)
    reach = sector_points(cx, cy, heading, half, reach_r, 0.3, sides)
    radius = 10.0 ** rng.uniform(-10.0, 1.0, n)
    return reach, radius, sides


def _hull_of_points(reach: FloatArray, radius: FloatArray, sides: int) -> ConvexPolygons | str:
    """The reference: the hull of the Minkowski points, or the error it raises."""
    n = reach.shape[0]
    discs = disc_points(np.zeros(n), np.zeros(n), radius + ROUNDING_M, sides)
    try:
        return convex_polygons(minkowski(reach, discs))
    except GeometryError as error:
        return f"{type(error).__name__}: {error}"


def _grown(reach: FloatArray, radius: FloatArray, sides: int) -> ConvexPolygons | str:
    try:
        return grown_polygons(reach, radius, sides)
    except GeometryError as error:
        return f"{type(error).__name__}: {error}"


@pytest.mark.requirement("SR-PRED-1", kind="property", code=ENVELOPES)
@pytest.mark.requirement("SR-SAT-4", kind="property", code=ENVELOPES)
@settings(max_examples=examples(400))
@given(batch=reach_batches())
@example(
    batch=(
        np.array([[[3.0, -2.0]] * 4, [[1.0, 1.0], [2.0, 1.0], [2.0, 2.0], [1.0, 2.0]]]),
        np.array([0.35, 0.2]),
        12,
    )
)
# a body beside one beyond the coordinates the hull accepts: the hull names the far row
@example(batch=(np.array([[[1.0, 1.0]], [[-1.0e6, 2.0]]]), np.array([0.5, 20.0]), 12))
# a body beside a far triangle whose disc rounds away (4 vertices): the triangle is padded
@example(
    batch=(
        np.array([[[1.0, 1.0]] * 3, [[9.0e5, 2.0], [9.0e5 + 3.0, 2.0], [9.0e5, 5.0]]]),
        np.array([0.5, 0.0]),
        12,
    )
)
def test_a_grown_polygon_is_the_hull_of_its_points(
    batch: tuple[FloatArray, FloatArray, int],
) -> None:
    reach, radius, sides = batch
    got, want = _grown(reach, radius, sides), _hull_of_points(reach, radius, sides)
    rec = current()
    single = int((reach == reach[:, :1]).all(axis=(1, 2)).sum())
    rec.count("rows", "single point", single)
    rec.count("rows", "region", reach.shape[0] - single)
    if isinstance(want, str) or isinstance(got, str):
        rec.count("batches", "refused by the hull")
        assert got == want
        return
    rec.count("batches", "built")
    assert isinstance(got, ConvexPolygons)
    np.testing.assert_array_equal(got.vertices_m, want.vertices_m)
    np.testing.assert_array_equal(got.counts, want.counts)
    np.testing.assert_array_equal(got.slack_m, want.slack_m)


@pytest.mark.requirement("SR-PRED-1", kind="example", code=ENVELOPES)
def test_a_body_disc_starts_at_its_lowest_x_vertex() -> None:
    """Two bodies (one point each) and the order the hull gives them: counter-clockwise from
    the lowest-x vertex (ties to the lower one), padded with that vertex."""
    centre = np.array([[[2.0, 1.0]], [[-4.0, 0.5]]])
    got = grown_polygons(centre, np.array([0.5, 0.25]), 6)
    outer = (np.array([0.5, 0.25]) + ROUNDING_M) / math.cos(math.pi / 6)
    assert got.counts.tolist() == [6, 6]
    assert got.slack_m.tolist() == [0.0, 0.0]
    for k in range(2):
        x, y = got.vertices_m[0, :, k], got.vertices_m[1, :, k]
        # the two lowest-x vertices of a hexagon with vertices at 30 + 60 j deg: 150 and 210
        assert x[0] == pytest.approx(centre[k, 0, 0] - outer[k] * math.cos(math.pi / 6))
        assert y[0] < centre[k, 0, 1]
        assert y[-1] > centre[k, 0, 1]
        turn = (x - x.mean()) * np.roll(y - y.mean(), -1) - (y - y.mean()) * np.roll(
            x - x.mean(), -1
        )
        assert (turn > 0).all()


def _hulled_rows(
    monkeypatch: pytest.MonkeyPatch, reach: FloatArray, radius: FloatArray, sides: int
) -> int:
    """How many rows of one grown_polygons call went through the hull (the rest were read off)."""
    rows: list[int] = []

    def counting(points: FloatArray) -> ConvexPolygons:
        rows.append(int(np.asarray(points).shape[0]))
        return convex_polygons(points)

    monkeypatch.setattr(envelopes, "convex_polygons", counting)
    grown_polygons(reach, radius, sides)
    monkeypatch.undo()
    return sum(rows)


@pytest.mark.requirement("SR-PRED-1", kind="example", code=ENVELOPES)
def test_only_rows_that_are_not_a_wide_disc_go_through_the_hull(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Bodies alone never run the hull; beside a region only the region does; at 1 km a disc
    2 % wider than the width threshold (2 R sin^2(pi/n) >= 1e-6 of the coordinates) is read
    off and one 2 % narrower is hulled, while at 1 m a 1 mm disc is read off."""
    sides = 12
    factor = 2.0 * math.sin(math.pi / sides) ** 2
    bodies = np.array([[[3.0, 1.0]], [[-2.0, 0.5]], [[0.0, 7.0]]])
    assert _hulled_rows(monkeypatch, bodies, np.array([0.4, 0.3, 0.25]), sides) == 0
    sector = sector_points(
        np.array([1.0]), np.array([2.0]), np.array([0.3]), np.array([0.2]), np.array([1.5]),
        0.3, sides,
    )  # fmt: skip
    mixed = np.concatenate([np.repeat(bodies[:2], sector.shape[1], axis=1), sector])
    assert _hulled_rows(monkeypatch, mixed, np.array([0.4, 0.3, 0.25]), sides) == 1
    centre = np.array([[[1000.0, 0.0]], [[1000.0, 0.0]], [[1.0, 0.0]]])
    wide, narrow = (1.02e-3 / factor, 0.98e-3 / factor)  # against 1e-6 x 1000 m
    radius = np.array([wide, narrow, 1e-3])
    assert _hulled_rows(monkeypatch, centre, radius, sides) == 1
