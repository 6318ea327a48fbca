"""A Nav2 collision_monitor parameter file, validated, in Nav2's own reading (SR-NAV-4).

What is read (layout of ``nav2_collision_monitor``; see docs/nav2.md):

* ``collision_monitor: ros__parameters:`` with ``polygons: [...]``, each polygon's ``type``
  (``polygon`` | ``circle`` | ``velocity_polygon``), ``action_type`` (``stop`` | ``slowdown`` |
  ``limit`` | ``approach`` | ``none``), ``points`` (the string ``"[[x, y], ...]"`` of recent
  releases, parsed as single-precision floats as Nav2 does, or the flat list ``[x1, y1, x2, ...]``
  of older ones), ``radius``, ``min_points`` (or the older ``max_points`` = min_points - 1),
  ``slowdown_ratio``, ``linear_limit``, ``time_before_collision``, ``simulation_time_step``,
  ``enabled``; a velocity polygon's ``holonomic`` and ``velocity_polygons`` sub-list, each with
  ``points``, ``linear_min``, ``linear_max``, ``theta_min``, ``theta_max`` (and, holonomic,
  ``direction_start_angle``, ``direction_end_angle``); ``observation_sources`` with each
  source's ``type``, ``enabled`` and ``source_timeout`` (default: the node's ``source_timeout``,
  2.0 s; 0 disables Nav2's stop on stale data); ``base_frame_id``.
* The robot's speed limits, when the same file holds them: ``velocity_smoother`` ``max_velocity`` /
  ``min_velocity`` ``[x, y, theta]`` and ``smoothing_frequency``; ``controller_server``
  ``controller_frequency`` and, per controller plugin, DWB's ``max_vel_x``, ``min_vel_x``,
  ``max_vel_y``, ``max_vel_theta``, MPPI's ``vx_max``, ``vx_min``, ``vy_max``, ``wz_max``, Regulated
  Pure Pursuit's ``desired_linear_vel``. Where several give a limit, the largest is kept (the
  robot may be driven by any of them).

Anything malformed raises :class:`~safety.nav2.reader.Nav2ParamsError` naming the key, the value
and what is allowed.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass, replace
from fractions import Fraction
from pathlib import Path
from typing import Any

from safety.nav2.reader import (
    MAX_ABS_VALUE,
    Nav2ParamsError,
    Section,
    load_yaml,
    nearest_float32,
    node_parameters,
    parse_yaml,
)

__all__ = [
    "ACTIONS",
    "SHAPES",
    "Limit",
    "Nav2Params",
    "Source",
    "SubPolygon",
    "Vertex",
    "Zone",
    "load_params",
    "parse_params",
    "parse_points",
]

ACTIONS = ("stop", "slowdown", "limit", "approach", "none")
SHAPES = ("polygon", "circle", "velocity_polygon")
SOURCE_TYPES = ("scan", "pointcloud", "range", "polygon")
# Nav2's defaults (configuring-collision-monitor-node).
DEFAULT_SOURCE_TIMEOUT_S = Fraction(2)
DEFAULT_MIN_POINTS = 4
# Bounded work: the exact geometry is quadratic in the vertices, the velocity-band search in the
# number of bands (Nav2 configurations use a handful of each).
MAX_VERTICES = 256
MAX_BANDS = 32
PI = Fraction(3.141592653589793)

Vertex = tuple[Fraction, Fraction]

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_PAIR = rf"\[({_NUMBER}),({_NUMBER})\]"
_POINTS = re.compile(rf"\[(?:{_PAIR}(?:,{_PAIR})*)?\]")
_POINTS_ALLOWED = (
    '"[[x, y], [x, y], ...]" with at least 3 vertices, or a flat list [x1, y1, x2, y2, ...]'
)


@dataclass(frozen=True, slots=True)
class SubPolygon:
    """One entry of a velocity polygon: a shape used while the command is in its band."""

    name: str
    vertices: tuple[Vertex, ...]
    linear_min_mps: Fraction
    linear_max_mps: Fraction
    theta_min_radps: Fraction
    theta_max_radps: Fraction
    direction_start_rad: Fraction
    direction_end_rad: Fraction


@dataclass(frozen=True, slots=True)
class Zone:
    """One listed polygon of the collision monitor, in the base frame [m].

    Exactly one of ``vertices`` (static polygon), ``radius_m`` (static circle), ``subpolygons``
    (velocity polygon) or ``dynamic_topic`` (shape set at run time) describes the shape.
    """

    name: str
    shape: str
    action: str
    enabled: bool
    min_points: int
    vertices: tuple[Vertex, ...] | None = None
    radius_m: Fraction | None = None
    subpolygons: tuple[SubPolygon, ...] = ()
    holonomic: bool = False
    dynamic_topic: str | None = None
    slowdown_ratio: Fraction | None = None
    linear_limit_mps: Fraction | None = None
    time_before_collision_s: Fraction | None = None
    simulation_time_step_s: Fraction | None = None


@dataclass(frozen=True, slots=True)
class Source:
    """An observation source; ``timeout_s`` 0 means Nav2 never stops on its stale data."""

    name: str
    type: str
    enabled: bool
    timeout_s: Fraction


@dataclass(frozen=True, slots=True)
class Limit:
    """A value [m/s, rad/s or s] and where it came from (a parameter, an option, the config)."""

    value: Fraction
    source: str


@dataclass(frozen=True, slots=True)
class Nav2Params:
    """The collision monitor's zones and sources, and the robot limits the file gives."""

    name: str
    base_frame_id: str
    zones: tuple[Zone, ...]
    unlisted: tuple[str, ...]
    sources: tuple[Source, ...]
    forward: Limit | None
    reverse: Limit | None
    lateral: Limit | None
    yaw_rate: Limit | None
    control_period: Limit | None

    def data_age_bound_s(self) -> Fraction | None:
        """The oldest data the monitor may act on [s]: the largest enabled source_timeout.

        None when unbounded: a source with ``source_timeout: 0`` (Nav2 then uses its data
        however old) or no enabled source at all (nothing fresh ever arrives).
        """
        timeouts = [s.timeout_s for s in self.sources if s.enabled]
        if not timeouts or min(timeouts) == 0:
            return None
        return max(timeouts)


