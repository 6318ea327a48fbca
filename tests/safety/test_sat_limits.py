"""The SAT check stage by stage: which step decides a pair, the tolerance and slack in each,
both table orientations, and the checks of its input (SR-SAT-1, SR-SAT-4, SR-SAT-6).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) asks of every step of
the kernel whether a test would notice it changed. The verdicts alone rarely do (the steps
only decide pairs sooner, never differently), so these cases pin which step decided each
pair (``SatChecker.stats``), and put pairs at the tolerance band's edges along an axis, along
the centre line and along an edge normal that only the full test tries.
"""

from __future__ import annotations

import re
from typing import Any

import numpy as np
import pytest
import shapely

from pipeline.types import ConvexPolygons, FloatArray
from safety.geometry.polygons import GeometryError, convex_polygons
from safety.geometry.sat import (
    CHUNK_PAIRS,
    FULL_CHUNK_PAIRS,
    SatChecker,
    SatStats,
    _column_max,
)

SAT = ["safety/geometry/sat.py"]
TOL_M = 2.0**-10


def _polygons(rings: list[list[list[float]]], slack_m: list[float] | None = None) -> ConvexPolygons:
    polys = convex_polygons([np.array(r, dtype=np.float64) for r in rings])
    if slack_m is None:
        return polys
    return ConvexPolygons(polys.vertices_m, polys.counts, np.array(slack_m, dtype=np.float64))


def _square(x0: float, y0: float, side: float = 1.0) -> list[list[float]]:
    return [[x0, y0], [x0 + side, y0], [x0 + side, y0 + side], [x0, y0 + side]]


