"""Penetration, MTV and distance beyond the single square pair (SR-SAT-2).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) showed these unwatched:
an MTV along an edge of B (the other sign), polygons with different vertex counts (the padded
columns), several pairs at once (reductions over the right axis), the signed best gap, and the
input errors word for word.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.errors import GeometryError
from pipeline.types import FloatArray
from safety.geometry.contact import contact_pairs
from safety.geometry.polygons import convex_polygons

CONTACT = ["safety/geometry/contact.py"]
SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
# Its slanted edge (x + y = 1.9) cuts the square's corner (1, 1) by 0.1 / sqrt(2): shallower
# than along x or y (0.5 each), so the best axis is the triangle's own edge normal.
TRIANGLE = np.array([[1.4, 0.5], [1.4, 1.4], [0.5, 1.4]])


def _moved(polygon: FloatArray, dx: float, dy: float) -> FloatArray:
    moved: FloatArray = np.add(polygon, np.array([dx, dy]))
    return moved


@pytest.mark.requirement("SR-SAT-2", kind="example", code=CONTACT)
def test_the_mtv_along_an_edge_of_b_pushes_b_away_from_a() -> None:
    a, b = convex_polygons([SQUARE]), convex_polygons([TRIANGLE])
    depth = 0.1 / math.sqrt(2.0)
    ab = contact_pairs(a, b)
    assert ab.depth_m[0] == pytest.approx(depth)
    assert ab.best_gap_m[0] == pytest.approx(-depth)
    assert ab.mtv_m[0] == pytest.approx([0.05, 0.05])
    ba = contact_pairs(b, a)
    assert ba.depth_m[0] == pytest.approx(depth)
    assert ba.mtv_m[0] == pytest.approx([-0.05, -0.05])
    assert (ab.distance_m[0], ba.distance_m[0]) == (0.0, 0.0)


@pytest.mark.requirement("SR-SAT-2", kind="example", code=CONTACT)
def test_a_triangle_and_a_square_apart_in_either_order() -> None:
    far = _moved(TRIANGLE, 1.6, -0.9)  # nearest vertex (2.1, 0.5): 1.1 m from the edge x = 1
    for a, b in (([SQUARE], [far]), ([far], [SQUARE])):
        contact = contact_pairs(convex_polygons(a), convex_polygons(b))
        assert contact.distance_m[0] == pytest.approx(1.1)
        assert contact.best_gap_m[0] == pytest.approx(1.1)
        assert contact.depth_m[0] == 0.0
        assert contact.mtv_m[0].tolist() == [0.0, 0.0]


@pytest.mark.requirement("SR-SAT-2", kind="example", code=CONTACT)
def test_each_pair_of_a_batch_gets_its_own_distance_and_depth() -> None:
    a = convex_polygons([SQUARE, SQUARE, SQUARE])
    b = convex_polygons(
        [_moved(SQUARE, 3.0, 0.0), _moved(SQUARE, 0.0, 1.5), _moved(SQUARE, 0.75, 0.0)]
    )
    contact = contact_pairs(a, b)
    assert contact.distance_m.tolist() == pytest.approx([2.0, 0.5, 0.0])
    assert contact.best_gap_m.tolist() == pytest.approx([2.0, 0.5, -0.25])
    assert contact.depth_m.tolist() == pytest.approx([0.0, 0.0, 0.25])
    np.testing.assert_allclose(contact.mtv_m, [[0.0, 0.0], [0.0, 0.0], [0.25, 0.0]], atol=1e-12)


@pytest.mark.requirement("SR-SAT-2", kind="example", code=CONTACT)
def test_bad_inputs_are_refused_with_the_reason() -> None:
    one = convex_polygons([SQUARE])
    two = convex_polygons([SQUARE, SQUARE])
    for a, b in ((one, SQUARE), (SQUARE, one)):
        with pytest.raises(GeometryError) as refused:
            contact_pairs(a, b)  # type: ignore[arg-type]
        assert str(refused.value) == "contact_pairs: expected ConvexPolygons for a and b"
    with pytest.raises(GeometryError) as refused:
        contact_pairs(one, two)
    assert str(refused.value) == "contact_pairs: 1 polygons in a but 2 in b"


def _hexagon(cx: float, cy: float) -> FloatArray:
    angles = np.arange(6) * math.pi / 3
    hexagon: FloatArray = np.column_stack([cx + np.cos(angles), cy + np.sin(angles)])
    return hexagon


@pytest.mark.requirement("SR-SAT-2", kind="example", code=CONTACT)
def test_polygons_with_more_vertices_on_one_side_in_either_order() -> None:
    square = convex_polygons([SQUARE])
    apart, into = convex_polygons([_hexagon(5.0, 0.5)]), convex_polygons([_hexagon(1.8, 0.5)])
    assert (apart.k, square.k) == (6, 4)
    for a, b in ((square, apart), (apart, square)):
        contact = contact_pairs(a, b)
        assert contact.distance_m[0] == pytest.approx(3.0)  # (4, 0.5) to the edge x = 1
        assert contact.depth_m[0] == 0.0
    ab, ba = contact_pairs(square, into), contact_pairs(into, square)
    assert ab.depth_m[0] == pytest.approx(0.2)  # the vertex (0.8, 0.5) is 0.2 inside x = 1
    assert ba.depth_m[0] == pytest.approx(0.2)
    np.testing.assert_allclose(ab.mtv_m[0], [0.2, 0.0], atol=1e-12)
    np.testing.assert_allclose(ba.mtv_m[0], [-0.2, 0.0], atol=1e-12)