def parse_points(section: Section, name: str, *, required: bool) -> tuple[Vertex, ...] | None:
    """Polygon vertices in either encoding, as the exact values Nav2 computes with."""
    value = section.data.get(name)
    if value is None:
        if required:
            raise section.fail(name, value, _POINTS_ALLOWED)
        return None
    if isinstance(value, str):
        compact = "".join(value.split())
        if len(compact) > 100_000 or _POINTS.fullmatch(compact) is None:
            raise section.fail(name, value, _POINTS_ALLOWED)
        numbers = re.findall(_NUMBER, compact)
        # parseVVF reads the string into single-precision floats.
        coords = [nearest_float32(Fraction(n)) for n in numbers]
    elif isinstance(value, list):
        if len(value) % 2:
            raise section.fail(name, value, _POINTS_ALLOWED)
        coords = [section.as_number(name, v) for v in value]
    else:
        raise section.fail(name, value, _POINTS_ALLOWED)
    if any(abs(c) > MAX_ABS_VALUE for c in coords):
        raise section.fail(name, value, f"coordinates within +-{int(MAX_ABS_VALUE)} m")
    vertices = tuple((coords[i], coords[i + 1]) for i in range(0, len(coords), 2))
    if len(set(vertices)) < 3:
        raise section.fail(name, value, _POINTS_ALLOWED)
    if len(vertices) > MAX_VERTICES:
        raise section.fail(name, value, f"at most {MAX_VERTICES} vertices")
    return vertices