# One pair per deciding step (A side, B side, verdict, the step):
BOX = (_square(0.0, 0.0), _square(3.0, 0.0), False, "box")
# Boxes of one size offset along the diagonal: the line through their centres separates them.
CENTRE = (
    [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
    [[1.25, 0.25], [1.25, 1.25], [0.25, 1.25]],
    False,
    "centre_line",
)
# A's corner (1, 1), farthest towards B, lies inside B: an overlap proved by a common point.
CERTIFICATE = (_square(0.0, 0.0), _square(0.5, 0.5), True, "certificate")
# Beyond the hypotenuse x + 4y = 4 of A: only that edge's normal separates them.
FULL_CLEAR = (
    [[0.0, 0.0], [4.0, 0.0], [0.0, 1.0]],
    [[2.125, 0.625], [2.375, 0.625], [2.375, 0.875], [2.125, 0.875]],
    False,
    "full_sat",
)
# A cross: the same box centre, no vertex of either inside the other, overlapping.
FULL_HIT = (
    [[0.0, 0.0], [10.0, 0.0], [10.0, 1.0], [0.0, 1.0]],
    [[4.5, -3.0], [5.5, -3.0], [5.5, 4.0], [4.5, 4.0]],
    True,
    "full_sat",
)
CASES = [BOX, CENTRE, CERTIFICATE, FULL_CLEAR, FULL_HIT]


def _stats(**decided: int) -> dict[str, int]:
    counts = {"box": 0, "centre_line": 0, "certificate": 0, "full_sat": 0} | decided
    return {"pairs": sum(counts.values()), **counts}


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize(
    "case", CASES, ids=["box", "centre line", "certificate", "full, clear", "full, overlap"]
)
def test_each_step_decides_its_pair_in_either_order(
    case: tuple[list[list[float]], list[list[float]], bool, str],
) -> None:
    a_ring, b_ring, verdict, step = case
    checker = SatChecker(TOL_M)
    for first, second in ((a_ring, b_ring), (b_ring, a_ring)):
        a, b = _polygons([first]), _polygons([second])
        assert checker.overlap_pairs(a, b).tolist() == [verdict]
        assert checker.stats.as_dict() == _stats(**{step: 1})
        assert checker.overlap_all(a, b).tolist() == [[verdict]]
        assert checker.stats.as_dict() == _stats(**{step: 1})


@pytest.mark.requirement("SR-SAT-6", kind="example", code=SAT)
def test_the_all_pairs_table_in_both_orientations_and_its_stages() -> None:
    """Five A polygons against three B polygons and the transpose: the table equals the pair
    by pair verdicts, whichever side is longer, and every pair is counted at one stage."""
    a = _polygons([c[0] for c in CASES])
    b = _polygons([CASES[0][1], CASES[2][1], CASES[4][1]])
    checker = SatChecker(TOL_M)
    expected = [
        [bool(checker.overlap_pairs(a.take([i]), b.take([j]))[0]) for j in range(b.n)]
        for i in range(a.n)
    ]
    table = checker.overlap_all(a, b)
    assert table.tolist() == expected
    stats = checker.stats.as_dict()
    assert stats["pairs"] == 15
    assert sum(stats[k] for k in ("box", "centre_line", "certificate", "full_sat")) == 15
    assert checker.overlap_all(b, a).tolist() == table.T.tolist()
    assert checker.stats.as_dict() == stats
    ia, ib = np.divmod(np.arange(15), 3)
    assert checker.overlap_pairs(a.take(ia), b.take(ib)).tolist() == table.ravel().tolist()
    assert checker.stats.as_dict() == stats
    # The unit square and the triangle at the origin touch B's square at (0.5, 0.5) only.
    assert table[:3].tolist() == [[False, True, False]] * 3


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize("transpose", [False, True])
@pytest.mark.parametrize(
    ("copies", "interleaved"), [(40, False), (CHUNK_PAIRS // 2 + 1, True)], ids=["40", "chunked"]
)
def test_many_pairs_take_the_same_steps(transpose: bool, copies: int, interleaved: bool) -> None:
    """Copies of each pair: the same verdicts and the same deciding steps as one copy. 40 are
    enough for the kernel's wide-table maximum; CHUNK_PAIRS / 2 + 1, the cases taken in turn,
    put 4 (CHUNK_PAIRS / 2 + 1) pairs through the kernel in three chunks and twice as many
    through the edge-normal tests as FULL_CHUNK_PAIRS, each chunk holding every kind."""
    order = (
        [c for _ in range(copies) for c in CASES]
        if interleaved
        else [c for c in CASES for _ in range(copies)]
    )
    rings_a, rings_b = [c[0] for c in order], [c[1] for c in order]
    if transpose:
        rings_a, rings_b = rings_b, rings_a
    checker = SatChecker(TOL_M)
    got = checker.overlap_pairs(_polygons(rings_a), _polygons(rings_b))
    assert got.tolist() == [c[2] for c in order]
    assert checker.stats.as_dict() == _stats(
        box=copies, centre_line=copies, certificate=copies, full_sat=2 * copies
    )


@pytest.mark.requirement("SR-SAT-6", kind="example", code=SAT)
def test_a_table_of_many_near_pairs_is_decided_pair_by_pair_across_chunks() -> None:
    """A row of FULL_CLEAR-like pairs 10 m apart, each a triangle and a square 0.01 m beyond
    its hypotenuse, the squares in reverse order and each with a slack of 0 or 0.02 m (seeded):
    the all-pairs table collides exactly where a pair's own slack covers its gap, across more
    pairs than CHUNK_PAIRS and FULL_CHUNK_PAIRS, every other pair separated by its boxes."""
    n = CHUNK_PAIRS + FULL_CHUNK_PAIRS + 7
    tri, square = _beyond_the_hypotenuse(0.01)
    shift = [[10.0 * i, 0.0] for i in range(n)]
    a = _polygons([(np.array(tri) + d).tolist() for d in shift])
    slack = np.random.default_rng(3).choice([0.0, 0.02], size=n)
    b = _polygons([(np.array(square) + d).tolist() for d in shift[::-1]], slack.tolist())
    checker = SatChecker(TOL_M)
    table = checker.overlap_all(a, b)
    expected = np.zeros((n, n), dtype=bool)
    expected[np.arange(n)[::-1], np.arange(n)] = slack > 0.0  # A[n - 1 - j] with B[j]
    assert table.tolist() == expected.tolist()
    assert 0 < int(slack.sum() / 0.02) < n
    assert checker.stats.as_dict() == _stats(box=n * n - n, full_sat=n)


def _beyond_the_diagonal(gap_m: float) -> tuple[list[list[float]], list[list[float]]]:
    """A right triangle and one mirrored beyond its hypotenuse x + y = 1, ``gap_m`` away
    along the diagonal (their boxes overlap; the centre line separates them)."""
    step = gap_m / np.sqrt(2.0)
    return (
        [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]],
        [[1.0 + step, step], [1.0 + step, 1.0 + step], [step, 1.0 + step]],
    )


def _beyond_the_hypotenuse(gap_m: float) -> tuple[list[list[float]], list[list[float]]]:
    """FULL_CLEAR's triangle and a square whose corner lies ``gap_m`` beyond the hypotenuse
    x + 4y = 4 (only that edge's normal separates them)."""
    normal = np.array([1.0, 4.0]) / np.sqrt(17.0)
    corner = np.array([2.0, 0.5]) + gap_m * normal
    x0, y0 = float(corner[0]), float(corner[1])
    return FULL_CLEAR[0], [[x0, y0], [x0 + 0.25, y0], [x0 + 0.25, y0 + 0.25], [x0, y0 + 0.25]]


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize(
    ("placed", "step"),
    [
        (lambda g: (_square(0.0, 0.0), _square(1.0 + g, 0.25)), "box"),
        (lambda g: (_square(0.0, 0.0), _square(0.25, 1.0 + g)), "box"),
        (_beyond_the_diagonal, "centre_line"),
        (_beyond_the_hypotenuse, "full_sat"),
    ],
    ids=["x", "y", "centre line", "edge normal"],
)
def test_the_tolerance_band_at_each_step(placed: object, step: str) -> None:
    """Within the tolerance a pair collides, a little beyond it the step that separates it
    says clear; with tolerance 0 the pair inside the band is clear."""
    assert callable(placed)
    for order in (slice(None), slice(None, None, -1)):
        inside = _polygons(list(placed(0.999 * TOL_M))[order])
        outside = _polygons(list(placed(1.001 * TOL_M))[order])
        checker = SatChecker(TOL_M)
        pair = (inside.take([0]), inside.take([1]))
        assert checker.overlap_pairs(*pair).tolist() == [True]
        assert checker.overlap_all(*pair).tolist() == [[True]]
        apart = (outside.take([0]), outside.take([1]))
        assert checker.overlap_pairs(*apart).tolist() == [False]
        assert checker.stats.as_dict() == _stats(**{step: 1})
        assert checker.overlap_all(*apart).tolist() == [[False]]
        assert SatChecker(0.0).overlap_pairs(*pair).tolist() == [False]


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize(
    "placed",
    [_beyond_the_diagonal, _beyond_the_hypotenuse],
    ids=["centre line", "edge normal"],
)
def test_each_side_s_slack_widens_the_band(placed: object) -> None:
    """A pair 4 mm apart, clear with no slack, collides when either polygon carries 5 mm of
    slack (the bound on how far its true region may reach past its vertices); in a batch,
    each pair takes its own polygons' slack."""
    assert callable(placed)
    ring_a, ring_b = placed(0.004)
    checker = SatChecker(TOL_M)
    for slack_a, slack_b, verdict in [(0.0, 0.0, False), (0.005, 0.0, True), (0.0, 0.005, True)]:
        a = _polygons([ring_a], [slack_a])
        b = _polygons([ring_b], [slack_b])
        assert checker.overlap_pairs(a, b).tolist() == [verdict]
        assert checker.overlap_all(a, b).tolist() == [[verdict]]
        assert checker.overlap_all(b, a).tolist() == [[verdict]]
    far = _square(50.0, 50.0)  # a polygon of no pair here, with slack
    a = _polygons([far, ring_a, ring_a], [0.005, 0.0, 0.005])
    b = _polygons([ring_b, ring_b, _square(80.0, 80.0)], [0.0, 0.0, 0.005])
    assert checker.overlap_pairs(a.take([1, 2]), b.take([0, 1])).tolist() == [False, True]
    assert checker.overlap_all(a, b).tolist() == [
        [False, False, False],
        [False, False, False],
        [True, True, False],
    ]


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_the_wide_table_maximum_takes_the_first_row_of_a_tie() -> None:
    """``_column_max`` on a narrow and on a wide table (the second form: 16 columns per row
    or more): the column maximum and the flat index of its first row, ties included."""
    rng = np.random.default_rng(7)
    for k, m in [(4, 8), (4, 64), (3, 48), (5, 200)]:
        x: FloatArray = rng.integers(0, 3, (k, m)).astype(np.float64)
        x[:, 0] = 1.0  # a column tied on every row
        top, flat = _column_max(x)
        assert top.tolist() == x.max(axis=0).tolist()
        assert flat.tolist() == (np.argmax(x, axis=0) * m + np.arange(m)).tolist()


@pytest.mark.requirement("SR-SAT-4", kind="example", code=SAT)
def test_bad_input_to_the_checker_is_refused_with_the_reason() -> None:
    """The tolerance lies in [0, 1e-3] and is finite; the inputs are ConvexPolygons, matched
    pairs come in equal numbers; every message word for word."""
    assert SatChecker(0.0).tolerance_m == 0.0
    assert SatChecker(1e-3).tolerance_m == 1e-3
    assert SatChecker().tolerance_m == 1e-9
    for bad in (-1e-12, np.nextafter(1e-3, 1.0), float("nan"), float("inf")):
        expected = f"SatChecker: tolerance_m = {bad!r}; expected a number in [0, 1e-3]"
        with pytest.raises(GeometryError, match=re.escape(expected)):
            SatChecker(bad)
    polys = _polygons([_square(0.0, 0.0), _square(2.0, 0.0)])
    checker = SatChecker()
    expected = "expected ConvexPolygons (see safety.geometry.polygons.convex_polygons), got list"
    for entry in (checker.overlap_pairs, checker.overlap_all):
        with pytest.raises(GeometryError, match=re.escape("a: " + expected)):
            entry([], polys)  # type: ignore[arg-type]
        with pytest.raises(GeometryError, match=re.escape("b: " + expected)):
            entry(polys, [])  # type: ignore[arg-type]
    with pytest.raises(GeometryError, match=re.escape("overlap_pairs: 2 polygons in a but 1 in b")):
        checker.overlap_pairs(polys, polys.take([0]))


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_stats_of_no_pair_and_of_a_fresh_checker() -> None:
    checker = SatChecker()
    assert checker.stats == SatStats()
    assert checker.stats.as_dict() == _stats()
    none = convex_polygons(np.zeros((0, 3, 2)))
    assert checker.overlap_all(none, _polygons([_square(0.0, 0.0)])).shape == (0, 1)
    assert checker.stats.as_dict() == _stats()
    assert checker.overlap_pairs(none, none).shape == (0,)
    assert checker.stats.as_dict() == _stats()


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize(
    ("ring_b", "gap"),
    [
        (_square(1.0 + TOL_M, 0.25), "x"),
        (_square(0.25, 1.0 + TOL_M), "y"),
        (_square(-1.0 - TOL_M, 0.25), "-x"),
        (_square(0.25, -1.0 - TOL_M), "-y"),
    ],
)
def test_a_pair_exactly_the_tolerance_apart_along_an_axis_collides(
    ring_b: list[list[float]], gap: str
) -> None:
    """The box test is closed: a gap of exactly the tolerance (exact in binary) is inside the
    band, in either order and at both entry points."""
    a, b = _polygons([_square(0.0, 0.0)]), _polygons([ring_b])
    checker = SatChecker(TOL_M)
    for first, second in ((a, b), (b, a)):
        assert checker.overlap_pairs(first, second).tolist() == [True], gap
        assert checker.overlap_all(first, second).tolist() == [[True]], gap


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_a_touching_pair_is_not_certified_and_the_full_test_decides_it() -> None:
    """A corner of each square lies on the other's edge: no vertex is strictly inside, so no
    certificate; the full test finds no separating axis, so the pair collides."""
    a, b = _polygons([_square(0.0, 0.0)]), _polygons([_square(1.0, 0.5)])
    checker = SatChecker(0.0)
    assert checker.overlap_pairs(a, b).tolist() == [True]
    assert checker.stats.as_dict() == _stats(full_sat=1)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_a_pair_exactly_at_the_threshold_along_an_edge_normal_collides() -> None:
    """Only the full test separates this pair, along the hypotenuse of the 3-4-5 triangle
    (an edge of length 5, so |n| is exact); B lies exactly thr = tolerance + 64u M beyond it
    (M = 8 m, every value below exact in binary): the band is closed, the pair collides; one
    part in a thousand farther it is clear."""
    tri = [[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]]
    thr = TOL_M + 64.0 * 2.0**-53 * 8.0

    def beyond(delta_m: float) -> list[list[float]]:
        return [[4.0, delta_m], [8.0, -3.0 + delta_m], [7.0, 4.0 + delta_m]]

    checker = SatChecker(TOL_M)
    for delta, verdict in ((1.25 * thr, True), (1.25 * thr * 1.001, False)):
        a, b = _polygons([tri]), _polygons([beyond(delta)])
        for first, second in ((a, b), (b, a)):
            assert checker.overlap_pairs(first, second).tolist() == [verdict]
            assert checker.stats.as_dict() == _stats(full_sat=1)
            assert checker.overlap_all(first, second).tolist() == [[verdict]]


def _regular(rng: np.random.Generator, sides: int) -> list[list[float]]:
    """A regular polygon of ``sides`` vertices, random centre (within 3 m), size and turn."""
    centre = rng.uniform(-3.0, 3.0, 2)
    angles = rng.uniform(0.0, 2.0 * np.pi) + 2.0 * np.pi * np.arange(sides) / sides
    radius = rng.uniform(0.5, 2.0)
    ring = centre + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)
    return [[float(x), float(y)] for x, y in ring]


@pytest.mark.requirement("SR-SAT-1", kind="cross-check", code=SAT)
def test_polygons_with_different_vertex_counts_agree_with_geos() -> None:
    """Squares against pentagons and hexagons (one and two more vertices: the kernel pads the
    smaller side by repeating its first vertex): every verdict, in both orders and at both
    entry points, is GEOS's (no pair of this seed lies within the 1e-12 m band)."""
    rng = np.random.default_rng(2026)
    checker = SatChecker(0.0)
    for sides in (5, 6):
        rings_a = [_regular(rng, 4) for _ in range(150)]
        rings_b = [_regular(rng, sides) for _ in range(150)]
        a, b = _polygons(rings_a), _polygons(rings_b)
        expected = [
            bool(shapely.Polygon(ra).intersects(shapely.Polygon(rb)))
            for ra, rb in zip(rings_a, rings_b, strict=True)
        ]
        gaps = [
            shapely.Polygon(ra).distance(shapely.Polygon(rb))
            for ra, rb in zip(rings_a, rings_b, strict=True)
        ]
        assert min(g for g in gaps if g > 0.0) > 1e-12
        assert 30 <= sum(expected) <= 120  # both verdicts well represented
        assert checker.overlap_pairs(a, b).tolist() == expected
        assert checker.overlap_pairs(b, a).tolist() == expected
        assert np.diagonal(checker.overlap_all(a, b)).tolist() == expected
        assert np.diagonal(checker.overlap_all(b, a)).tolist() == expected


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_one_side_s_point_inside_the_other_is_a_certificate() -> None:
    """The triangle's first vertex is outside the square, the square's first vertex (1.5,
    1.5) is inside the triangle: one common point certifies the overlap. The triangle is
    padded to four vertices; its zero-length edge must not veto the certificate."""
    tri = _polygons([[[0.0, 0.0], [4.0, 0.0], [0.0, 4.0]]])
    assert tri.vertices_m.shape[1] > int(tri.counts[0])  # padded
    square = _polygons([_square(1.5, 1.5)])
    checker = SatChecker(TOL_M)
    for first, second in ((tri, square), (square, tri)):
        assert checker.overlap_pairs(first, second).tolist() == [True]
        assert checker.stats.as_dict() == _stats(certificate=1)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize("tolerance_m", [0.0, 1e-9])
def test_the_box_step_counts_each_polygons_slack(tolerance_m: float) -> None:
    # Each square's exact region may reach 0.01 m beyond its vertices: 15 mm apart along x or
    # y (farther than either slack, within both) they may touch, and no step may call them
    # clear (as none does 12 mm apart along both).
    a = _polygons([_square(0.0, 0.0)], [0.01])
    for dx, dy in ((1.015, 0.0), (0.0, 1.015), (1.012, 1.012)):
        b = _polygons([_square(dx, dy)], [0.01])
        checker = SatChecker(tolerance_m)
        assert checker.overlap_pairs(a, b).tolist() == [True], (dx, dy)
        assert checker.overlap_all(a, b).tolist() == [[True]], (dx, dy)
        assert checker.overlap_all(b, a).tolist() == [[True]], (dx, dy)
    # Beyond both slacks (25 mm apart, within three), the boxes alone decide: clear.
    far = _polygons([_square(1.025, 0.0)], [0.01])
    checker = SatChecker(tolerance_m)
    assert checker.overlap_pairs(a, far).tolist() == [False]
    assert checker.stats == SatStats(pairs=1, box=1)
    for first, second in ((a, far), (far, a)):
        assert checker.overlap_all(first, second).tolist() == [[False]]
        assert checker.stats == SatStats(pairs=1, box=1)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_verdicts_are_boolean_arrays_at_both_entry_points() -> None:
    """``overlap_pairs`` and ``overlap_all`` return numpy bool arrays (callers negate and mask
    with them), with no pair, with only box-decided pairs and with pairs the kernel decides."""
    checker = SatChecker(TOL_M)
    none = convex_polygons(np.zeros((0, 3, 2)))
    a, b = _polygons([c[0] for c in CASES]), _polygons([c[1] for c in CASES])
    far = _polygons([_square(50.0, 50.0)] * len(CASES))
    for first, second in ((none, none), (a, far), (a, b)):
        assert checker.overlap_pairs(first, second).dtype == np.bool_
        assert checker.overlap_all(first, second).dtype == np.bool_


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_the_box_pad_covers_rounding_at_large_coordinates() -> None:
    """With tolerance 0 the band is thr = 64u M (M the largest coordinate magnitude): two unit
    squares near x = 1,000 m, 2^-40 m apart along x (below thr, 7.1e-12 m), collide in either
    order at both entry points, decided by the full test; 2^-34 m apart (above both boxes'
    pads) the boxes separate them."""
    checker = SatChecker(0.0)
    a = _polygons([_square(1000.0, 0.0)])
    for gap, verdict, stats in (
        (2.0**-40, True, _stats(full_sat=1)),
        (2.0**-34, False, _stats(box=1)),
    ):
        b = _polygons([_square(1001.0 + gap, 0.0)])
        for first, second in ((a, b), (b, a)):
            assert checker.overlap_pairs(first, second).tolist() == [verdict], gap
            assert checker.stats.as_dict() == stats
            assert checker.overlap_all(first, second).tolist() == [[verdict]], gap
            assert checker.stats.as_dict() == stats


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_the_centre_line_joins_the_box_centres() -> None:
    """A unit square and a 1 x 64 m rectangle beyond its corner (1, 1), 0.85 x the tolerance
    apart along x and y: within the band along both axes, along the line through the box
    centres (nearly vertical: 0.88 x the tolerance) and along every edge normal, so the pair
    collides; it lies 1.2 x the tolerance apart along the diagonal, which is not an axis the
    check may use. Decided by the full test, in either order, at both entry points."""
    g = 0.85 * TOL_M
    tall = [[1.0 + g, 1.0 + g], [2.0 + g, 1.0 + g], [2.0 + g, 65.0 + g], [1.0 + g, 65.0 + g]]
    a, b = _polygons([_square(0.0, 0.0)]), _polygons([tall])
    checker = SatChecker(TOL_M)
    for first, second in ((a, b), (b, a)):
        assert checker.overlap_pairs(first, second).tolist() == [True]
        assert checker.stats.as_dict() == _stats(full_sat=1)
        assert checker.overlap_all(first, second).tolist() == [[True]]
        assert checker.stats.as_dict() == _stats(full_sat=1)


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
@pytest.mark.parametrize(
    ("depth", "step"),
    [(17.0 / 16.0, "certificate"), (1.0, "full_sat"), (0.5, "full_sat")],
    ids=["beyond the margin", "at the margin", "within the margin"],
)
def test_a_certificate_needs_the_margin_above_rounding(depth: float, step: str) -> None:
    """A triangle's apex ``depth`` x 2^-26 m inside the unit square [1023, 1024]^2 (M = 1,024
    m, so the certificate margin 8 CERT_KAPPA M^2 is 2^-26 for this edge of length 1): deeper
    than the margin it certifies the overlap; at or within it, rounding could have put it there,
    and the full test decides. The pair collides in every case, in either order."""
    x = 1023.0 + depth * 2.0**-26
    tri = [[1022.0, 1023.25], [1022.0, 1023.75], [x, 1023.5]]
    a, b = _polygons([tri]), _polygons([_square(1023.0, 1023.0)])
    checker = SatChecker(TOL_M)
    for first, second in ((a, b), (b, a)):
        assert checker.overlap_pairs(first, second).tolist() == [True]
        assert checker.stats.as_dict() == _stats(**{step: 1})


@pytest.mark.requirement("SR-SAT-1", kind="example", code=SAT)
def test_the_edge_normal_tests_take_each_pair_once_in_bounded_passes(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """2 (FULL_CHUNK_PAIRS + 3) pairs that only the full test decides (FULL_CLEAR and
    FULL_HIT in turn): it sees every such pair exactly once, at most FULL_CHUNK_PAIRS at a
    time, its scratch within the module's bound (2 K^2 2 FULL_CHUNK_PAIRS values; SR-RUN-5)."""
    import safety.geometry.sat as sat

    seen: list[int] = []
    inner = sat._separated_full

    def spy(*args: Any) -> Any:
        seen.extend(args[3].tolist())
        assert args[3].size <= FULL_CHUNK_PAIRS
        return inner(*args)

    monkeypatch.setattr(sat, "_separated_full", spy)
    copies = FULL_CHUNK_PAIRS + 3
    order = [c for _ in range(copies) for c in (FULL_CLEAR, FULL_HIT)]
    a, b = _polygons([c[0] for c in order]), _polygons([c[1] for c in order])
    checker = SatChecker(TOL_M)
    assert checker.overlap_pairs(a, b).tolist() == [c[2] for c in order]
    assert sorted(seen) == list(range(len(order)))
    k = a.vertices_m.shape[1]
    scratch = checker._ws._buffers
    assert scratch["full"].size <= 2 * k * k * 2 * FULL_CHUNK_PAIRS
    assert scratch["kernel"].size <= 10 * k * 2 * CHUNK_PAIRS
