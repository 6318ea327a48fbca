"""A Nav2 collision_monitor-style speed policy on the raw scan points: the availability baseline
(SR-AVL-4).

What integrators use today: :class:`Nav2Baseline` reads a ``collision_monitor`` parameter file
(:func:`safety.nav2.load_params`, Nav2's own reading of it) and, every cycle, applies Nav2's
zone models to the scan's points in the robot (base) frame, filtering a constant command of
``stopping.robot_max_speed_mps`` (the controller's ``cmd_vel``):

* ``stop``: ``min_points`` or more points inside the zone: speed 0;
* ``slowdown``: the command times ``slowdown_ratio``; ``limit``: at most ``linear_limit``;
* ``approach``: the footprint (the zone's points, or the configured footprint when the file
  takes it from a topic, as Nav2's ``footprint_topic``) is moved along the command in steps of
  ``simulation_time_step`` up to ``time_before_collision``; at the first step with
  ``min_points`` inside, the command is scaled by (that step's start time) /
  ``time_before_collision`` (Nav2's ``getCollisionTime``, which counts a collision at the start
  of the step that reaches it, and checks the footprint where it stands first).

The most restrictive zone wins. Points inside a polygon are counted with Nav2's even-odd
ray-crossing test. There are no tracks, classes, predictions or stopping model: it knows
nothing about a reversing forklift. It runs in the same closed loop as the runtime
(:func:`safety.run.run`), through the same :class:`~safety.runtime.CycleInput` and
:class:`~safety.runtime.CycleOutput`; its records hold no governor inputs (not replayable).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.points import RangeFilter
from pipeline.types import Action, BoolArray, Command, FloatArray
from safety.audit.log import CycleRecord
from safety.model.decision import Decision
from safety.model.monitors import Observation
from safety.nav2 import Nav2Params, Nav2ParamsError, load_params
from safety.nav2.params import Zone
from safety.runtime import CycleInput, CycleOutput

__all__ = ["DEFAULT_BASELINE", "Nav2Baseline", "points_inside"]

DEFAULT_BASELINE = Path(__file__).resolve().parents[1] / "examples" / "nav2" / "baseline.yaml"
"""The tutorial's zones for this robot (examples/nav2/baseline.yaml)."""


def points_inside(vertices: FloatArray, x_m: FloatArray, y_m: FloatArray) -> BoolArray:
    """Nav2's even-odd ray-crossing test of each point against the polygon ``vertices`` (k, 2).

    An edge counts when the point's y lies in (lower end, upper end] and the edge meets the ray
    from the point along +x beyond it, as collision_monitor's ``Polygon::isPointInside`` counts
    it: a point on a bottom or right edge is outside, one on a top or left edge inside."""
    inside = np.zeros(x_m.shape, dtype=bool)
    xi, yi = vertices[:, 0], vertices[:, 1]
    xj, yj = np.roll(xi, 1), np.roll(yi, 1)
    for k in range(vertices.shape[0]):
        crosses = (y_m <= yj[k]) == (y_m > yi[k])
        with np.errstate(divide="ignore", invalid="ignore"):
            x_cut = (xj[k] - xi[k]) * (y_m - yi[k]) / (yj[k] - yi[k]) + xi[k]
        inside ^= crosses & (x_m < x_cut)
    return inside


@dataclass(frozen=True)
class _Shape:
    """A zone as the baseline evaluates it: its polygon or circle radius, floats."""

    zone: Zone
    vertices: FloatArray | None
    radius_m: float | None

    def count(self, x_m: FloatArray, y_m: FloatArray) -> int:
        """Points inside the shape where it stands."""
        if self.radius_m is not None:
            return int(np.count_nonzero(np.hypot(x_m, y_m) <= self.radius_m))
        assert self.vertices is not None
        return int(np.count_nonzero(points_inside(self.vertices, x_m, y_m)))


