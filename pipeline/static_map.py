"""The site's static map: where the fixed structure is, as an occupancy grid (SR-AVL-8).

A warehouse robot is given the map it localises in; Nav2 reads it as a YAML file naming an
image (``map_server``'s format: ``image``, ``resolution``, ``origin``, ``negate``,
``occupied_thresh``, ``free_thresh``, ``mode``). :meth:`StaticMap.from_nav2` reads that file,
:meth:`StaticMap.from_parts` rasterises known polygons (the simulated world's racking and
walls) and :meth:`StaticMap.write_nav2` writes the same format back.

The grid is in the map frame, which the runtime takes to be its tracking frame (assumption A-11:
the localisation keeps the two within ``map.tolerance_m``). Row 0 is the lowest ``y``; cell
``(r, c)`` covers ``[x0 + c h, x0 + (c + 1) h) x [y0 + r h, y0 + (r + 1) h)`` for resolution
``h`` and origin ``(x0, y0)``.

A point is **covered** when its cell's centre lies within ``tolerance_m`` of an occupied cell's
centre (the grid dilated by a disc). The bounds this gives (checked against shapely in
``properties/test_static_map.py``):

* a covered point lies within ``tolerance_m + sqrt(2) h / 2`` of an occupied cell's centre;
* :meth:`from_parts` marks a cell occupied when its centre lies within ``sqrt(2) h / 2`` of a
  part (every cell a part touches, and cells beside them whose centre is that close), so every
  point of a part is covered and a covered point lies within :meth:`StaticMap.reach_m`
  ``= tolerance_m + sqrt(2) h`` of a part.

:func:`clusters_on_map` says which clusters lie wholly on the map: every one of their returns
covered.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from scipy import ndimage

from pipeline.config import SafecaseConfig
from pipeline.errors import ConfigError
from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = ["StaticMap", "checked_map", "clusters_on_map", "map_from_config"]

_NAV2_KEYS = ("image", "resolution", "origin")
_FREE_PIXEL = 254
_OCCUPIED_PIXEL = 0


def _refused(line: str) -> ConfigError:
    """A configuration error of one line (the map file or value, what is allowed)."""
    return ConfigError([line])


@dataclass(frozen=True)
class StaticMap:
    """An occupancy grid of the fixed structure and its covered cells (module docstring).

    ``occupied`` (rows, cols) is the map; ``covered`` the same grid dilated by a disc of
    ``tolerance_m`` (cell centre to cell centre); ``source`` names where it came from.
    """

    occupied: BoolArray
    covered: BoolArray
    resolution_m: float
    origin_x_m: float
    origin_y_m: float
    tolerance_m: float
    source: str

    @classmethod
    def from_grid(
        cls,
        occupied: BoolArray,
        resolution_m: float,
        origin_xy_m: tuple[float, float],
        tolerance_m: float,
        source: str,
    ) -> StaticMap:
        """A map of ``occupied`` (row 0 the lowest ``y``), its covered cells computed here."""
        if not (math.isfinite(resolution_m) and resolution_m > 0.0):
            raise _refused(f"{source}: resolution must be a positive number, got {resolution_m}")
        if not (math.isfinite(tolerance_m) and tolerance_m >= 0.0):
            raise _refused(f"{source}: tolerance must be >= 0, got {tolerance_m}")
        grid = np.asarray(occupied, dtype=bool)
        if grid.ndim != 2 or 0 in grid.shape:
            raise _refused(f"{source}: the map must be a non-empty 2-D grid, got {grid.shape}")
        reach = math.floor(tolerance_m / resolution_m)
        offsets = np.arange(-reach, reach + 1)
        disc = np.hypot(offsets[:, None], offsets[None, :]) * resolution_m <= tolerance_m
        covered = ndimage.binary_dilation(grid, structure=disc) if reach else grid.copy()
        grid.setflags(write=False)
        covered.setflags(write=False)
        x0, y0 = (float(v) for v in origin_xy_m)
        return cls(grid, covered, float(resolution_m), x0, y0, float(tolerance_m), source)

    @classmethod
    def from_parts(
        cls,
        parts: list[FloatArray],
        resolution_m: float,
        tolerance_m: float,
        source: str = "parts",
    ) -> StaticMap:
        """Rasterise closed polygons ``parts`` (each (V, 2), metres): a cell is occupied when
        its centre lies within ``sqrt(2) h / 2`` of a part (module docstring)."""
        if not parts:
            raise _refused(f"{source}: a static map needs at least one part")
        union = shapely.unary_union([shapely.Polygon(p) for p in parts])
        h = float(resolution_m)
        pad = tolerance_m + 2.0 * h
        x_lo, y_lo, x_hi, y_hi = union.bounds
        x0, y0 = math.floor((x_lo - pad) / h) * h, math.floor((y_lo - pad) / h) * h
        cols = math.ceil((x_hi + pad - x0) / h)
        rows = math.ceil((y_hi + pad - y0) / h)
        gx, gy = np.meshgrid(x0 + (np.arange(cols) + 0.5) * h, y0 + (np.arange(rows) + 0.5) * h)
        # A part through a cell's corner is at exactly sqrt(2) h / 2 from its centre; the slack
        # keeps that tie on the occupied side whatever the rounding of the distance.
        reach = math.sqrt(0.5) * h * (1.0 + 1e-12)
        # Only cells whose centre lies in some part's bounding box grown by the reach (and a
        # cell more, against rounding) can be near it; the rest of the grid is aisle.
        candidate = np.zeros((rows, cols), dtype=bool)
        for part in parts:
            lo = (part.min(axis=0) - reach - h - (x0, y0)) / h
            hi = (part.max(axis=0) + reach + h - (x0, y0)) / h
            c0, r0 = (max(0, math.floor(v)) for v in lo)
            c1, r1 = math.ceil(hi[0]) + 1, math.ceil(hi[1]) + 1
            candidate[r0:r1, c0:c1] = True
        r, c = np.nonzero(candidate)
        shapely.prepare(union)
        near = np.zeros((rows, cols), dtype=bool)
        near[r, c] = shapely.dwithin(union, shapely.points(gx[r, c], gy[r, c]), reach)
        return cls.from_grid(near, h, (x0, y0), tolerance_m, source)

    @classmethod
    def from_nav2(cls, path: Path | str, tolerance_m: float) -> StaticMap:
        """Read a Nav2 ``map_server`` YAML file and its image (trinary interpretation: a pixel
        is occupied when its occupancy probability exceeds ``occupied_thresh``)."""
        from PIL import Image  # matplotlib's dependency; only map files need it
        from ruamel.yaml import YAML

        yaml_path = Path(path)
        if not yaml_path.is_file():
            raise _refused(f"map.file: no such map file: {yaml_path}")
        meta: Any = YAML(typ="safe").load(yaml_path.read_text(encoding="utf-8"))
        if not isinstance(meta, dict) or any(k not in meta for k in _NAV2_KEYS):
            raise _refused(
                f"{yaml_path}: a Nav2 map file needs the keys {', '.join(_NAV2_KEYS)}; "
                f"got {sorted(meta) if isinstance(meta, dict) else type(meta).__name__}"
            )
        origin = meta["origin"]
        if not (isinstance(origin, list) and len(origin) == 3):
            raise _refused(f"{yaml_path}: origin must be [x, y, yaw], got {origin!r}")
        if float(origin[2]) != 0.0:
            raise _refused(
                f"{yaml_path}: origin yaw {origin[2]} is not supported; allowed: 0 (as most of "
                "Nav2 assumes)"
            )
        mode = meta.get("mode", "trinary")
        if mode not in ("trinary", "scale"):
            raise _refused(f"{yaml_path}: mode {mode!r}; allowed: trinary, scale")
        image_path = yaml_path.parent / str(meta["image"])
        if not image_path.is_file():
            raise _refused(f"{yaml_path}: its image {image_path} does not exist")
        with Image.open(image_path) as image:
            pixels = np.asarray(image.convert("L"), dtype=np.float64)
        negate = bool(int(meta.get("negate", 0)))
        occupancy = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
        occupied = occupancy > float(meta.get("occupied_thresh", 0.65))
        return cls.from_grid(
            occupied[::-1],
            float(meta["resolution"]),
            (float(origin[0]), float(origin[1])),
            tolerance_m,
            str(yaml_path),
        )

    def write_nav2(self, yaml_path: Path | str) -> Path:
        """Write the map as a Nav2 YAML file and a PGM image beside it; returns the YAML."""
        from PIL import Image

        out = Path(yaml_path)
        image_path = out.with_suffix(".pgm")
        pixels = np.where(self.occupied[::-1], _OCCUPIED_PIXEL, _FREE_PIXEL).astype(np.uint8)
        Image.fromarray(pixels, mode="L").save(image_path)
        out.write_text(
            f"image: {image_path.name}\nmode: trinary\nresolution: {self.resolution_m!r}\n"
            f"origin: [{self.origin_x_m!r}, {self.origin_y_m!r}, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.196\n",
            encoding="utf-8",
        )
        return out

    def reach_m(self) -> float:
        """How far from a part a covered point of a :meth:`from_parts` map can lie [m]."""
        return self.tolerance_m + math.sqrt(2.0) * self.resolution_m

    def cells(self, x_m: FloatArray, y_m: FloatArray) -> tuple[IntArray, IntArray, BoolArray]:
        """Row and column of each point's cell, and whether it lies on the grid."""
        col = np.floor((np.asarray(x_m) - self.origin_x_m) / self.resolution_m)
        row = np.floor((np.asarray(y_m) - self.origin_y_m) / self.resolution_m)
        rows, cols = self.occupied.shape
        inside = (row >= 0) & (row < rows) & (col >= 0) & (col < cols)
        return (
            np.where(inside, row, 0).astype(np.int64),
            np.where(inside, col, 0).astype(np.int64),
            inside,
        )

    def covers(self, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
        """Per point (map frame, metres): whether it is covered (off the grid: not; NaN: not)."""
        row, col, inside = self.cells(x_m, y_m)
        hit: BoolArray = inside & self.covered[row, col]
        return hit


def clusters_on_map(
    static_map: StaticMap, labels: IntArray, x_m: FloatArray, y_m: FloatArray, n_clusters: int
) -> BoolArray:
    """Per cluster ``0..n_clusters-1``: every return labelled with it is covered (points in the
    map frame; label -1 is noise and ignored). A cluster with no return is not on the map."""
    labels = np.asarray(labels, dtype=np.int64)
    member = (labels >= 0) & (labels < n_clusters)
    lab = labels[member]
    uncovered = ~static_map.covers(np.asarray(x_m)[member], np.asarray(y_m)[member])
    bad = np.bincount(lab, weights=uncovered.astype(np.float64), minlength=n_clusters)
    count = np.bincount(lab, minlength=n_clusters)
    on: BoolArray = (bad == 0) & (count > 0)
    return on


def checked_map(static_map: StaticMap, config: SafecaseConfig) -> StaticMap:
    """``static_map`` if its reach (:meth:`StaticMap.reach_m`) stays below
    ``runtime.person_radius_m`` (as :class:`~pipeline.config.MapSection` requires), else a
    :class:`~pipeline.errors.ConfigError` naming the map, its reach and the bound."""
    radius = config.runtime.person_radius_m
    if static_map.reach_m() >= radius:
        raise _refused(
            f"{static_map.source}: tolerance {static_map.tolerance_m} m + sqrt(2) x resolution "
            f"{static_map.resolution_m} m = {static_map.reach_m():.4g} m must be below "
            f"runtime.person_radius_m ({radius})"
        )
    return static_map


def map_from_config(config: SafecaseConfig) -> StaticMap | None:
    """The map ``map.file`` names (None when it is empty), checked by :func:`checked_map`."""
    section = config.map
    if not section.file:
        return None
    return checked_map(StaticMap.from_nav2(section.file, section.tolerance_m), config)
