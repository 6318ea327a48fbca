"""The ego robot: a footprint driving along a route, commanded by a speed policy (SR-SIM-5).

The robot follows a polyline route (heading along the current segment) at a speed that tracks
the last command that has taken effect: a command issued at ``t`` takes effect at
``t + actuation_latency_s``; the speed then rises at most at ``accel_mps2`` and falls at
``decel_mps2`` (the braking deceleration drawn for this run from the configured range) until
it reaches the command. After a contact the robot is halted (speed 0, commands ignored), as a
bumper stop would do. It stops at the end of its route.

A **speed policy** is any callable from an :class:`EgoObservation` to a commanded speed in
m/s; it is called once per scan, when the scan is complete. :class:`ConstantSpeed` is the
default; the safety governor plugs in the same way (``lambda obs: governor(obs.scan, ...)``)
without any change here.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_parent
from pipeline.sources.sim.history import ThinnedRows
from pipeline.sources.sim.shapes import Outline, rectangle
from pipeline.sources.sim.truth import ScanTruth
from pipeline.types import FloatArray, Scan, frozen_array

__all__ = ["ConstantSpeed", "Ego", "EgoObservation", "EgoSpec", "Route", "SpeedPolicy"]


@dataclass(frozen=True, slots=True)
class EgoObservation:
    """What the ego's policy gets after each scan.

    ``stamp_s`` is when the observation is delivered (the end of the revolution); ``pose`` and
    ``speed_mps`` are the robot's own odometry then. ``truth`` is the simulator's ground truth
    of the scan: for oracle policies and tests only; a real governor must not read it.
    """

    stamp_s: float
    scan: Scan
    pose: FloatArray
    speed_mps: float
    truth: ScanTruth


SpeedPolicy = Callable[[EgoObservation], float]
"""Maps an observation to a commanded speed (m/s, >= 0)."""


@dataclass(frozen=True, slots=True)
class ConstantSpeed:
    """Always command the same speed (the default policy)."""

    speed_mps: float

    def __call__(self, observation: EgoObservation) -> float:
        return self.speed_mps


@dataclass(frozen=True, slots=True)
class Route:
    """A polyline ``(N >= 2, 2)`` followed by arc length (metres)."""

    points_m: FloatArray

    def __post_init__(self) -> None:
        pts = frozen_array(self.points_m)
        if pts.ndim != 2 or pts.shape[0] < 2 or pts.shape[1] != 2:
            raise ValueError(f"Route: points must have shape (N >= 2, 2), got {pts.shape}")
        if np.any(np.hypot(*np.diff(pts, axis=0).T) <= 0):
            raise ValueError("Route: consecutive points must differ")
        object.__setattr__(self, "points_m", pts)

    @property
    def cumulative_m(self) -> FloatArray:
        """Arc length at each point."""
        seg = np.hypot(*np.diff(self.points_m, axis=0).T)
        return np.concatenate([[0.0], np.cumsum(seg)])

    @property
    def length_m(self) -> float:
        """Total length."""
        return float(self.cumulative_m[-1])

    def pose_at(self, arc_m: FloatArray) -> FloatArray:
        """Poses ``(T, 3)`` (x, y, heading) at arc lengths ``arc_m`` (clamped to the route)."""
        cum = self.cumulative_m
        s = np.clip(np.asarray(arc_m, dtype=np.float64), 0.0, cum[-1])
        seg = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, cum.size - 2)
        p0 = self.points_m[seg]
        d = self.points_m[seg + 1] - p0
        seg_len = cum[seg + 1] - cum[seg]
        frac = (s - cum[seg]) / seg_len
        out = np.empty((*s.shape, 3))
        out[..., 0] = p0[..., 0] + frac * d[..., 0]
        out[..., 1] = p0[..., 1] + frac * d[..., 1]
        out[..., 2] = np.arctan2(d[..., 1], d[..., 0])
        return out


@dataclass(frozen=True, slots=True)
class EgoSpec:
    """The ego robot of one run (metres, m/s, m/s^2, seconds, radians).

    ``mount`` is the scanner pose (x, y, yaw) in the robot frame; ``max_speed_mps`` caps
    every command.
    """

    route: Route
    length_m: float
    width_m: float
    accel_mps2: float
    decel_mps2: float
    actuation_latency_s: float
    max_speed_mps: float
    initial_speed_mps: float
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if min(self.length_m, self.width_m, self.accel_mps2, self.decel_mps2) <= 0:
            raise ValueError("EgoSpec: size, acceleration and deceleration must be > 0")
        if self.actuation_latency_s < 0 or not (0 <= self.initial_speed_mps <= self.max_speed_mps):
            raise ValueError(
                f"EgoSpec: need latency >= 0 and 0 <= initial speed ({self.initial_speed_mps}) "
                f"<= max speed ({self.max_speed_mps})"
            )

    def footprint(self) -> Outline:
        """The robot's rectangle in its own frame (origin at its centre)."""
        hl, hw = self.length_m / 2, self.width_m / 2
        return Outline.from_parts([rectangle(-hl, hl, -hw, hw)])

    def scanner_poses(self, robot_poses: FloatArray) -> FloatArray:
        """Scanner poses ``(T, 3)`` in the world for robot poses ``(T, 3)``."""
        mx, my, myaw = self.mount
        out = np.empty_like(robot_poses)
        pose = (robot_poses[:, 0], robot_poses[:, 1], robot_poses[:, 2])
        out[:, 0], out[:, 1] = to_parent(pose, mx, my)
        out[:, 2] = robot_poses[:, 2] + myaw
        return out