class Nav2Baseline:
    """The baseline policy for one configuration and parameter file (module docstring)."""

    def __init__(self, config: SafecaseConfig, params: Nav2Params) -> None:
        self.scan_filter = RangeFilter(config.scan)
        self.command_mps = float(config.stopping.robot_max_speed_mps)
        geometry = config.geometry
        hl, hw = 0.5 * geometry.footprint_length_m, 0.5 * geometry.footprint_width_m
        footprint = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
        self.shapes = tuple(_shape(z, footprint) for z in params.zones if z.enabled)
        self.previous_now_s: float | None = None

    @classmethod
    def from_file(cls, config: SafecaseConfig, path: Path = DEFAULT_BASELINE) -> Nav2Baseline:
        """The baseline of the parameter file ``path``; raises ``Nav2ParamsError``."""
        return cls(config, load_params(path))

    def speed_mps(self, x_m: FloatArray, y_m: FloatArray) -> tuple[float, tuple[str, ...]]:
        """The filtered command for points (robot frame) and the zones that set it."""
        speed, reasons = self.command_mps, []
        for shape in self.shapes:
            zone = shape.zone
            if zone.action == "approach":
                limit = self._approach_mps(shape, x_m, y_m)
            else:
                n = shape.count(x_m, y_m)
                if n < zone.min_points:
                    continue
                limit = _zone_limit(zone, self.command_mps)
            if limit < speed:
                speed = limit
                reasons.append(f"nav2:{zone.name}: {zone.action} -> {limit:.3f} m/s")
        return speed, tuple(reasons)

    def _approach_mps(self, shape: _Shape, x_m: FloatArray, y_m: FloatArray) -> float:
        """Nav2's approach model at the command (module docstring)."""
        zone = shape.zone
        assert zone.time_before_collision_s is not None
        assert zone.simulation_time_step_s is not None
        before = float(zone.time_before_collision_s)
        step = float(zone.simulation_time_step_s)
        if shape.count(x_m, y_m) >= zone.min_points:
            return 0.0
        v = self.command_mps
        for k in range(math.floor(before / step + 1e-9) + 1):
            # The footprint moved by v (k + 1) step: the points move back by as much.
            if shape.count(x_m - v * (k + 1) * step, y_m) >= zone.min_points:
                return v * (k * step) / before
        return v

    def step(self, inp: CycleInput) -> CycleOutput:
        """One cycle: the scan's points through the zones; no scan is a STOP."""
        cpu0, start = time.thread_time_ns(), time.perf_counter_ns()
        reasons: tuple[str, ...]
        if inp.scan is None:
            speed, reasons = 0.0, ("nav2: no scan this cycle",)
        else:
            points = self.scan_filter.points(inp.scan)
            speed, reasons = self.speed_mps(points.x_m, points.y_m)
        wall = (time.perf_counter_ns() - start) * 1e-9
        duration = inp.charge_s if inp.charge_s is not None else wall
        now = inp.now_s + duration + inp.delay_s
        if speed <= 0.0:
            action = Action.STOP
        elif speed < self.command_mps:
            action = Action.SLOW
        else:
            action = Action.PROCEED
        command = Command(action, max(speed, 0.0), now, reasons)
        observation = Observation(
            now_s=now,
            previous_now_s=self.previous_now_s,
            scan_stamp_s=None if inp.scan is None else inp.scan.stamp_s,
            cycle_duration_s=duration,
        )
        self.previous_now_s = now
        decision = Decision(command, None, ())
        record = CycleRecord(observation, decision, None, {}, {"nav2": wall})
        cpu = (time.thread_time_ns() - cpu0) * 1e-9
        return CycleOutput(command, decision, record, {"nav2": wall}, cpu, None, None)


def _zone_limit(zone: Zone, command_mps: float) -> float:
    """The speed a triggered stop, slowdown or limit zone allows."""
    if zone.action == "stop":
        return 0.0
    if zone.action == "slowdown":
        assert zone.slowdown_ratio is not None
        return command_mps * float(zone.slowdown_ratio)
    if zone.action == "limit":
        assert zone.linear_limit_mps is not None
        return float(zone.linear_limit_mps)  # a limit above the command leaves it as it is
    return command_mps  # "none": Nav2 only reports it


def _shape(zone: Zone, footprint: FloatArray) -> _Shape:
    """The zone's static shape; an approach zone without one is the robot's footprint."""
    if zone.subpolygons:
        raise Nav2ParamsError(f"{zone.name}: velocity polygons are not supported by the baseline")
    if zone.radius_m is not None:
        return _Shape(zone, None, float(zone.radius_m))
    if zone.vertices is not None:
        return _Shape(zone, np.array(zone.vertices, dtype=np.float64), None)
    if zone.action == "approach":
        return _Shape(zone, footprint, None)
    raise Nav2ParamsError(
        f"{zone.name}: a shape set at run time ({zone.dynamic_topic}) is not supported by the "
        "baseline; give its points"
    )
