"""``nav2 export``: the governor's proved zones as a Nav2 velocity polygon (SR-NAV-3).

The governor's margin tiers (:mod:`safety.model.stopping`) are depths the stopping model proves
up to a speed: a tier of margin ``m`` covers the separation of the assumed obstacle class up to
``safe_speed_mps(m)``. Export turns them into one ``velocity_polygon`` stop zone whose
sub-polygons, one per speed band, each reach ``m`` beyond the footprint's front (the configured
footprint, plus :data:`LATERAL_MARGIN_M` on each side) for the commanded speeds up to the largest
speed that depth is proved for; bands are listed from the slowest, so at a shared edge Nav2 picks
the smaller zone, which is proved there. Tiers proved beyond the robot's maximum speed give way
to one top band as deep as the separation at the maximum speed needs (rounded up to 0.01 mm).
Every band is tight to within rounding: a zone 1 mm shallower is refuted.

Depths and band edges are computed from the file as Nav2 will read it (points as
single-precision floats, band edges as doubles), and the written text is checked with
:func:`safety.nav2.verdicts.check` before it is returned: export never writes a zone that
``nav2 check`` does not prove. ``source_timeout`` is the configuration's perception latency and
the yaw band its ``geometry.max_yaw_rate_radps``, so Nav2's reaction time is the project's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from pipeline.config import SafecaseConfig, config_hash
from safety.model.stopping import ClosingClass, Tier
from safety.nav2.obligations import Model, coverage, needed_m, safe_speed
from safety.nav2.params import Nav2Params, Vertex, parse_params
from safety.nav2.reader import nearest_float32
from safety.nav2.solver import Verdict
from safety.nav2.verdicts import build_model, check

__all__ = ["LATERAL_MARGIN_M", "Band", "export_bands", "export_yaml", "zone_vertices"]

# Each band's zone is this much wider than the footprint on each side [m], so the footprint's
# sides stay inside it after Nav2 rounds the points to single precision.
LATERAL_MARGIN_M = Fraction(1, 100)
# Band edges [m/s] and the top band's depth [m] are rounded to this (down and up).
_STEP = Fraction(1, 10**5)
_NAME = "VelocityPolygonStop"
# A stop zone ahead of the footprint: it is met travelling forward.
_TRAVEL = "forward"


def zone_vertices(x_front_m: Fraction, half_width_m: Fraction) -> tuple[Vertex, ...]:
    """The rectangle from the base frame's origin to ``x_front_m`` ahead [m], ``half_width_m``
    to each side [m], as Nav2 reads it (each coordinate the nearest single-precision float)."""
    x, y = nearest_float32(x_front_m), nearest_float32(half_width_m)
    zero = Fraction(0)
    return ((x, y), (x, -y), (zero, -y), (zero, y))


@dataclass(frozen=True, slots=True)
class Band:
    """One sub-polygon: commanded speeds ``[low, high]`` [m/s], the zone's front ``x_front_m``."""

    name: str
    low_mps: Fraction
    high_mps: Fraction
    x_front_m: Fraction
    half_width_m: Fraction
    why: str


