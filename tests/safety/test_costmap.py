"""Examples for the costmap grid (SR-PRED-2)."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from safety.geometry.costmap import Costmap, CostmapBuilder
from safety.geometry.polygons import convex_polygons


def _square(cx: float, cy: float, half: float) -> np.ndarray:
    return np.array(
        [
            [cx - half, cy - half],
            [cx + half, cy - half],
            [cx + half, cy + half],
            [cx - half, cy + half],
        ]
    )


def test_grid_size_origin_and_a_square() -> None:
    builder = CostmapBuilder(default_config().costmap)
    assert (builder.rows, builder.cols) == (400, 400)
    assert (builder.origin_x_m, builder.origin_y_m) == (-10.0, -10.0)
    # A 0.2 m square centred on a cell corner marks 4 x 4 cells plus the ring it touches.
    costmap = builder.rasterize(convex_polygons([_square(1.0, 1.0, 0.2)]))
    i, j = np.nonzero(costmap.occupied)
    assert costmap.occupied.sum() == 10 * 10  # [0.8, 1.2] touches cells 35..44 in x and y
    assert (i.min(), i.max(), j.min(), j.max()) == (215, 224, 215, 224)
    box = costmap.cell_bounds(np.array([215]), np.array([215]))[0]
    assert box == pytest.approx([0.75, 0.75, 0.8, 0.8])


def test_clipping_and_several_envelopes() -> None:
    config = overridden(
        default_config(), {"costmap": {"width_m": 4.0, "height_m": 2.0, "resolution_m": 0.1}}
    )
    builder = CostmapBuilder(config.costmap)
    polys = convex_polygons(
        [_square(0.0, 0.0, 0.15), _square(1.9, 0.0, 0.5), _square(9.0, 9.0, 0.5)]
    )
    costmap = builder.rasterize(polys)
    assert costmap.shape == (20, 40)
    assert costmap.n_clipped == 2  # one reaches past the edge, one lies wholly outside
    assert costmap.occupied[10, 20]  # the small square at the centre
    assert costmap.occupied[10, 39]  # the one reaching past the right edge


def test_costmap_arrays_are_read_only() -> None:
    costmap = CostmapBuilder(default_config().costmap).rasterize(
        convex_polygons([_square(0, 0, 1)])
    )
    assert isinstance(costmap, Costmap)
    with pytest.raises(ValueError):
        costmap.occupied[0, 0] = True
