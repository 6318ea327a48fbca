"""The costmap at its edges: the tolerance band, the grid's border, empty input (SR-PRED-2).

The mutation campaign (SR-EVD-5, SR-EVD-6; docs/findings/mutation.md) showed these unwatched:
which vertices and edge crossings within ``contact_tolerance_m`` of a grid line widen a row's
extent, the clamping of an edge's crossing to the edge itself, the count of envelopes clipped
at each border of the grid, a grid of one cell, a call with no envelope (or none on the grid),
and the checks of ``Costmap``. The cases use a grid of 1 m cells with a tolerance of 2^-10 m,
so every grid line and every coordinate below is exact in binary floating point.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

from pipeline.config import CostmapSection, default_config, overridden
from pipeline.types import BoolArray, ConvexPolygons, FloatArray
from properties.oracles.geometry import shapely_polygons
from safety.geometry.costmap import Costmap, CostmapBuilder
from safety.geometry.polygons import convex_polygons

COSTMAP = ["safety/geometry/costmap.py"]
TOL_M = 2.0**-10
# 8 x 8 cells of 1 m centred on the origin: row i spans y in [i - 4, i - 3], column j x in
# [j - 4, j - 3].
SECTION: CostmapSection = overridden(
    default_config(),
    {
        "costmap": {
            "resolution_m": 1.0,
            "width_m": 8.0,
            "height_m": 8.0,
            "contact_tolerance_m": TOL_M,
        }
    },
).costmap


def _cells(builder: CostmapBuilder, polygons: ConvexPolygons) -> tuple[BoolArray, FloatArray]:
    """Per cell of the grid: touches a polygon (shapely, closed sets); distance to the nearest."""
    r = builder.section.resolution_m
    i, j = np.meshgrid(np.arange(builder.rows), np.arange(builder.cols), indexing="ij")
    x0 = builder.origin_x_m + j.ravel() * r
    y0 = builder.origin_y_m + i.ravel() * r
    boxes = shapely.box(x0, y0, x0 + r, y0 + r)
    shapes = shapely_polygons(polygons)
    hit = np.zeros(boxes.shape, dtype=bool)
    dist = np.full(boxes.shape, np.inf)
    for shape in shapes:
        hit |= shapely.intersects(boxes, shape)
        dist = np.minimum(dist, shapely.distance(boxes, shape))
    shape2 = (builder.rows, builder.cols)
    return hit.reshape(shape2), dist.reshape(shape2)


def _square(cx: float, cy: float, half: float) -> FloatArray:
    return np.array(
        [
            [cx - half, cy - half],
            [cx + half, cy - half],
            [cx + half, cy + half],
            [cx - half, cy + half],
        ]
    )


# Polygons with a vertex or a nearly flat edge within the tolerance of the grid line y = 0
# (between rows 3 and 4), whose edges meet that line in another column than the vertex. Four
# vertices each, so that no padding vertex repeats the one in the band.
_T = TOL_M
_WEDGE = np.array([[0.99, -_T / 2], [3.5, 2 * _T], [3.8, 0.05], [3.0, 0.05]])
BAND_CASES: dict[str, FloatArray] = {
    # Bottom vertex T/2 below y = 0; its shallow edges leave row 3 through y = 0 at x = 1.01
    # and x = 1.49, right of the vertex's column, and no other vertex is within the tolerance
    # of row 3: row 3 reaches column 5 only through the crossings, column 4 only through the
    # vertex.
    "bottom vertex just below a line": _WEDGE,
    # The mirror image: top vertex T/2 above y = 0, its edges enter row 4 at x = 1.01 and 1.49.
    "top vertex just above a line": _WEDGE * np.array([1.0, -1.0]),
    # A bottom edge rising by T from T/2 above y = 0: the line y = 0 lies within the tolerance
    # below its lower end, so its crossing is the end itself, not the edge's extension to x = -5.
    "flat bottom edge just above a line": np.array([[-2.5, _T / 2], [2.5, 1.5 * _T], [0.0, 2.0]]),
    # A top edge falling by T to 3T/2 below y = 0: y = 0 lies within the tolerance above its
    # upper end, whose crossing is that end, not the extension to x = -5.
    "flat top edge just below a line": np.array([[0.0, -2.0], [2.5, -1.5 * _T], [-2.5, -_T / 2]]),
}


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
@pytest.mark.parametrize("name", sorted(BAND_CASES))
def test_vertices_and_crossings_in_the_tolerance_band(name: str) -> None:
    builder = CostmapBuilder(SECTION)
    polygons = convex_polygons([BAND_CASES[name]])
    costmap = builder.rasterize(polygons)
    hit, dist = _cells(builder, polygons)
    missed = np.argwhere(hit & ~costmap.occupied).tolist()
    assert missed == [], f"touching cells not marked: {missed}"
    extra = costmap.occupied & ~hit
    assert (dist[extra] <= TOL_M).all(), f"marked {dist[extra].max():.3g} m from the polygon"


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
@pytest.mark.parametrize("below", [True, False])
def test_a_vertex_exactly_the_tolerance_from_a_row_marks_it(below: bool) -> None:
    """The tolerance is inclusive: a bottom vertex exactly T below y = 0 marks its cell of
    row 4 (above the line), a top vertex exactly T above it its cell of row 3; twice as far
    they do not. The vertex's edges are shallow and run to the right (they cross y = 0 in
    column 5), so only the vertex itself reaches column 4."""
    sign = np.array([1.0, 1.0 if below else -1.0])
    builder = CostmapBuilder(SECTION)
    row = 4 if below else 3
    for gap, marked in ((_T, True), (2 * _T, False)):
        ring = np.array([[0.99, -gap], [3.5, 2 * _T], [3.8, 0.05], [3.0, 0.05]]) * sign
        costmap = builder.rasterize(convex_polygons([ring]))
        assert costmap.occupied[row, 4] is np.bool_(marked), (gap, costmap.occupied[row])
        assert costmap.occupied[row, 5]  # where the edges cross y = 0


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_zero_tolerance_marks_both_sides_of_a_grid_line_and_skips_empty_rows() -> None:
    """With no tolerance, a rectangle whose bottom (y = -2) and sides (x = -0.5, 0.5) lie on
    grid lines of a 0.1 m grid from -3 m marks the cells beyond those lines too: they share
    the line with it. Its top, y = -1.3, rounds into row 17, whose bottom line (-3 + 17 * 0.1)
    lies above it: that row holds no part of the rectangle and is skipped, neither marked nor
    failing."""
    section = overridden(
        default_config(),
        {
            "costmap": {
                "resolution_m": 0.1,
                "width_m": 6.0,
                "height_m": 6.0,
                "contact_tolerance_m": 0.0,
            }
        },
    ).costmap
    builder = CostmapBuilder(section)
    assert np.floor((-1.3 - builder.origin_y_m) / 0.1) == 17
    assert builder.origin_y_m + 0.1 * 17 > -1.3
    polygons = convex_polygons([np.array([[-0.5, -2.0], [0.5, -2.0], [0.5, -1.3], [-0.5, -1.3]])])
    costmap = builder.rasterize(polygons)
    hit, _ = _cells(builder, polygons)
    assert (costmap.occupied == hit).all()
    assert not costmap.occupied[17].any()
    for i in range(9, 17):  # row 9 ends on the bottom; columns 24 and 35 on the sides
        assert np.flatnonzero(costmap.occupied[i]).tolist() == list(range(24, 36)), i


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_horizontal_edges_raise_no_floating_point_error() -> None:
    """A flat edge has no crossing parameter; it must not be computed by dividing by zero
    (a runtime that traps floating-point errors would fail here)."""
    builder = CostmapBuilder(SECTION)
    with np.errstate(all="raise"):
        polygons = convex_polygons([_square(0.5, 0.5, 0.25), _square(-1.0, -1.0, 1.0)])
        costmap = builder.rasterize(polygons)
    hit, _ = _cells(builder, polygons)
    assert (costmap.occupied == hit).all()
    assert int(costmap.occupied.sum()) == 4 * 4  # [-2, 0]^2 touches 4 x 4 cells, (4, 4) too


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_no_envelope_gives_the_empty_grid() -> None:
    builder = CostmapBuilder(SECTION)
    for polygons in (
        convex_polygons(np.zeros((0, 3, 2))),
        convex_polygons([_square(20.0, 0.0, 1.0), _square(0.0, -9.0, 0.5)]),  # off the grid
    ):
        costmap = builder.rasterize(polygons)
        assert costmap.occupied.shape == (8, 8)
        assert costmap.occupied.dtype == np.bool_
        assert not costmap.occupied.any()
        assert (costmap.origin_x_m, costmap.origin_y_m, costmap.resolution_m) == (-4.0, -4.0, 1.0)
        assert type(costmap.n_clipped) is int
        assert costmap.n_clipped == polygons.n


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_clipping_is_counted_at_each_border_and_only_there() -> None:
    builder = CostmapBuilder(SECTION)
    # Inside the border cells (rows and columns 0 and 7) by a tenth of a cell: not clipped.
    inside = {
        "left": _square(-3.7, 0.5, 0.2),
        "right": _square(3.7, 0.5, 0.2),
        "bottom": _square(0.5, -3.7, 0.2),
        "top": _square(0.5, 3.7, 0.2),
    }
    cell = {"left": (4, 0), "right": (4, 7), "bottom": (0, 4), "top": (7, 4)}
    for side, ring in inside.items():
        costmap = builder.rasterize(convex_polygons([ring]))
        assert costmap.n_clipped == 0, side
        assert np.argwhere(costmap.occupied).tolist() == [list(cell[side])], side
    # Past the border by a tenth of a cell: clipped, and its cell on the grid still marked.
    past = {
        "left": _square(-4.0, 0.5, 0.1),
        "right": _square(4.0, 0.5, 0.1),
        "bottom": _square(0.5, -4.0, 0.1),
        "top": _square(0.5, 4.0, 0.1),
    }
    for side, ring in past.items():
        costmap = builder.rasterize(convex_polygons([ring]))
        assert costmap.n_clipped == 1, side
        assert np.argwhere(costmap.occupied).tolist() == [list(cell[side])], side
    costmap = builder.rasterize(convex_polygons([*inside.values(), *past.values()]))
    assert costmap.n_clipped == 4


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
@pytest.mark.parametrize("size_m", [0.05, 0.02])
def test_a_grid_smaller_than_a_cell_has_one_cell(size_m: float) -> None:
    section = overridden(
        default_config(), {"costmap": {"resolution_m": 0.05, "width_m": size_m, "height_m": size_m}}
    ).costmap
    builder = CostmapBuilder(section)
    assert (builder.rows, builder.cols) == (1, 1)
    assert (builder.origin_x_m, builder.origin_y_m) == pytest.approx((-0.025, -0.025))
    costmap = builder.rasterize(convex_polygons([_square(0.0, 0.0, 0.01)]))
    assert costmap.occupied.tolist() == [[True]]
    assert costmap.n_clipped == 0


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_costmap_checks_its_cells() -> None:
    costmap = Costmap(np.array([[0, 2], [1, 0]]), -1.0, -1.0, 1.0, 0)
    assert costmap.occupied.dtype == np.bool_
    assert costmap.occupied.tolist() == [[False, True], [True, False]]
    assert costmap.shape == (2, 2)
    with pytest.raises(ValueError) as refused:
        Costmap(np.zeros(4, dtype=bool), -1.0, -1.0, 1.0, 0)
    assert str(refused.value) == "Costmap: occupied must be a 2-D array"


@pytest.mark.requirement("SR-PRED-2", kind="example", code=COSTMAP)
def test_cell_bounds_of_one_cell_and_of_a_block() -> None:
    costmap = CostmapBuilder(SECTION).rasterize(convex_polygons(np.zeros((0, 3, 2))))
    assert costmap.cell_bounds(np.int64(4), np.int64(5)).tolist() == [1.0, 0.0, 2.0, 1.0]
    i, j = np.meshgrid(np.arange(2), np.arange(3), indexing="ij")
    boxes = costmap.cell_bounds(i, j)
    assert boxes.shape == (2, 3, 4)
    assert boxes[1, 2].tolist() == [-2.0, -3.0, -1.0, -2.0]