def _subpolygon(parent: Section, name: str, holonomic: bool) -> SubPolygon:
    sub = parent.section(name, required=True)
    assert sub is not None
    vertices = parse_points(sub, "points", required=True)
    assert vertices is not None
    values: dict[str, Fraction] = {}
    for key in ("linear_min", "linear_max", "theta_min", "theta_max"):
        if not sub.has(key):
            raise sub.fail(key, None, "a number (required)")
        values[key] = sub.as_number(key, sub.data[key])
    start = sub.number("direction_start_angle", -PI) if holonomic else -PI
    end = sub.number("direction_end_angle", PI) if holonomic else PI
    for low, high in (("linear_min", "linear_max"), ("theta_min", "theta_max")):
        if values[low] > values[high]:
            raise sub.fail(high, sub.data[high], f"a number >= {low} ({float(values[low]):g})")
    return SubPolygon(
        name,
        vertices,
        values["linear_min"],
        values["linear_max"],
        values["theta_min"],
        values["theta_max"],
        start,
        end,
    )


def _zone(section: Section, name: str) -> Zone:
    shape = section.choice("type", SHAPES)
    action = section.choice("action_type", ACTIONS)
    min_points = section.integer("min_points", DEFAULT_MIN_POINTS, low=1)
    # Humble's max_points is the most points still allowed: one more stops; it wins if given.
    min_points = section.integer("max_points", min_points - 1, low=0) + 1
    zero = Fraction(0)
    zone = Zone(name, shape, action, section.boolean("enabled", True), min_points)
    if action == "slowdown":
        ratio = section.number("slowdown_ratio", Fraction(1, 2), low=zero, high=Fraction(1))
        zone = replace(zone, slowdown_ratio=ratio)
    elif action == "limit":
        limit = section.number("linear_limit", Fraction(1, 2), low=zero)
        zone = replace(zone, linear_limit_mps=limit)
    elif action == "approach":
        before = section.number("time_before_collision", Fraction(2), low=zero, low_open=True)
        step = section.number("simulation_time_step", Fraction(1, 10), low=zero, low_open=True)
        zone = replace(zone, time_before_collision_s=before, simulation_time_step_s=step)
    if shape == "velocity_polygon":
        holonomic = section.boolean("holonomic", False)
        subs = section.names("velocity_polygons", required=True)
        if len(subs) > MAX_BANDS:
            raise section.fail("velocity_polygons", list(subs), f"at most {MAX_BANDS} names")
        parts = tuple(_subpolygon(section, s, holonomic) for s in subs)
        return replace(zone, subpolygons=parts, holonomic=holonomic)
    if shape == "circle":
        radius = section.number("radius", low=zero, low_open=True)
        if radius is not None:
            return replace(zone, radius_m=radius)
    else:
        vertices = parse_points(section, "points", required=False)
        if vertices is not None:
            return replace(zone, vertices=vertices)
    # No static shape: Nav2 takes it from a topic at run time.
    if action == "approach":
        topic = section.string("footprint_topic", "local_costmap/published_footprint")
    else:
        topic = section.string("polygon_sub_topic")
    if topic is None:
        what = "points" if shape == "polygon" else "radius"
        raise section.fail(what, None, f"the {what} of the zone, or a polygon_sub_topic")
    return replace(zone, dynamic_topic=topic)


def _sources(node: Section) -> tuple[Source, ...]:
    default_timeout = node.number("source_timeout", DEFAULT_SOURCE_TIMEOUT_S, low=Fraction(0))
    assert default_timeout is not None
    sources = []
    for name in node.names("observation_sources", required=True):
        section = node.section(name, required=False) or Section({}, node.key(name))
        timeout = section.number("source_timeout", default_timeout, low=Fraction(0))
        assert timeout is not None
        sources.append(
            Source(
                name,
                section.choice("type", SOURCE_TYPES, "scan"),
                section.boolean("enabled", True),
                timeout,
            )
        )
    return tuple(sources)


def _largest(candidates: list[tuple[Fraction, str]]) -> Limit | None:
    if not candidates:
        return None
    value = max(max(v for v, _ in candidates), Fraction(0))
    return Limit(value, ", ".join(s for _, s in candidates))


