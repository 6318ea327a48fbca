"""Swept volumes of a footprint along trajectories and the planner's path check (SR-SAT-3).

A trajectory is sampled every ``step_s`` (0.1 s in the source material); its swept volume is
the convex hull of the footprint placed at every sample. The planner check takes T candidate
trajectories and O obstacle envelopes and reports which trajectories are blocked, by which
envelope, and the earliest time of contact (:class:`~pipeline.types.SweptPathReport`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.config import GeometrySection
from pipeline.frames import to_parent
from pipeline.types import ConvexPolygons, FloatArray, IntArray, SweptPathReport, frozen_array
from safety.geometry.polygons import (
    MAX_COORD_M,
    GeometryError,
    NonFiniteGeometryError,
    PolygonBounds,
    Workspace,
    convex_hull_batch,
    convex_polygons,
    polygons_from_hull,
)
from safety.geometry.sat import RHO, SatChecker

__all__ = [
    "SweptPathChecker",
    "Trajectories",
    "candidate_trajectories",
    "rectangle_footprint",
    "segment_hulls",
    "swept_hulls",
    "unicycle_trajectories",
]


@dataclass(frozen=True, slots=True)
class Trajectories:
    """N trajectories sampled at S poses every ``step_s`` seconds; arrays are (S, N).

    Pose s of trajectory n is (x_m[s, n], y_m[s, n], theta_rad[s, n]) at time s * step_s.
    Non-finite poses raise :class:`~safety.geometry.polygons.NonFiniteGeometryError` naming them.
    """

    x_m: FloatArray
    y_m: FloatArray
    theta_rad: FloatArray
    step_s: float

    def __post_init__(self) -> None:
        arrays = [frozen_array(a) for a in (self.x_m, self.y_m, self.theta_rad)]
        if arrays[0].ndim != 2 or any(a.shape != arrays[0].shape for a in arrays):
            raise GeometryError(
                "Trajectories: x_m, y_m and theta_rad must be (S, N) arrays of one shape, got "
                + ", ".join(str(a.shape) for a in arrays)
            )
        if arrays[0].shape[0] < 1:
            raise GeometryError("Trajectories: at least one pose per trajectory is needed")
        for name, array in zip(("x_m", "y_m", "theta_rad"), arrays, strict=True):
            bad = ~np.isfinite(array)
            if name != "theta_rad":
                bad |= np.abs(array) > MAX_COORD_M
            if bad.any():
                step, traj = np.argwhere(bad)[0]
                raise NonFiniteGeometryError(
                    f"Trajectories: {name}[{step}, {traj}] = {float(array[step, traj])!r} "
                    f"(trajectory {traj}, step {step}); expected a finite pose"
                )
        if not (np.isfinite(self.step_s) and self.step_s > 0.0):
            raise GeometryError(f"Trajectories: step_s = {self.step_s!r}; expected > 0")
        object.__setattr__(self, "x_m", arrays[0])
        object.__setattr__(self, "y_m", arrays[1])
        object.__setattr__(self, "theta_rad", arrays[2])

    @property
    def n(self) -> int:
        """Number of trajectories."""
        return int(self.x_m.shape[1])

    @property
    def steps(self) -> int:
        """Number of poses per trajectory."""
        return int(self.x_m.shape[0])


def unicycle_trajectories(
    speed_mps: npt.ArrayLike,
    yaw_rate_radps: npt.ArrayLike,
    *,
    horizon_s: float,
    step_s: float,
    x0_m: float = 0.0,
    y0_m: float = 0.0,
    theta0_rad: float = 0.0,
) -> Trajectories:
    """Constant (speed, yaw rate) arcs from one start pose, sampled every ``step_s``.

    Exact arc integration: the chord after time t has length ``v t sinc(w t / 2)`` along the
    mean heading ``theta0 + w t / 2`` (``sinc`` keeps straight lines exact).
    """
    v = np.atleast_1d(np.asarray(speed_mps, dtype=np.float64))
    w = np.atleast_1d(np.asarray(yaw_rate_radps, dtype=np.float64))
    if v.shape != w.shape or v.ndim != 1:
        raise GeometryError(f"unicycle_trajectories: speeds {v.shape} and yaw rates {w.shape}")
    if not (np.isfinite(horizon_s) and horizon_s >= 0 and np.isfinite(step_s) and step_s > 0):
        raise GeometryError(
            f"unicycle_trajectories: horizon_s = {horizon_s!r}, step_s = {step_s!r}; expected "
            "horizon_s >= 0 and step_s > 0"
        )
    steps = int(np.floor(horizon_s / step_s + 1e-9)) + 1
    t = (np.arange(steps) * step_s)[:, None]
    turn = w[None, :] * t
    chord = v[None, :] * t * np.sinc(turn / (2.0 * np.pi))
    heading = theta0_rad + 0.5 * turn
    return Trajectories(
        x_m=x0_m + chord * np.cos(heading),
        y_m=y0_m + chord * np.sin(heading),
        theta_rad=theta0_rad + turn,
        step_s=step_s,
    )


def candidate_trajectories(
    n_speeds: int = 7,
    n_yaw_rates: int = 25,
    *,
    max_speed_mps: float = 1.0,
    max_yaw_rate_radps: float = 1.0,
    horizon_s: float = 1.5,
    step_s: float = 0.1,
) -> Trajectories:
    """The planner's default grid: speeds in (0, max] times yaw rates in [-max, max] (175)."""
    speeds = np.linspace(max_speed_mps / n_speeds, max_speed_mps, n_speeds)
    yaw = np.linspace(-max_yaw_rate_radps, max_yaw_rate_radps, n_yaw_rates)
    v, w = np.meshgrid(speeds, yaw, indexing="ij")
    return unicycle_trajectories(v.ravel(), w.ravel(), horizon_s=horizon_s, step_s=step_s)


