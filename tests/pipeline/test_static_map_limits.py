"""The site map's edges (SR-AVL-8): the grid's first row and column, a one-cell grid, bad grids
and tolerances, Nav2's pixel semantics (negate, the occupancy threshold, its boundary), labels
out of range."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import shapely
from PIL import Image

from pipeline.config import default_config, overridden
from pipeline.errors import ConfigError
from pipeline.static_map import StaticMap, checked_map, clusters_on_map


def test_the_first_row_and_column_are_on_the_grid() -> None:
    grid = np.zeros((3, 4), dtype=bool)
    grid[0, 0] = True
    smap = StaticMap.from_grid(grid, 0.5, (1.0, 2.0), 0.0, "corner")
    assert smap.covers(np.array([1.1, 1.6, 0.9]), np.array([2.1, 2.1, 2.1])).tolist() == [
        True,
        False,
        False,
    ]


def test_a_one_cell_map_and_points_off_it() -> None:
    smap = StaticMap.from_grid(np.ones((1, 1), dtype=bool), 0.1, (0.0, 0.0), 0.0, "one")
    x = np.array([0.05, -0.05, 0.15, 0.05, np.nan])
    y = np.array([0.05, 0.05, 0.05, 0.15, 0.05])
    assert smap.covers(x, y).tolist() == [True, False, False, False, False]
    strip = StaticMap.from_grid(np.ones((1, 3), dtype=bool), 0.1, (0.0, 0.0), 0.0, "strip")
    assert strip.covers(np.array([0.25]), np.array([0.05])).tolist() == [True]


def test_the_grids_are_read_only() -> None:
    smap = StaticMap.from_grid(np.ones((2, 2), dtype=bool), 0.1, (0.0, 0.0), 0.1, "ro")
    with pytest.raises(ValueError, match="read-only"):
        smap.occupied[0, 0] = False
    with pytest.raises(ValueError, match="read-only"):
        smap.covered[0, 0] = False


@pytest.mark.parametrize(
    ("grid", "resolution", "tolerance", "match"),
    [
        (np.ones((2, 2)), 0.0, 0.1, "bad: resolution must be a positive number, got 0.0"),
        (np.ones((2, 2)), 0.1, -0.1, "bad: tolerance must be >= 0, got -0.1"),
        (np.ones(4), 0.1, 0.1, r"bad: the map must be a non-empty 2-D grid, got \(4,\)"),
        (np.ones((0, 3)), 0.1, 0.1, r"bad: the map must be a non-empty 2-D grid, got \(0, 3\)"),
    ],
)
def test_bad_grids_are_refused_naming_the_source(
    grid: np.ndarray, resolution: float, tolerance: float, match: str
) -> None:
    with pytest.raises(ConfigError, match=match):
        StaticMap.from_grid(grid, resolution, (0.0, 0.0), tolerance, "bad")


def test_no_parts_is_refused_naming_the_source() -> None:
    with pytest.raises(ConfigError, match="site: a static map needs at least one part"):
        StaticMap.from_parts([], 0.05, 0.1, "site")
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    assert StaticMap.from_parts([square], 0.05, 0.1).source == "parts"


def _map_file(tmp_path: Path, pixels: list[int], extra: str) -> Path:
    Image.fromarray(np.array([pixels], dtype=np.uint8)).save(tmp_path / "m.pgm")
    yaml_path = tmp_path / "m.yaml"
    yaml_path.write_text(f"image: m.pgm\nresolution: 1.0\norigin: [1.0, 2.0, 0.0]\n{extra}")
    return yaml_path


def test_nav2_pixels_are_read_as_map_server_reads_them(tmp_path: Path) -> None:
    """Trinary: occupied when (255 - value) / 255 exceeds occupied_thresh (0.65 by default);
    with negate, value / 255; a value exactly at the threshold is not occupied."""
    pixels = [0, 89, 90, 100, 166, 254, 255]
    plain = StaticMap.from_nav2(_map_file(tmp_path, pixels, ""), 0.0)
    assert plain.occupied[0].tolist() == [True, True, False, False, False, False, False]
    negated = StaticMap.from_nav2(_map_file(tmp_path, pixels, "negate: 1\nmode: scale\n"), 0.0)
    assert negated.occupied[0].tolist() == [False, False, False, False, True, True, True]
    at = 155.0 / 255.0
    edge = StaticMap.from_nav2(_map_file(tmp_path, pixels, f"occupied_thresh: {at!r}\n"), 0.0)
    assert edge.occupied[0].tolist() == [True, True, True, False, False, False, False]
    assert (edge.origin_x_m, edge.origin_y_m) == (1.0, 2.0)


def test_a_colour_map_image_is_read_by_its_luminance(tmp_path: Path) -> None:
    rgb = np.zeros((1, 3, 3), dtype=np.uint8)
    rgb[0, 1] = 254
    rgb[0, 2] = (254, 0, 0)  # luminance 76: occupied
    Image.fromarray(rgb).save(tmp_path / "c.png")
    (tmp_path / "c.yaml").write_text("image: c.png\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\n")
    assert StaticMap.from_nav2(tmp_path / "c.yaml", 0.0).occupied.tolist() == [[True, False, True]]


def test_a_written_map_carries_every_key_map_server_requires(tmp_path: Path) -> None:
    from ruamel.yaml import YAML

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    path = StaticMap.from_parts([square], 0.05, 0.1).write_nav2(tmp_path / "w.yaml")
    meta = YAML(typ="safe").load(path.read_text())
    assert sorted(meta) == sorted(
        ["image", "mode", "resolution", "origin", "negate", "occupied_thresh", "free_thresh"]
    )
    assert (meta["occupied_thresh"], meta["free_thresh"], meta["negate"]) == (0.65, 0.196, 0)


def test_the_reach_and_the_person_radius() -> None:
    """The reach is tolerance + sqrt(2) x resolution; a map reaching exactly a person's radius
    is refused (the bound is strict)."""
    smap = StaticMap.from_grid(np.ones((2, 2), dtype=bool), 0.05, (0.0, 0.0), 0.05, "r")
    assert smap.reach_m() == 0.05 + math.sqrt(2.0) * 0.05
    config = default_config()
    assert checked_map(smap, config) is smap
    exact = overridden(
        config,
        {
            "map": {"tolerance_m": 0.0, "resolution_m": 0.01},
            "runtime": {"person_radius_m": smap.reach_m()},
        },
    )
    with pytest.raises(ConfigError, match=r"r: tolerance 0\.05 m"):
        checked_map(smap, exact)


def test_a_grid_of_numbers_is_read_as_occupied_where_nonzero() -> None:
    smap = StaticMap.from_grid(np.array([[0, 2]]), 1.0, (0.0, 0.0), 0.0, "ints")
    assert smap.occupied.dtype == np.bool_
    assert smap.occupied.tolist() == [[False, True]]


def test_a_bad_origin_is_refused_naming_it(tmp_path: Path) -> None:
    path = _map_file(tmp_path, [0], "")
    path.write_text(path.read_text().replace("origin: [1.0, 2.0, 0.0]", "origin: 3"))
    with pytest.raises(ConfigError, match=r"m.yaml: origin must be \[x, y, yaw\], got 3"):
        StaticMap.from_nav2(path, 0.0)
    path.write_text(path.read_text().replace("origin: 3", "origin: [1.0, 2.0]"))
    with pytest.raises(ConfigError, match=r"origin must be \[x, y, yaw\], got \[1.0, 2.0\]"):
        StaticMap.from_nav2(path, 0.0)


def test_a_file_that_is_not_a_mapping_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "list.yaml"
    path.write_text("- image\n- resolution\n")
    with pytest.raises(ConfigError, match="needs the keys image, resolution, origin; got list"):
        StaticMap.from_nav2(path, 0.0)
    path.write_text("image: m.pgm\n")
    with pytest.raises(ConfigError, match=r"got \['image'\]"):
        StaticMap.from_nav2(path, 0.0)


def test_labels_out_of_range_are_not_counted() -> None:
    smap = StaticMap.from_grid(np.ones((2, 2), dtype=bool), 1.0, (0.0, 0.0), 0.0, "all")
    x, y = np.array([0.5, 0.5, 9.0]), np.array([0.5, 1.5, 9.0])
    assert clusters_on_map(smap, np.array([0, 1, 2]), x, y, 2).tolist() == [True, True]
    assert clusters_on_map(smap, np.array([0.0, 1.0, 2.0]), x, y, 2).tolist() == [True, True]


def _every_cell(parts: list[np.ndarray], smap: StaticMap) -> np.ndarray:
    """The reference raster: every cell's centre against the union of the parts."""
    union = shapely.unary_union([shapely.Polygon(p) for p in parts])
    rows, cols = smap.occupied.shape
    h = smap.resolution_m
    gx, gy = np.meshgrid(
        smap.origin_x_m + (np.arange(cols) + 0.5) * h, smap.origin_y_m + (np.arange(rows) + 0.5) * h
    )
    reach = math.sqrt(0.5) * h * (1.0 + 1e-12)  # from_parts' reach, tie slack included
    near = shapely.dwithin(union, shapely.points(gx.ravel(), gy.ravel()), reach)
    return np.asarray(near).reshape(rows, cols)


@pytest.mark.parametrize("resolution", [0.05, 0.3, 2.0])
def test_the_raster_of_candidate_cells_equals_every_cell_against_the_union(
    resolution: float,
) -> None:
    """from_parts tests only the cells near some part's bounding box; the grid is the same."""
    rng = np.random.default_rng(7)
    parts = []
    for _ in range(12):
        cx, cy, w, d = (
            rng.uniform(-6, 6),
            rng.uniform(-6, 6),
            rng.uniform(0.1, 4),
            rng.uniform(0.05, 1),
        )
        parts.append(np.array([[cx, cy], [cx + w, cy], [cx + w, cy + d], [cx, cy + d]]))
    smap = StaticMap.from_parts(parts, resolution, 0.1)
    reference = _every_cell(parts, smap)
    assert np.array_equal(smap.occupied, reference)


def test_a_part_through_a_cells_corner_occupies_that_cell() -> None:
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    smap = StaticMap.from_parts([square], 0.5, 0.0)
    assert (smap.origin_x_m, smap.origin_y_m) == (-1.0, -1.0)
    assert smap.occupied[1, 1]  # the cell [-0.5, 0) x [-0.5, 0), touching the corner (0, 0)
    assert not smap.occupied[0, 0]