def _decimal(value: Fraction) -> str:
    """A terminating decimal in full (every value written here has one)."""
    digits = 0
    while (value * 10**digits).denominator != 1:
        digits += 1
        if digits > 30:
            raise ValueError(f"{value} has no short decimal form")
    scaled = abs(value) * 10**digits
    text = str(scaled.numerator // scaled.denominator).rjust(digits + 1, "0")
    whole, fraction = text[: len(text) - digits], text[len(text) - digits :]
    # The least digit count that makes the value whole leaves no trailing zero to strip.
    return ("-" if value < 0 else "") + whole + "." + (fraction or "0")


def _proved_speed(model: Model, x_front: Fraction, half_width: Fraction) -> Fraction | None:
    """Largest proved speed (less one step, so Nav2's double edge stays inside) of a zone
    [m/s]; None when no speed above standstill is proved."""
    zone = coverage(zone_vertices(x_front, half_width), None, model.footprint, _TRAVEL)
    speed, _ = safe_speed(model, zone, _TRAVEL, _NAME, _STEP)
    return None if speed is None or speed <= _STEP else speed - _STEP


def export_bands(
    config: SafecaseConfig, closing: ClosingClass = ClosingClass.STATIC
) -> tuple[Band, ...]:
    """The speed bands of the exported velocity polygon, slowest first."""
    model, _ = build_model(_EMPTY, config, latency="project", closing=closing)
    stopping = model.stopping
    top = stopping.robot_max_speed_mps
    front = model.footprint.length_m / 2
    half_width = model.footprint.width_m / 2 + LATERAL_MARGIN_M
    pairs: list[tuple[Fraction, Fraction, str]] = []
    for tier in Tier:
        margin = stopping.margin_m(tier)
        speed = _proved_speed(model, front + margin, half_width)
        if speed is not None and speed < top:
            pairs.append((speed, front + margin, f"tier {tier.value}: margin {_decimal(margin)} m"))
    # Keep the staircase: a faster band needs a deeper zone; drop dominated tiers.
    staircase: list[tuple[Fraction, Fraction, str]] = []
    for speed, x_front, why in sorted(pairs, key=lambda p: (p[0], -p[1])):
        while staircase and staircase[-1][1] >= x_front:
            staircase.pop()
        staircase.append((speed, x_front, why))
    needed = needed_m(model, top)
    assert needed is not None
    # The shallowest whole step at least the separation needed that is proved at top speed.
    depth = Fraction(math.ceil(needed / _STEP)) * _STEP
    while True:
        proved = _proved_speed(model, front + depth, half_width)
        if proved is not None and proved >= top:
            break
        depth += _STEP
    staircase.append((top, front + depth, f"the maximum speed: separation {float(needed):.6g} m"))
    bands, low = [], Fraction(0)
    for i, (speed, x_front, why) in enumerate(staircase):
        bands.append(Band(f"band_{i}", low, speed, x_front, half_width, why))
        low = speed
    return tuple(bands)


_EMPTY = Nav2Params("export", "base_footprint", (), (), (), None, None, None, None, None)


def _yaml(config: SafecaseConfig, bands: tuple[Band, ...], closing: ClosingClass) -> str:
    s, g = config.stopping, config.geometry
    timeout = _decimal(Fraction(repr(s.perception_latency_s)))
    yaw = _decimal(Fraction(repr(g.max_yaw_rate_radps)))
    names = ", ".join(f'"{b.name}"' for b in bands)
    control = _decimal(Fraction(repr(s.control_cycle_s)))
    length = _decimal(Fraction(repr(g.footprint_length_m)))
    width = _decimal(Fraction(repr(g.footprint_width_m)))
    lines = [
        f"# Written by `safecase nav2 export` from the configuration {config_hash(config)[:16]}.",
        "# One stop zone, a velocity polygon: each band's zone covers the worst-case stopping",
        f"# separation (obstacle: {closing.value}) at every commanded speed of its band, as",
        "# `safecase nav2 check` proves with the project's stopping model (docs/nav2.md).",
        f"# The proof takes the data to be at most source_timeout = {timeout} s old",
        f"# (stopping.perception_latency_s) and the monitor to run every {control} s",
        "# (stopping.control_cycle_s): keep every source_timeout at or below it and feed the",
        "# monitor at least that often. The robot is the configured footprint, a",
        f"# {length} x {width} m rectangle centred on base_footprint.",
        "collision_monitor:",
        "  ros__parameters:",
        '    base_frame_id: "base_footprint"',
        '    odom_frame_id: "odom"',
        '    cmd_vel_in_topic: "cmd_vel_smoothed"',
        '    cmd_vel_out_topic: "cmd_vel"',
        '    state_topic: "collision_monitor_state"',
        "    transform_tolerance: 0.1",
        f"    source_timeout: {timeout}",
        "    base_shift_correction: True",
        "    stop_pub_timeout: 2.0",
        f'    polygons: ["{_NAME}"]',
        f"    {_NAME}:",
        '      type: "velocity_polygon"',
        '      action_type: "stop"',
        "      min_points: 4",
        "      visualize: True",
        "      enabled: True",
        '      polygon_pub_topic: "velocity_polygon_stop"',
        "      holonomic: false",
        f"      velocity_polygons: [{names}]",
    ]
    for band in bands:
        x, y = _decimal(band.x_front_m), _decimal(band.half_width_m)
        lines += [
            f"      {band.name}:",
            f"        # {band.why}; zone {_decimal(band.x_front_m)} m ahead of base_footprint",
            f'        points: "[[{x}, {y}], [{x}, -{y}], [0.0, -{y}], [0.0, {y}]]"',
            f"        linear_min: {_decimal(band.low_mps)}",
            f"        linear_max: {_decimal(band.high_mps)}",
            f"        theta_min: -{yaw}",
            f"        theta_max: {yaw}",
        ]
    lines += [
        '    observation_sources: ["scan"]',
        "    scan:",
        '      type: "scan"',
        '      topic: "scan"',
        f"      source_timeout: {timeout}",
        "      enabled: True",
    ]
    return "\n".join(lines) + "\n"


def export_yaml(config: SafecaseConfig, closing: ClosingClass = ClosingClass.STATIC) -> str:
    """The collision_monitor parameter file, checked: every zone of it is PROVED (SR-NAV-3)."""
    text = _yaml(config, export_bands(config, closing), closing)
    # check's default data age is Nav2's own: the file's source_timeout.
    report = check(parse_params(text, "export"), config, closing=closing)
    if report.verdict is not Verdict.PROVED:
        failed = [f.label for f in report.findings if f.verdict is not Verdict.PROVED]
        raise RuntimeError(f"nav2 export: the exported zones are not all proved: {failed}")
    return text