def rectangle_footprint(length_m: float, width_m: float) -> ConvexPolygons:
    """A robot footprint centred on its reference point, x forward."""
    hl, hw = 0.5 * length_m, 0.5 * width_m
    return convex_polygons([np.array([[-hl, -hw], [hl, -hw], [hl, hw], [-hl, hw]])])


def _placed_points(
    footprint: ConvexPolygons, x: FloatArray, y: FloatArray, theta: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Footprint vertices at each pose: x, y of shape (poses..., Kf) (pose axes first)."""
    if footprint.n != 1:
        raise GeometryError(f"footprint: expected one polygon, got {footprint.n}")
    fx = footprint.vertices_m[0, : footprint.counts[0], 0]
    fy = footprint.vertices_m[1, : footprint.counts[0], 0]
    placed: tuple[FloatArray, FloatArray] = to_parent(
        (x[..., None], y[..., None], theta[..., None]), fx, fy
    )
    return placed


def swept_hulls(
    footprint: ConvexPolygons, trajectories: Trajectories, workspace: Workspace | None = None
) -> ConvexPolygons:
    """Convex hull of the footprint at every pose, one polygon per trajectory (SR-SAT-3)."""
    px, py = _placed_points(
        footprint, trajectories.x_m.T, trajectories.y_m.T, trajectories.theta_rad.T
    )
    # Sized explicitly: with no trajectory, -1 cannot be inferred from an empty array.
    points = trajectories.steps * px.shape[-1]
    px, py = px.reshape(trajectories.n, points), py.reshape(trajectories.n, points)
    order, counts, slack = convex_hull_batch(px, py, what="trajectory", workspace=workspace)
    return polygons_from_hull(px, py, order, counts, slack)


def segment_hulls(
    footprint: ConvexPolygons,
    trajectories: Trajectories,
    which: IntArray,
    workspace: Workspace | None = None,
) -> ConvexPolygons:
    """Hulls of the footprint at poses k and k+1 of each trajectory in ``which``.

    Polygon ``i * (S - 1) + k`` belongs to trajectory ``which[i]``, segment k (with a single
    pose, segment 0 is the footprint itself).
    """
    steps = trajectories.steps
    x, y, th = (a[:, which].T for a in (trajectories.x_m, trajectories.y_m, trajectories.theta_rad))
    if steps == 1:
        x0, y0, t0 = x, y, th
        x1, y1, t1 = x, y, th
    else:
        x0, y0, t0 = x[:, :-1], y[:, :-1], th[:, :-1]
        x1, y1, t1 = x[:, 1:], y[:, 1:], th[:, 1:]
    ax, ay = _placed_points(footprint, x0, y0, t0)
    bx, by = _placed_points(footprint, x1, y1, t1)
    kf = ax.shape[-1]
    px = np.concatenate([ax, bx], axis=-1).reshape(-1, 2 * kf)
    py = np.concatenate([ay, by], axis=-1).reshape(-1, 2 * kf)
    order, counts, slack = convex_hull_batch(px, py, what="segment", workspace=workspace)
    return polygons_from_hull(px, py, order, counts, slack)


class SweptPathChecker:
    """Blocks candidate trajectories whose swept hull overlaps an obstacle envelope.

    Configured by the ``geometry`` section: ``contact_tolerance_m`` (the SAT tolerance band),
    ``pregate_m`` (envelopes farther than this, and than any swept hull reaches, are not
    checked) and ``max_obstacles`` (a bound on the work per cycle). Holds scratch buffers:
    one checker per thread.
    """

    def __init__(self, config: GeometrySection) -> None:
        self.config = config
        self.sat = SatChecker(config.contact_tolerance_m)
        self._ws = Workspace()

    def footprint(self) -> ConvexPolygons:
        """The configured rectangular footprint (``footprint_length_m`` x ``_width_m``)."""
        return rectangle_footprint(self.config.footprint_length_m, self.config.footprint_width_m)

    def candidates(self, max_speed_mps: float) -> Trajectories:
        """The configured grid of ``n_speeds`` x ``n_yaw_rates`` constant arcs."""
        c = self.config
        return candidate_trajectories(
            c.n_speeds,
            c.n_yaw_rates,
            max_speed_mps=max_speed_mps,
            max_yaw_rate_radps=c.max_yaw_rate_radps,
            horizon_s=c.horizon_s,
            step_s=c.sample_dt_s,
        )

    def check(
        self,
        footprint: ConvexPolygons,
        trajectories: Trajectories,
        obstacles: ConvexPolygons,
        *,
        robot_x_m: float = 0.0,
        robot_y_m: float = 0.0,
    ) -> SweptPathReport:
        """Which trajectories are blocked, by which envelope, and when (SR-SAT-3)."""
        if obstacles.n > self.config.max_obstacles:
            raise GeometryError(
                f"swept-path check: {obstacles.n} obstacle envelopes; at most "
                f"{self.config.max_obstacles} (geometry.max_obstacles) per cycle"
            )
        if not (np.isfinite(robot_x_m) and np.isfinite(robot_y_m)):
            raise NonFiniteGeometryError(
                f"swept-path check: robot position ({robot_x_m!r}, {robot_y_m!r}) is not finite"
            )
        hulls = swept_hulls(footprint, trajectories, self._ws)
        gated = self._pregate(hulls, obstacles, robot_x_m, robot_y_m)
        kept = np.flatnonzero(~gated)
        n_traj, n_obs = trajectories.n, obstacles.n
        blocked = np.zeros((n_traj, n_obs), dtype=bool)
        if kept.size:
            blocked[:, kept] = self.sat.overlap_all(hulls, obstacles.take(kept))
        contact = np.full((n_traj, n_obs), -1, dtype=np.int64)
        hull_only = np.zeros((n_traj, n_obs), dtype=bool)
        ti, oi = np.nonzero(blocked)
        if ti.size:
            steps = self._contact_steps(footprint, trajectories, obstacles, ti, oi)
            hull_only[ti, oi] = steps < 0
            contact[ti, oi] = np.maximum(steps, 0)
        big = np.iinfo(np.int64).max
        masked = np.where(blocked, contact, big)
        any_blocked = blocked.any(axis=1)
        # With no envelope (an empty world) there is nothing to reduce: every path is clear.
        first = np.where(any_blocked, masked.argmin(axis=1), -1) if n_obs else np.full(n_traj, -1)
        soonest = masked.min(axis=1, initial=big)
        earliest = np.where(any_blocked, soonest * trajectories.step_s, np.inf)
        return SweptPathReport(
            blocked=blocked,
            contact_step=contact,
            hull_only=hull_only,
            earliest_contact_s=earliest,
            first_obstacle=first,
            gated=gated,
            step_s=trajectories.step_s,
        )

    def _pregate(
        self, hulls: ConvexPolygons, obstacles: ConvexPolygons, rx: float, ry: float
    ) -> npt.NDArray[np.bool_]:
        """Envelopes certainly out of reach: beyond ``pregate_m`` and beyond every hull."""
        v = hulls.vertices_m
        dx, dy = v[0] - rx, v[1] - ry
        reach = float(np.sqrt((dx * dx + dy * dy).max())) if hulls.n else 0.0
        bounds = PolygonBounds(obstacles)
        magnitude = max(
            float(np.abs(v).max(initial=0.0)), float(bounds.magnitude_m.max(initial=0.0))
        )
        # Margins above rounding and the SAT threshold keep the gate implied by exact
        # disjointness: gated envelopes are farther than any hull by more than 2 thr.
        margin = 2.0 * (self.sat.tolerance_m + RHO * magnitude) + 1e-9 * (1.0 + reach)
        gate = max(self.config.pregate_m, reach) + margin
        ox, oy = bounds.centre_x_m - rx, bounds.centre_y_m - ry
        distance = np.sqrt(ox * ox + oy * oy) - bounds.radius_m
        gated: npt.NDArray[np.bool_] = distance > gate
        return gated

    def _contact_steps(
        self,
        footprint: ConvexPolygons,
        trajectories: Trajectories,
        obstacles: ConvexPolygons,
        ti: IntArray,
        oi: IntArray,
    ) -> IntArray:
        """First segment of trajectory ti[p] touching obstacle oi[p]; -1 when none does."""
        which, slot = np.unique(ti, return_inverse=True)
        segments = segment_hulls(footprint, trajectories, which, self._ws)
        per = max(trajectories.steps - 1, 1)
        seg_idx = (slot[:, None] * per + np.arange(per)[None, :]).ravel()
        obs_idx = np.repeat(oi, per)
        hits = self.sat.overlap_pairs(segments.take(seg_idx), obstacles.take(obs_idx))
        hits = hits.reshape(ti.size, per)
        steps: IntArray = np.where(hits.any(axis=1), hits.argmax(axis=1), -1)
        return steps