def _robot_limits(data: dict[str, object]) -> dict[str, Limit | None]:
    forward: list[tuple[Fraction, str]] = []
    reverse: list[tuple[Fraction, str]] = []
    lateral: list[tuple[Fraction, str]] = []
    yaw: list[tuple[Fraction, str]] = []
    frequencies: list[tuple[Fraction, str]] = []
    smoother = node_parameters(data, "velocity_smoother")
    if smoother is not None:
        high, low = smoother.triple("max_velocity"), smoother.triple("min_velocity")
        if high is not None:
            forward.append((high[0], smoother.key("max_velocity[0]")))
            lateral.append((abs(high[1]), smoother.key("max_velocity[1]")))
            yaw.append((abs(high[2]), smoother.key("max_velocity[2]")))
        if low is not None:
            reverse.append((-low[0], smoother.key("min_velocity[0]")))
            lateral.append((abs(low[1]), smoother.key("min_velocity[1]")))
            yaw.append((abs(low[2]), smoother.key("min_velocity[2]")))
        rate = smoother.number("smoothing_frequency", low=Fraction(0), low_open=True)
        if rate is not None:
            frequencies.append((rate, smoother.key("smoothing_frequency")))
    controller = node_parameters(data, "controller_server")
    if controller is not None:
        rate = controller.number("controller_frequency", low=Fraction(0), low_open=True)
        if rate is not None:
            frequencies.append((rate, controller.key("controller_frequency")))
        for plugin in controller.names("controller_plugins", required=False) or ("FollowPath",):
            section = controller.section(plugin, required=False)
            if section is None:
                continue
            for key, into, sign in (
                ("max_vel_x", forward, 1),
                ("vx_max", forward, 1),
                ("desired_linear_vel", forward, 1),
                ("min_vel_x", reverse, -1),
                ("vx_min", reverse, -1),
                ("max_vel_y", lateral, 1),
                ("vy_max", lateral, 1),
                ("max_vel_theta", yaw, 1),
                ("wz_max", yaw, 1),
            ):
                value = section.number(key)
                if value is not None:
                    into.append((sign * value, section.key(key)))
    period = None
    if frequencies:
        slowest, where = min(frequencies)
        period = Limit(1 / slowest, f"1 / {where}")
    return {
        "forward": _largest(forward),
        "reverse": _largest(reverse),
        "lateral": _largest(lateral),
        "yaw_rate": _largest(yaw),
        "control_period": period,
    }


def load_params(path: Path) -> Nav2Params:
    """Read and validate the Nav2 parameter file ``path`` (SR-NAV-4)."""
    return _params(*load_yaml(path))


def parse_params(text: str, name: str = "<text>") -> Nav2Params:
    """Validate Nav2 parameters given as YAML text (named ``name`` in errors)."""
    return _params(*parse_yaml(text, name))


def _params(data: Mapping[str, Any], name: str) -> Nav2Params:
    node = node_parameters(data, "collision_monitor")
    if node is None:
        raise Nav2ParamsError(
            f"{name}: no `collision_monitor: ros__parameters:` section: allowed: a Nav2 "
            "collision monitor parameter file"
        )
    listed = node.names("polygons", required=True)
    zones = tuple(_zone(_required(node, n), n) for n in listed)
    sources = _sources(node)
    taken = set(listed) | {s.name for s in sources}
    unlisted = tuple(
        k
        for k, v in node.data.items()
        if k not in taken and isinstance(v, dict) and v.get("type") in SHAPES
    )
    base = node.string("base_frame_id", "base_footprint")
    assert base is not None
    return Nav2Params(
        name=name,
        base_frame_id=base,
        zones=zones,
        unlisted=unlisted,
        sources=sources,
        **_robot_limits(dict(data)),
    )


def _required(node: Section, name: str) -> Section:
    section = node.section(name, required=False)
    if section is None:  # nothing there: node.section refuses a value that is not a mapping
        raise Nav2ParamsError(
            f"{node.key(name)} = None: allowed: a mapping with the polygon's type and "
            "action_type (it is listed in polygons)"
        )
    return section
