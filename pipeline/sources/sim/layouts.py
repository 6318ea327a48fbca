"""Static layouts: a warehouse aisle between pallet racks, and an apron stand (SR-SIM-1, -3).

Warehouse figures: adjustable pallet racking bays of 2.7 m (three 800 mm-wide Euro pallets per
beam pair, the common bay width in FEM 10.2.02-style layouts), frame depth 1.1 m, upright
profiles about 0.1 m square; counterbalance-truck aisles of ~3.5 m and reach-truck aisles of
2.7-3.0 m. At the scanner's height (~0.2 m) a rack shows its uprights and whatever stands on
the floor level: pallet loads set 50 mm back from the upright face. Behind each rack row is a
wall (standing in for the next, back-to-back row).

Apron figures: an Airbus A320 parked on its stand (Airbus "A320 Aircraft Characteristics"
document: wheelbase 12.64 m, main-gear track 7.59 m; main tyres 46 x 16 in, nose tyres
30 x 8.8 in), cut at 0.2 m height: a tyre of diameter D shows a chord of
2 sqrt(h (D - h)), i.e. 0.88 m for the mains and 0.67 m for the nose tyres. Traffic cones
(~0.2 m across at scan height) mark the engines; a ground power unit (2.0 x 1.2 m) stands by.

All layouts are in the world frame (metres), x along the ego robot's main direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.sources.sim.shapes import rectangle, regular_polygon
from pipeline.sources.sim.world import Structure
from pipeline.types import FloatArray

__all__ = ["AisleLayout", "ApronLayout", "apron_stand", "warehouse_aisle"]

BAY_M = 2.7
RACK_DEPTH_M = 1.1
UPRIGHT_M = 0.1


@dataclass(frozen=True, slots=True)
class AisleLayout:
    """A main aisle along x, ``|y| <= half_width_m``, from ``x_start_m`` to ``x_end_m``, with
    cross aisles (gaps through both rack rows) over the given x intervals."""

    structure: Structure
    half_width_m: float
    x_start_m: float
    x_end_m: float
    cross_aisles_m: tuple[tuple[float, float], ...]
    bounds_m: tuple[float, float, float, float]


def _rack_row(
    x0: float, x1: float, face_y: float, side: float, rng: np.random.Generator, fill: float
) -> list[tuple[str, FloatArray]]:
    """Uprights and floor-level pallet loads of one rack row facing the aisle at ``face_y``;
    ``side`` = +1 for the row at +y, -1 for the row at -y."""
    parts: list[tuple[str, FloatArray]] = []
    n_bays = max(1, int((x1 - x0 + 1e-9) // BAY_M))
    back_y = face_y + side * RACK_DEPTH_M
    for k in range(n_bays + 1):
        ux = x0 + k * BAY_M
        for y_edge in (face_y, back_y - side * UPRIGHT_M):
            y_lo, y_hi = sorted((y_edge, y_edge + side * UPRIGHT_M))
            parts.append(("rack_upright", rectangle(ux, ux + UPRIGHT_M, y_lo, y_hi)))
    for k in range(n_bays):
        bx = x0 + k * BAY_M + UPRIGHT_M
        for j in range(3):
            if rng.random() >= fill:
                continue
            px = bx + 0.05 + j * 0.86
            y_near = face_y + side * 0.05
            y_lo, y_hi = sorted((y_near, y_near + side * 1.0))
            parts.append(("pallet_load", rectangle(px, px + 0.80, y_lo, y_hi)))
    return parts


def warehouse_aisle(
    rng: np.random.Generator,
    *,
    length_m: float = 36.0,
    aisle_width_m: float = 3.5,
    x_start_m: float = -4.0,
    cross_aisles_m: tuple[tuple[float, float], ...] = (),
    pallet_fill: float = 0.7,
) -> AisleLayout:
    """A main aisle between two rack rows, interrupted by cross aisles, with end walls."""
    half = aisle_width_m / 2
    x_end = x_start_m + length_m
    gaps = sorted(cross_aisles_m)
    for lo, hi in gaps:
        if not (x_start_m < lo < hi < x_end):
            raise ValueError(f"cross aisle [{lo}, {hi}] must lie inside [{x_start_m}, {x_end}]")
    runs: list[tuple[float, float]] = []
    cursor = x_start_m
    for lo, hi in gaps:
        runs.append((cursor, lo))
        cursor = hi
    runs.append((cursor, x_end))
    parts: list[tuple[str, FloatArray]] = []
    wall_y = half + RACK_DEPTH_M
    for lo, hi in runs:
        if hi - lo < BAY_M / 2:
            continue
        for side in (1.0, -1.0):
            parts.extend(_rack_row(lo, hi, side * half, side, rng, pallet_fill))
            y0 = side * wall_y
            y_lo, y_hi = sorted((y0, y0 + side * 0.2))
            parts.append(("wall", rectangle(lo, hi, y_lo, y_hi)))
    span = wall_y + 5.5
    parts.append(("wall", rectangle(x_start_m - 0.3, x_start_m, -span, span)))
    parts.append(("wall", rectangle(x_end + 3.0, x_end + 3.3, -span, span)))
    bounds = (x_start_m - 0.5, x_end + 3.5, -span, span)
    return AisleLayout(
        structure=Structure.from_parts(parts),
        half_width_m=half,
        x_start_m=x_start_m,
        x_end_m=x_end,
        cross_aisles_m=tuple(gaps),
        bounds_m=bounds,
    )


@dataclass(frozen=True, slots=True)
class ApronLayout:
    """An apron area; the service road runs along x at ``|y| <= road_half_width_m``."""

    structure: Structure
    road_half_width_m: float
    bounds_m: tuple[float, float, float, float]
    decor: tuple[tuple[str, FloatArray], ...]


def apron_stand(
    *,
    nose_xy_m: tuple[float, float] = (-8.0, 36.0),
    road_half_width_m: float = 3.0,
) -> ApronLayout:
    """An A320 parked nose-in at ``nose_xy_m`` (nose gear; fuselage along +y towards the
    terminal wall), its main gears 12.64 m aft, cones, a GPU; the service road along x at
    y = 0 passes behind the tail (the fuselage itself is above the scan plane)."""
    chord_main = 2 * math.sqrt(0.2 * (1.168 - 0.2))
    chord_nose = 2 * math.sqrt(0.2 * (0.762 - 0.2))
    nx, ny = nose_xy_m
    parts: list[tuple[str, FloatArray]] = []
    # Nose gear: two 30 x 8.8 in tyres; fuselage along y, so tyre chords run along y.
    for s in (-0.25, 0.25):
        parts.append(
            (
                "aircraft_tyre",
                rectangle(nx + s - 0.112, nx + s + 0.112, ny - chord_nose / 2, ny + chord_nose / 2),
            )
        )
    # Main gears 12.64 m aft of the nose gear; the aircraft faces the terminal at +y.
    my = ny - 12.64
    for side in (-1.0, 1.0):
        gx = nx + side * 7.59 / 2
        for s in (-0.465, 0.465):
            parts.append(
                (
                    "aircraft_tyre",
                    rectangle(
                        gx + s - 0.203, gx + s + 0.203, my - chord_main / 2, my + chord_main / 2
                    ),
                )
            )
    for cx, cy in (
        (nx - 5.8, my + 2.5),
        (nx + 5.8, my + 2.5),
        (nx, ny + 4.5),
        (nx - 9.0, my - 1.0),
        (nx + 9.0, my - 1.0),
    ):
        parts.append(("cone", regular_polygon(0.11, 8, (cx, cy))))
    parts.append(("gpu", rectangle(nx + 3.0, nx + 5.0, ny + 1.0, ny + 2.2)))
    parts.append(("wall", rectangle(nx - 10.0, nx + 52.0, ny + 7.0, ny + 7.4)))
    bounds = (nx - 10.0, nx + 52.0, -8.0, ny + 7.6)
    # Silhouette for pictures only (A320: length 37.57 m, span 35.8 m, fuselage 3.95 m wide;
    # nose 5.07 m ahead of the nose gear), all of it above the scan plane.
    nose = ny + 5.07
    tail = nose - 37.57
    hw = 1.975
    silhouette = np.array(
        [
            [nx, nose],
            [nx - hw, nose - 3.0],
            [nx - hw, my + 3.5],
            [nx - 17.9, my - 3.0],
            [nx - 17.9, my - 4.5],
            [nx - hw, my - 1.5],
            [nx - hw, tail + 5.0],
            [nx - 6.2, tail + 1.5],
            [nx - 6.2, tail],
            [nx + 6.2, tail],
            [nx + 6.2, tail + 1.5],
            [nx + hw, tail + 5.0],
            [nx + hw, my - 1.5],
            [nx + 17.9, my - 4.5],
            [nx + 17.9, my - 3.0],
            [nx + hw, my + 3.5],
            [nx + hw, nose - 3.0],
        ]
    )
    return ApronLayout(
        structure=Structure.from_parts(parts),
        road_half_width_m=road_half_width_m,
        bounds_m=bounds,
        decor=(("A320 (above the scan plane)", silhouette),),
    )
