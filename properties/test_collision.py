"""Soundness of the SAT collision check against FCL, GEOS and exact arithmetic (SR-SAT-1/2/6).

Every example is decided four ways: our SAT, python-fcl (``collide`` on extruded prisms),
shapely/GEOS (``intersects``) and exact rational SAT on the same float coordinates (with a
z3 linear real arithmetic query confirming the near-contact "clear" verdicts). Each
disagreement with FCL is counted by kind, with how exact arithmetic resolved it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import SafecaseConfig
from properties.geometry_cases import PairDraw, convex_points, polygon_pairs
from properties.oracles.geometry import (
    exact_pair,
    fcl_collide,
    fcl_distance,
    fcl_penetration,
    z3_common_point,
)
from safety.geometry.contact import contact_pairs
from safety.geometry.polygons import U, convex_polygons, transform_polygons
from safety.geometry.sat import RHO, SatChecker

SAT = ["safety/geometry/sat.py", "safety/geometry/polygons.py"]


def _band(draw: PairDraw, tol: float, slack: float) -> float:
    magnitude = float(max(np.abs(draw.a).max(), np.abs(draw.b).max()))
    return tol + RHO * magnitude + slack


@pytest.mark.requirement("SR-SAT-1", kind="cross-check", code=SAT)
@settings(max_examples=examples(300))
@given(pair=polygon_pairs())
def test_sat_never_misses_an_overlap(pair: PairDraw, safecase_config: SafecaseConfig) -> None:
    tol = safecase_config.geometry.contact_tolerance_m
    polys = convex_polygons([pair.a, pair.b])
    a, b = polys.take([0]), polys.take([1])
    ours = bool(SatChecker(tol).overlap_pairs(a, b)[0])
    exact = exact_pair(pair.a, pair.b)
    fcl_says = fcl_collide(pair.a, pair.b)
    geos_says = bool(shapely.intersects(shapely.Polygon(pair.a), shapely.Polygon(pair.b)))
    band = _band(pair, tol, float(polys.slack_m.sum()))
    rec = current()
    rec.count("pairs", "tested")
    rec.count("pairs", "exact overlap" if exact.overlap else "exact clear")
    rec.count("pairs", f"placement {pair.placement}")
    near = abs(exact.margin_m()) <= 1e-6 * pair.scale_m
    if near:
        rec.count("pairs", "within 1e-6 of the scale from contact")
    # FCL disagreements by kind, and how exact arithmetic resolved them.
    if fcl_says != exact.overlap:
        kind = "FCL missed an exact overlap" if exact.overlap else "FCL collision, exact clear"
        rec.count("FCL disagreements (resolved by exact arithmetic)", kind)
        if ours == exact.overlap:
            rec.count("FCL disagreements (resolved by exact arithmetic)", "SAT agreed with exact")
        else:
            rec.count("FCL disagreements (resolved by exact arithmetic)", "SAT in tolerance band")
    if geos_says != exact.overlap:
        rec.count("GEOS disagreements", "exact overlap" if exact.overlap else "exact clear")
    if ours != fcl_says:
        rec.count("SAT vs FCL", "differ")
    # The safety claim: no false negative, ever.
    if exact.overlap:
        assert ours, f"SAT said clear but the polygons overlap (margin {exact.margin_m():.3g} m)"
        rec.count("SAT outcome", "true collision")
    elif ours:
        rec.count("SAT outcome", "collision within the tolerance band")
        assert exact.margin_m() <= 2.0 * band, (
            f"collision reported {exact.margin_m():.3g} m apart, beyond the band {band:.3g} m"
        )
    else:
        rec.count("SAT outcome", "true clear")
        if near:
            smt = z3_common_point(pair.a, pair.b)
            assert not smt.common_point, "z3 found a common point for a 'clear' pair"
            rec.count("SAT outcome", "near-contact clear confirmed by z3 (unsat)")
    rec.count("SAT false negatives", "count", 0)


@pytest.mark.requirement("SR-SAT-2", kind="cross-check", code=["safety/geometry/contact.py"])
@settings(max_examples=examples(200))
@given(pair=polygon_pairs())
def test_depth_and_distance_match_exact_and_fcl(pair: PairDraw) -> None:
    polys = convex_polygons([pair.a, pair.b])
    contact = contact_pairs(polys.take([0]), polys.take([1]))
    exact = exact_pair(pair.a, pair.b)
    magnitude = max(np.abs(pair.a).max(), np.abs(pair.b).max())
    rec = current()
    if exact.overlap:
        rec.count("pairs", "overlapping")
        assert contact.depth_m[0] == pytest.approx(exact.penetration_m(), abs=1e-12 * magnitude)
        # The MTV moves B by the depth along an edge normal.
        assert float(np.hypot(*contact.mtv_m[0])) == pytest.approx(
            contact.depth_m[0], abs=1e-12 * magnitude
        )
        depth = fcl_penetration(pair.a, pair.b)
        if depth is None:
            rec.count("FCL depth", "no contact reported (exact: overlap)")
            return
        if abs(depth - exact.penetration_m()) <= 1e-6 * pair.scale_m:
            rec.count("FCL depth", "equal to exact within 1e-6 of the scale")
        else:
            rec.count("FCL depth", "larger than the exact minimum (depth along MPR's direction)")
            assert depth >= exact.penetration_m() - 1e-9 * pair.scale_m, (
                f"FCL depth {depth:.6g} below the exact minimum {exact.penetration_m():.6g}"
            )
    else:
        rec.count("pairs", "disjoint")
        assert contact.distance_m[0] == pytest.approx(exact.distance_m(), abs=1e-12 * magnitude)
        if exact.distance_m() > 1e-12 * magnitude:
            assert contact.depth_m[0] == 0.0
        else:  # touching exactly: a depth within rounding of the coordinates is no overlap
            assert contact.depth_m[0] <= 1e-12 * magnitude
            rec.count("pairs", "touching (depth within rounding)")
        fd = fcl_distance(pair.a, pair.b)
        if abs(fd - exact.distance_m()) <= 1e-9 * max(pair.scale_m, exact.distance_m()):
            rec.count("FCL distance", "equal to exact within 1e-9 of the scale")
        else:
            rec.count("FCL distance", f"differs (FCL {fd:.3g} m, exact {exact.distance_m():.3g} m)")


@st.composite
def _polygon_lists(draw: st.DrawFn) -> tuple[list[np.ndarray], list[np.ndarray]]:
    scale = 10.0 ** draw(st.floats(-2.0, 2.0), label="log10 scale")
    box = st.tuples(st.floats(-3, 3), st.floats(-3, 3))

    def one() -> st.SearchStrategy[np.ndarray]:
        return st.builds(
            lambda pts, at: pts - pts.mean(axis=0) + np.asarray(at) * scale,
            convex_points(min_scale_exp=math.log10(scale), max_scale_exp=math.log10(scale)),
            box,
        )

    left = draw(st.lists(one(), min_size=1, max_size=6), label="A")
    right = draw(st.lists(one(), min_size=1, max_size=6), label="B")
    return left, right


@pytest.mark.requirement("SR-SAT-6", kind="property", code=["safety/geometry/sat.py"])
@settings(max_examples=examples(100))
@given(lists=_polygon_lists())
def test_batched_equals_pairwise_and_symmetric(
    lists: tuple[list[np.ndarray], list[np.ndarray]],
) -> None:
    try:
        a = convex_polygons(lists[0])
        b = convex_polygons(lists[1])
    except ValueError:
        assume(False)
        raise
    checker = SatChecker(1e-9)
    table = checker.overlap_all(a, b)
    flipped = checker.overlap_all(b, a)
    assert (table == flipped.T).all(), "overlap(A, B) != overlap(B, A)"
    for i in range(a.n):
        for j in range(b.n):
            single = checker.overlap_pairs(a.take([i]), b.take([j]))[0]
            assert single == table[i, j], f"batched {table[i, j]} but pair ({i}, {j}) {single}"
    ia, ib = np.meshgrid(np.arange(a.n), np.arange(b.n), indexing="ij")
    matched = checker.overlap_pairs(a.take(ia.ravel()), b.take(ib.ravel()))
    assert (matched.reshape(a.n, b.n) == table).all()
    current().count("pairs", "compared", a.n * b.n)
    current().count("pairs", "colliding", int(table.sum()))


@pytest.mark.requirement("SR-SAT-6", kind="property", code=["safety/geometry/sat.py"])
@settings(max_examples=examples(200))
@given(
    pair=polygon_pairs(),
    angle=st.floats(-math.pi, math.pi),
    shift=st.tuples(st.floats(-100, 100), st.floats(-100, 100)),
)
def test_rigid_motion_keeps_decisive_verdicts(
    pair: PairDraw, angle: float, shift: tuple[float, float]
) -> None:
    polys = convex_polygons([pair.a, pair.b])
    moved = transform_polygons(polys, shift[0], shift[1], angle)
    checker = SatChecker(1e-9)
    before = bool(checker.overlap_pairs(polys.take([0]), polys.take([1]))[0])
    after = bool(checker.overlap_pairs(moved.take([0]), moved.take([1]))[0])
    exact_before = exact_pair(polys.vertex_list(0), polys.vertex_list(1))
    exact_after = exact_pair(moved.vertex_list(0), moved.vertex_list(1))
    magnitude = max(np.abs(moved.vertices_m).max(), np.abs(polys.vertices_m).max())
    # Rotation moves every coordinate by rounding (a few u * M): only margins well outside
    # that and the band are decisive.
    decisive = 1e-9 + 1e4 * U * magnitude
    rec = current()
    if min(abs(exact_before.margin_m()), abs(exact_after.margin_m())) > decisive:
        rec.count("pairs", "decisive")
        assert before == after, "a rigid motion changed a decisive verdict"
    else:
        rec.count("pairs", "within rounding of contact (not compared)")
    assert before == bool(checker.overlap_pairs(polys.take([1]), polys.take([0]))[0])