class Ego:
    """The robot's state over a run, stepped with a fixed ``dt_s`` from time 0.

    Keeps its time / arc history so poses at any past instant (a beam's own time) can be
    interpolated. With ``window_steps`` None (the default) it keeps every step of the run
    (``n_steps`` of them). With ``window_steps`` set it keeps only that many recent steps
    for interpolation and :meth:`rewind`, and its :meth:`log` holds at most ``log_rows``
    evenly thinned steps (:class:`~pipeline.sources.sim.history.ThinnedRows`) plus the steps
    :meth:`pin` asks for, so its memory does not grow with the run (SR-RUN-5). Steps become
    final with :meth:`commit` (or when they leave the window); a rewind never goes before the
    last final step. Values at the kept times are the same bits either way.
    """

    def __init__(
        self,
        spec: EgoSpec,
        dt_s: float,
        n_steps: int,
        *,
        window_steps: int | None = None,
        log_rows: int = 8192,
    ) -> None:
        if window_steps is not None and window_steps < 1:
            raise ValueError(f"Ego: window_steps must be >= 1, got {window_steps}")
        self.spec = spec
        self.dt_s = dt_s
        self.speed_mps = spec.initial_speed_mps
        self.target_mps = spec.initial_speed_mps
        self.halted = False
        self._pending: deque[tuple[float, float]] = deque()
        self._window = window_steps
        size = n_steps + 1 if window_steps is None else 2 * (window_steps + 1)
        self._t = np.zeros(size)
        self._arc = np.zeros(size)
        self._speed = np.zeros(size)
        self._cmd = np.zeros(size)
        self._speed[0] = self.speed_mps
        self._cmd[0] = self.target_mps
        self._n = 0
        self._base = 0  # the step held in slot 0
        self._final = 0  # steps up to this one are final
        self._log: ThinnedRows | None = None
        if window_steps is not None:
            self._log = ThinnedRows(4, log_rows)
            self._log.append(self._row(0))

    @property
    def time_s(self) -> float:
        """Current time."""
        return float(self._t[self._n - self._base])

    @property
    def steps_done(self) -> int:
        """Number of steps taken."""
        return self._n

    @property
    def arc_m(self) -> float:
        """Distance driven along the route."""
        return float(self._arc[self._n - self._base])

    def command(self, speed_mps: float, issued_s: float) -> None:
        """Queue a commanded speed (clipped to [0, max speed]); takes effect after the latency.

        A non-finite command is treated as 0 (fail safe).
        """
        v = float(speed_mps) if np.isfinite(speed_mps) else 0.0
        v = min(max(v, 0.0), self.spec.max_speed_mps)
        self._pending.append((issued_s + self.spec.actuation_latency_s, v))

    def halt(self) -> None:
        """Stop dead and ignore further commands (after a contact)."""
        self.halted = True
        self.speed_mps = 0.0
        self.target_mps = 0.0

    def rewind(self, steps_done: int) -> None:
        """Forget every step after ``steps_done`` (the speed is that step's; commands that
        were taken up after it are lost, which matters only for a robot about to halt)."""
        if not self._final <= steps_done <= self._n:
            raise ValueError(f"Ego.rewind: step {steps_done} is not in {self._final}..{self._n}")
        self._n = steps_done
        self.speed_mps = float(self._speed[steps_done - self._base])

    def commit(self) -> None:
        """Make every step so far final: a bounded ego logs them and may drop them later."""
        self._commit(self._n)

    def pin(self, step: int) -> None:
        """Keep ``step`` in a bounded ego's :meth:`log` (a full log keeps every step)."""
        if self._log is not None:
            self._log.pin(step)

    def _row(self, step: int) -> FloatArray:
        k = step - self._base
        return np.array([self._t[k], self._arc[k], self._speed[k], self._cmd[k]])

    def _commit(self, step: int) -> None:
        if self._log is not None:
            for k in range(self._final + 1, step + 1):
                self._log.append(self._row(k))
        self._final = max(self._final, step)

    def _make_room(self) -> None:
        """Slide a bounded window so that the next step has a slot."""
        if self._window is None or self._n + 1 - self._base < self._t.size:
            return
        lo = self._n - self._window  # the oldest step kept
        self._commit(lo)
        src = lo - self._base
        keep = self._window + 1
        for column in (self._t, self._arc, self._speed, self._cmd):
            column[:keep] = column[src : src + keep]
        self._base = lo

    def step(self) -> None:
        """Advance one ``dt_s``."""
        t0 = self._n * self.dt_s
        t1 = (self._n + 1) * self.dt_s  # exact multiples: no drift over long runs
        # A command acts from the first step that starts at or after it is due (never early).
        while self._pending and self._pending[0][0] <= t0 + 1e-12:
            _, v = self._pending.popleft()
            if not self.halted:
                self.target_mps = v
        v0 = self.speed_mps
        if self.halted:
            v1 = 0.0
        elif self.target_mps >= v0:
            v1 = min(self.target_mps, v0 + self.spec.accel_mps2 * self.dt_s)
        else:
            v1 = max(self.target_mps, v0 - self.spec.decel_mps2 * self.dt_s)
        arc = self.arc_m + 0.5 * (v0 + v1) * self.dt_s
        if arc >= self.spec.route.length_m:
            arc, v1 = self.spec.route.length_m, 0.0
        self._make_room()
        self.speed_mps = v1
        self._n += 1
        k = self._n - self._base
        self._t[k] = t1
        self._arc[k] = arc
        self._speed[k] = v1
        self._cmd[k] = self.target_mps

    def pose(self) -> FloatArray:
        """Current pose (x, y, heading)."""
        pose: FloatArray = self.spec.route.pose_at(np.array([self.arc_m]))[0]
        return pose

    def _held(self, t_s: FloatArray) -> tuple[FloatArray, slice]:
        """The query times and the slots of the steps held; a bounded ego refuses times
        before its window (it no longer knows them)."""
        t = np.asarray(t_s, dtype=np.float64)
        held = slice(0, self._n - self._base + 1)
        if self._base and t.size and float(np.min(t)) < self._t[0]:
            raise ValueError(
                f"Ego: time {float(np.min(t))} s is before the steps kept (from {self._t[0]} s)"
            )
        return t, held

    def poses_at(self, t_s: FloatArray) -> FloatArray:
        """Robot poses ``(T, 3)`` at past times (linear in arc between steps)."""
        t, held = self._held(t_s)
        arc: FloatArray = np.interp(t, self._t[held], self._arc[held])
        return self.spec.route.pose_at(arc)

    def speeds_at(self, t_s: FloatArray) -> FloatArray:
        """Speeds at past times (linear between steps)."""
        t, held = self._held(t_s)
        return np.interp(t, self._t[held], self._speed[held])

    def log(self) -> dict[str, FloatArray]:
        """The history so far: time, arc, x, y, heading, speed and the command in force during
        the step that ended at each time (every step, or a bounded ego's thinned steps, its
        pinned steps and every step not yet final)."""
        if self._log is None:
            n = self._n + 1
            t, arc, speed, cmd = self._t[:n], self._arc[:n], self._speed[:n], self._cmd[:n]
        else:
            _, rows = self._log.rows()
            tail = [self._row(k) for k in range(self._final + 1, self._n + 1)]
            table = np.concatenate([rows, np.array(tail).reshape(-1, 4)])
            t, arc, speed, cmd = table.T
        poses = self.spec.route.pose_at(arc)
        return {
            "t_s": t.copy(),
            "arc_m": arc.copy(),
            "x_m": poses[:, 0],
            "y_m": poses[:, 1],
            "heading_rad": poses[:, 2],
            "speed_mps": speed.copy(),
            "command_mps": cmd.copy(),
        }
