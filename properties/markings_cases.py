"""Case builders for the marking properties (SR-MRK-1..4): a small scanner for test time, a
single straight stripe placed relative to a robot, a map with nothing near the robot, and
noisy points on a known line or arc."""

from __future__ import annotations

import math

import numpy as np

from pipeline.config import MarkingsSection, SafecaseConfig
from pipeline.sensors.marking_map import MarkingMap
from pipeline.sensors.markings import Markings, RingScan, detect_markings
from pipeline.sources.sim.rings import Cylinders, RingTruth, Surface, ring_scan
from pipeline.types import BoolArray, FloatArray, Pose

__all__ = [
    "arc_points",
    "bare_map",
    "detected",
    "line_points",
    "small_markings",
    "stripe_map",
]


def small_markings(config: SafecaseConfig, n_columns: int = 720) -> MarkingsSection:
    """The configured section with fewer columns a revolution (0.5 deg at 720): test time."""
    return config.markings.model_copy(update={"n_columns": n_columns})


def stripe_map(pose: Pose, offset_m: float, angle_rad: float, length_m: float = 40.0) -> MarkingMap:
    """One straight 0.15 m stripe whose centre line passes ``offset_m`` from the robot at
    ``pose``, turned ``angle_rad`` from the robot's heading, centred on the foot of the
    perpendicular."""
    heading = pose[2] + angle_rad
    ux, uy = math.cos(heading), math.sin(heading)
    fx, fy = pose[0] - offset_m * uy, pose[1] + offset_m * ux  # a positive offset: on the left
    half = 0.5 * length_m
    seg = np.array([[fx - half * ux, fy - half * uy, fx + half * ux, fy + half * uy]])
    return MarkingMap(seg, np.zeros((0, 5)))


def bare_map() -> MarkingMap:
    """A map whose only marking is 5 km away: every return near the robot is bare asphalt."""
    return MarkingMap(np.array([[5000.0, 5000.0, 5010.0, 5000.0]]), np.zeros((0, 5)))


def line_points(
    rng: np.random.Generator,
    n_in: int,
    n_out: int,
    angle_rad: float,
    offset_m: float,
    noise_m: float,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """``n_in`` points on the line at distance ``offset_m`` from the origin with direction
    ``angle_rad`` (along 10 m, perpendicular noise ``noise_m``) and ``n_out`` uniform outliers
    in the surrounding 12 m square; the mask marks the line's points."""
    ux, uy = math.cos(angle_rad), math.sin(angle_rad)
    t = rng.uniform(-5.0, 5.0, n_in)
    e = rng.normal(0.0, noise_m, n_in)
    x = -offset_m * uy + t * ux - e * uy
    y = offset_m * ux + t * uy + e * ux
    ox = rng.uniform(-6.0, 6.0, n_out) - offset_m * uy
    oy = rng.uniform(-6.0, 6.0, n_out) + offset_m * ux
    mask = np.concatenate([np.ones(n_in, bool), np.zeros(n_out, bool)])
    return np.concatenate([x, ox]), np.concatenate([y, oy]), mask


def arc_points(
    rng: np.random.Generator,
    n: int,
    centre: tuple[float, float],
    radius_m: float,
    start_rad: float,
    sweep_rad: float,
    noise_m: float,
) -> tuple[FloatArray, FloatArray]:
    """``n`` points on an arc with radial noise ``noise_m``."""
    a = start_rad + rng.uniform(0.0, sweep_rad, n)
    r = radius_m + rng.normal(0.0, noise_m, n)
    return centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)


def detected(
    config: MarkingsSection,
    pose: Pose,
    marking_map: MarkingMap,
    surface: Surface,
    seed: int,
    cylinders: Cylinders | None = None,
) -> tuple[RingScan, RingTruth, Markings]:
    """One simulated revolution from ``pose`` (noise from ``seed``), what it hit, and what the
    detector made of it."""
    rng = np.random.default_rng(seed)
    scan, truth = ring_scan(config, pose, marking_map, surface, rng, cylinders=cylinders)
    return scan, truth, detect_markings(scan, config)
