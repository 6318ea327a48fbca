"""Motion profiles and the trajectories they produce (SR-SIM-2, SR-SIM-3).

A :class:`Motion` is a signed speed along the body's x axis that is piecewise linear in time
(knots), plus a piecewise-constant yaw rate. Every profile the simulator knows (constant
velocity, accelerate / decelerate, turning, stop-and-go, the forklift reversing manoeuvre) is
one of these, so the ground-truth labels can be derived exactly from the knots
(:mod:`pipeline.sources.sim.truth`). :func:`integrate` turns a motion and a start pose into a
:class:`Trajectory` on a fine time grid; poses at any instant (a beam's own time) are
interpolated from it. :func:`tow_train` derives the dollies of a baggage train from the tug's
trajectory (each axle follows its tow point along a tractrix, so the train cuts corners as a
real one does). Random parameters come from a ``numpy.random.Generator`` only.

Units: seconds, metres, m/s, m/s^2, radians, rad/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.frames import to_parent
from pipeline.sources.sim.history import grid_window
from pipeline.sources.sim.objects import (
    DOLLY_DRAWBAR_M,
    DOLLY_REAR_AXLE_X_M,
    DOLLY_REAR_HITCH_M,
    DOLLY_WHEELBASE_M,
    TUG_HITCH_X_M,
)
from pipeline.types import FloatArray, frozen_array

__all__ = [
    "TRAJECTORY_DT_S",
    "Motion",
    "Trajectory",
    "accelerate",
    "constant",
    "integrate",
    "offset_trajectory",
    "random_reversing",
    "reversing",
    "stationary",
    "stop_and_go",
    "tow_train",
    "turning",
]

TRAJECTORY_DT_S = 0.005  # grid of precomputed trajectories; poses between are interpolated


@dataclass(frozen=True, slots=True)
class Motion:
    """Signed speed (piecewise linear through the knots) and yaw rate (piecewise constant).

    ``knot_t_s`` starts at 0 and increases strictly; the speed holds its last knot value after
    the last knot. ``yaw_t_s`` starts at 0 and increases strictly; yaw rate ``yaw_rate_rps[i]``
    applies from ``yaw_t_s[i]`` to ``yaw_t_s[i + 1]`` (the last one for ever). ``profile``
    names the profile that built it.
    """

    knot_t_s: FloatArray
    knot_v_mps: FloatArray
    yaw_t_s: FloatArray
    yaw_rate_rps: FloatArray
    profile: str

    def __post_init__(self) -> None:
        for name in ("knot_t_s", "knot_v_mps", "yaw_t_s", "yaw_rate_rps"):
            object.__setattr__(self, name, frozen_array(getattr(self, name)))
        kt, kv, yt, yr = self.knot_t_s, self.knot_v_mps, self.yaw_t_s, self.yaw_rate_rps
        if kt.ndim != 1 or kt.shape != kv.shape or kt.size == 0:
            raise ValueError(f"Motion: knots need equal 1-D shapes, got {kt.shape}, {kv.shape}")
        if yt.ndim != 1 or yt.shape != yr.shape or yt.size == 0:
            raise ValueError(
                f"Motion: yaw segments need equal 1-D shapes, got {yt.shape}, {yr.shape}"
            )
        for arr, what in ((kt, "knot_t_s"), (yt, "yaw_t_s")):
            if arr[0] != 0.0 or np.any(np.diff(arr) <= 0):
                raise ValueError(f"Motion: {what} must start at 0 and increase strictly: {arr}")
        if not (np.all(np.isfinite(kv)) and np.all(np.isfinite(yr))):
            raise ValueError("Motion: speeds and yaw rates must be finite")

    def speed_at(self, t_s: FloatArray) -> FloatArray:
        """Signed speed (m/s) at times ``t_s``."""
        return np.interp(t_s, self.knot_t_s, self.knot_v_mps)

    def accel_at(self, t_s: FloatArray) -> FloatArray:
        """Signed acceleration (m/s^2): the slope of the knot segment containing each time."""
        kt, kv = self.knot_t_s, self.knot_v_mps
        if kt.size < 2:
            return np.zeros_like(np.asarray(t_s, dtype=np.float64))
        slopes = np.diff(kv) / np.diff(kt)
        seg = np.searchsorted(kt, t_s, side="right") - 1
        inside = (seg >= 0) & (seg < kt.size - 1)
        return np.where(inside, slopes[np.clip(seg, 0, kt.size - 2)], 0.0)

    def heading_change(self, t_s: FloatArray) -> FloatArray:
        """Exact integral of the yaw rate from 0 to each time (rad)."""
        starts = self.yaw_t_s
        lengths = np.append(np.diff(starts), np.inf)
        inside = np.clip(
            np.asarray(t_s, dtype=np.float64)[:, None] - starts[None, :], 0.0, lengths[None, :]
        )
        return inside @ self.yaw_rate_rps

    def yaw_rate_at(self, t_s: FloatArray) -> FloatArray:
        """Yaw rate (rad/s) at times ``t_s``."""
        seg = np.searchsorted(self.yaw_t_s, t_s, side="right") - 1
        return self.yaw_rate_rps[np.clip(seg, 0, self.yaw_t_s.size - 1)]


def _straight(knot_t: list[float], knot_v: list[float], profile: str) -> Motion:
    return Motion(np.array(knot_t), np.array(knot_v), np.zeros(1), np.zeros(1), profile)


def stationary() -> Motion:
    """Standing still."""
    return _straight([0.0], [0.0], "stationary")


def constant(speed_mps: float) -> Motion:
    """Constant velocity along the start heading."""
    return _straight([0.0], [speed_mps], "constant")


def accelerate(v0_mps: float, v1_mps: float, start_s: float, accel_mps2: float) -> Motion:
    """Hold ``v0`` until ``start_s``, then change speed to ``v1`` at ``|accel_mps2|``."""
    if accel_mps2 == 0 or start_s < 0:
        raise ValueError(f"accelerate: need accel != 0 and start >= 0, got {accel_mps2}, {start_s}")
    if v1_mps == v0_mps:
        return _straight([0.0], [v0_mps], "accelerate")
    ramp = max(abs(v1_mps - v0_mps) / abs(accel_mps2), 1e-6)  # knots must stay distinct
    if start_s == 0:
        return _straight([0.0, ramp], [v0_mps, v1_mps], "accelerate")
    return _straight([0.0, start_s, start_s + ramp], [v0_mps, v0_mps, v1_mps], "accelerate")


def turning(speed_mps: float, start_s: float, turn_rad: float, yaw_rate_rps: float) -> Motion:
    """Constant speed; from ``start_s`` turn through ``turn_rad`` at ``|yaw_rate_rps|``."""
    if yaw_rate_rps == 0 or start_s <= 0:
        raise ValueError(
            f"turning: need yaw rate != 0 and start > 0, got {yaw_rate_rps}, {start_s}"
        )
    rate = abs(yaw_rate_rps) * np.sign(turn_rad)
    dur = abs(turn_rad) / abs(yaw_rate_rps)
    return Motion(
        np.zeros(1),
        np.array([speed_mps]),
        np.array([0.0, start_s, start_s + dur]),
        np.array([0.0, rate, 0.0]),
        "turning",
    )


def stop_and_go(
    speed_mps: float,
    accel_mps2: float,
    decel_mps2: float,
    go_s: float,
    stop_s: float,
    cycles: int,
) -> Motion:
    """Drive at ``speed_mps`` for ``go_s``, brake to rest, wait ``stop_s``, and go again."""
    if min(accel_mps2, decel_mps2, go_s, stop_s) < 1e-6 or cycles < 1 or speed_mps == 0:
        raise ValueError(
            "stop_and_go: speed, accelerations and durations must be positive "
            f"(>= 1e-6), cycles >= 1; got {speed_mps}, {accel_mps2}, {decel_mps2}, {go_s}, "
            f"{stop_s}, {cycles}"
        )
    t, kt, kv = 0.0, [0.0], [speed_mps]
    for _ in range(cycles):
        t += go_s
        kt.append(t)
        kv.append(speed_mps)
        t += abs(speed_mps) / decel_mps2
        kt.append(t)
        kv.append(0.0)
        t += stop_s
        kt.append(t)
        kv.append(0.0)
        t += abs(speed_mps) / accel_mps2
        kt.append(t)
        kv.append(speed_mps)
    return _straight(kt, kv, "stop_and_go")


def reversing(
    forward_mps: float,
    slow_start_s: float,
    slow_s: float,
    dwell_s: float,
    reverse_mps: float,
    reverse_accel_mps2: float,
    reverse_s: float | None = None,
) -> Motion:
    """The forklift reversal from the source material: drive forward at ``forward_mps``
    (about +0.8 m/s), slow to rest over ``slow_s`` (3-5 frames of 0.1 s), wait ``dwell_s``,
    then accelerate backwards to ``-|reverse_mps|`` (0.6 m/s or more). With ``reverse_s``
    the truck reverses at that speed for ``reverse_s`` seconds and then brakes to rest at
    ``reverse_accel_mps2`` (a reversing manoeuvre is a few metres long)."""
    if min(forward_mps, slow_s, reverse_accel_mps2, slow_start_s) <= 0 or dwell_s < 0:
        raise ValueError("reversing: speeds, durations and acceleration must be positive")
    v_rev = -abs(reverse_mps)
    t1 = slow_start_s
    t2 = t1 + slow_s
    kt = [0.0, t1, t2]
    kv = [forward_mps, forward_mps, 0.0]
    if t2 + dwell_s > t2:  # a dwell too short to be a separate knot is no dwell
        kt.append(t2 + dwell_s)
        kv.append(0.0)
    ramp = abs(v_rev) / reverse_accel_mps2
    kt.append(kt[-1] + ramp)
    kv.append(v_rev)
    if reverse_s is not None:
        if reverse_s <= 0:
            raise ValueError(f"reversing: reverse_s must be > 0, got {reverse_s}")
        kt += [kt[-1] + reverse_s, kt[-1] + reverse_s + ramp]
        kv += [v_rev, 0.0]
    return _straight(kt, kv, "reversing")


def random_reversing(rng: np.random.Generator, slow_start_s: float) -> Motion:
    """A reversal with randomised parameters around the source's figures: forward 0.6-1.0
    m/s, slowing over 3, 4 or 5 frames, dwell 0-0.3 s, reversing at 0.6-0.9 m/s reached at
    0.5-1.0 m/s^2, held for 1.5-3 s before braking to rest."""
    return reversing(
        forward_mps=float(rng.uniform(0.6, 1.0)),
        slow_start_s=slow_start_s,
        slow_s=0.1 * int(rng.integers(3, 6)),
        dwell_s=float(rng.uniform(0.0, 0.3)),
        reverse_mps=float(rng.uniform(0.6, 0.9)),
        reverse_accel_mps2=float(rng.uniform(0.5, 1.0)),
        reverse_s=float(rng.uniform(1.5, 3.0)),
    )


@dataclass(frozen=True, slots=True)
class Trajectory:
    """Poses on a time grid: body-centre position, heading, signed speed along the heading,
    velocity, acceleration, distance travelled and (dollies only) drawbar articulation."""

    t_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    accel_mps2: FloatArray
    arc_m: FloatArray
    articulation_rad: FloatArray

    def __post_init__(self) -> None:
        for name in self.__slots__:
            object.__setattr__(self, name, frozen_array(getattr(self, name)))

    @staticmethod
    def from_poses(
        t_s: FloatArray,
        x_m: FloatArray,
        y_m: FloatArray,
        heading_rad: FloatArray,
        articulation_rad: FloatArray | None = None,
    ) -> Trajectory:
        """Derive speed, acceleration and distance from poses by finite differences."""
        vx = np.gradient(x_m, t_s)
        vy = np.gradient(y_m, t_s)
        speed = vx * np.cos(heading_rad) + vy * np.sin(heading_rad)
        step = np.hypot(np.diff(x_m), np.diff(y_m))
        arc = np.concatenate([[0.0], np.cumsum(step)])
        return Trajectory(
            t_s=t_s,
            x_m=x_m,
            y_m=y_m,
            heading_rad=heading_rad,
            speed_mps=speed,
            vx_mps=vx,
            vy_mps=vy,
            accel_mps2=np.gradient(speed, t_s),
            arc_m=arc,
            articulation_rad=np.zeros_like(t_s) if articulation_rad is None else articulation_rad,
        )

    def at(self, t_s: FloatArray) -> dict[str, FloatArray]:
        """Every column interpolated at times ``t_s`` (held constant outside the grid).

        Only the grid points around the query times are read (:func:`grid_window`): the same
        bits as interpolating over the whole grid, at a cost that does not grow with the
        run's length (SR-RUN-5).
        """
        t = np.asarray(t_s, dtype=np.float64)
        lo, hi = grid_window(self.t_s, t)
        grid = self.t_s[lo:hi]
        return {
            name: np.interp(t, grid, getattr(self, name)[lo:hi])
            for name in self.__slots__
            if name != "t_s"
        }

    @property
    def duration_s(self) -> float:
        """Last time on the grid."""
        return float(self.t_s[-1])


def integrate(
    motion: Motion,
    x0_m: float,
    y0_m: float,
    heading0_rad: float,
    duration_s: float,
    dt_s: float = TRAJECTORY_DT_S,
) -> Trajectory:
    """Integrate ``motion`` from a start pose over ``[0, duration_s]`` on a ``dt_s`` grid
    (trapezoidal rule; speed, acceleration and yaw rate are exact at the grid times)."""
    if duration_s <= 0 or dt_s <= 0:
        raise ValueError(f"integrate: duration and dt must be > 0, got {duration_s}, {dt_s}")
    n = int(np.ceil(duration_s / dt_s))
    t = np.linspace(0.0, n * dt_s, n + 1)
    v = motion.speed_at(t)
    heading = heading0_rad + motion.heading_change(t)
    vx = v * np.cos(heading)
    vy = v * np.sin(heading)
    x = x0_m + np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt_s)])
    y = y0_m + np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt_s)])
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    return Trajectory(
        t_s=t,
        x_m=x,
        y_m=y,
        heading_rad=heading,
        speed_mps=v,
        vx_mps=vx,
        vy_mps=vy,
        accel_mps2=motion.accel_at(t),
        arc_m=arc,
        articulation_rad=np.zeros_like(t),
    )


def offset_trajectory(leader: Trajectory, dx_m: float, dy_m: float) -> Trajectory:
    """A point fixed at ``(dx_m, dy_m)`` in the leader's body frame (e.g. a pallet jack's
    operator walking ahead of its handle), same heading."""
    x, y = to_parent((leader.x_m, leader.y_m, leader.heading_rad), dx_m, dy_m)
    # One pose per sample: the offset point comes out as arrays.
    return Trajectory.from_poses(
        leader.t_s, np.asarray(x), np.asarray(y), leader.heading_rad.copy()
    )


def _tractrix(leader_xy: FloatArray, length_m: float, start_dir: FloatArray) -> FloatArray:
    """Path of a point dragged at fixed distance behind ``leader_xy`` ``(N, 2)``."""
    out = np.empty_like(leader_xy)
    out[0] = leader_xy[0] - length_m * start_dir
    # Sequential by nature (each position depends on the previous one); runs once per
    # scenario build, never per cycle.
    prev = out[0]
    for k in range(1, leader_xy.shape[0]):
        d = leader_xy[k] - prev
        norm = float(np.hypot(d[0], d[1]))
        prev = leader_xy[k] - length_m * (d / norm) if norm > 0 else prev
        out[k] = prev
    return out


def tow_train(tug: Trajectory, n_dollies: int) -> list[Trajectory]:
    """Trajectories of ``n_dollies`` dollies towed behind ``tug`` (body-centre poses).

    The tow eye of each dolly sits on the hitch ahead (the tug's, then the previous dolly's);
    the front axle (on a turntable) trails the eye by the drawbar length and the rear axle
    trails the front axle by the wheelbase, both as tractrices. The dolly heads from its rear
    to its front axle; the drawbar's articulation is its angle to that heading. The train is
    assumed to start stretched out straight behind the tug.
    """
    if n_dollies < 0:
        raise ValueError(f"tow_train: n_dollies must be >= 0, got {n_dollies}")
    c, s = np.cos(tug.heading_rad), np.sin(tug.heading_rad)
    hitch = np.stack([tug.x_m + c * TUG_HITCH_X_M, tug.y_m + s * TUG_HITCH_X_M], axis=1)
    start_dir = np.array([c[0], s[0]])
    out = []
    for _ in range(n_dollies):
        front = _tractrix(hitch, DOLLY_DRAWBAR_M, start_dir)
        rear = _tractrix(front, DOLLY_WHEELBASE_M, start_dir)
        heading = np.unwrap(np.arctan2(front[:, 1] - rear[:, 1], front[:, 0] - rear[:, 0]))
        bar = np.arctan2(hitch[:, 1] - front[:, 1], hitch[:, 0] - front[:, 0])
        articulation = (bar - heading + np.pi) % (2 * np.pi) - np.pi
        ch, sh = np.cos(heading), np.sin(heading)
        centre = rear - DOLLY_REAR_AXLE_X_M * np.stack([ch, sh], axis=1)
        out.append(
            Trajectory.from_poses(tug.t_s, centre[:, 0], centre[:, 1], heading, articulation)
        )
        hitch = rear - DOLLY_REAR_HITCH_M * np.stack([ch, sh], axis=1)
    return out
