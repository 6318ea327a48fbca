"""Pictures of a simulated run: the scene from above, speeds and labels, separations.

Used by ``safecase sim show``. matplotlib is imported lazily so that the simulator itself does
not need it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pipeline.frames import to_parent
from pipeline.sources.sim.lidar import STRUCTURE_ID
from pipeline.sources.sim.objects import FORKLIFT_KINDS
from pipeline.sources.sim.simulation import SimResult
from pipeline.sources.sim.truth import ObjectClass, forklift_states

__all__ = ["key_time", "scene_figure"]

_STRUCTURE_COLOURS = {
    "wall": "#6b6b6b",
    "rack_upright": "#3b5b92",
    "pallet_load": "#c9a36b",
    "aircraft_tyre": "#222222",
    "cone": "#f08a24",
    "gpu": "#8a8a5c",
}
_STATE_COLOURS = {
    int(ObjectClass.FORKLIFT_MOVING): "#d9f0d3",
    int(ObjectClass.FORKLIFT_STATIONARY): "#e0e0e0",
    int(ObjectClass.FORKLIFT_NEAR_REVERSAL): "#fdd49e",
}


def key_time(result: SimResult) -> float:
    """The most telling instant of a run: the first contact, else the closest approach of a
    moving object (else of any object)."""
    if result.contact:
        return float(np.nanmin(result.contact_time_s))
    if result.min_separation_m.size:
        moving = np.array(
            [np.abs(o.trajectory.speed_mps).max() > 0.05 for o in result.world.objects]
        )
        sep = (
            np.where(moving, result.min_separation_m, np.inf)
            if moving.any()
            else result.min_separation_m
        )
        i = int(np.argmin(sep))
        return float(result.min_separation_time_s[i])
    return float(result.ego_log["t_s"][-1] / 2)


def scene_figure(result: SimResult, at_s: float | None = None) -> Any:
    """A matplotlib Figure: top view at ``at_s`` (default :func:`key_time`) with the scan
    taken then, trajectories, object outlines every 2 s; speeds with forklift state bands;
    ego-to-object separations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    world = result.world
    t_key = key_time(result) if at_s is None else float(at_s)
    frame = min(result.frames, key=lambda f: abs(f.truth.stamp_s - t_key))
    t_key = frame.truth.stamp_s
    x0, x1, y0, y1 = world.bounds_m
    if (x1 - x0) > 1.6 * (y1 - y0):  # wide scene on top, the two plots below
        scene_h = 14.0 * (y1 - y0) / (x1 - x0) + 0.8
        fig = plt.figure(figsize=(14, scene_h + 4.2), layout="constrained")
        grid = fig.add_gridspec(2, 2, height_ratios=[scene_h, 4.2])
        ax = fig.add_subplot(grid[0, :])
        ax_v = fig.add_subplot(grid[1, 0])
        ax_d = fig.add_subplot(grid[1, 1])
    else:
        fig = plt.figure(figsize=(15, 9), layout="constrained")
        grid = fig.add_gridspec(2, 2, width_ratios=[1.6, 1])
        ax = fig.add_subplot(grid[:, 0])
        ax_v = fig.add_subplot(grid[0, 1])
        ax_d = fig.add_subplot(grid[1, 1])
    cmap = plt.get_cmap("tab10")
    colours = [cmap(i % 10) for i in range(len(world.objects))]

    for label, poly in world.decor:
        ax.add_patch(Polygon(poly, closed=True, fc="#dde6f2", ec="#9aaccc", lw=0.8, label=label))
    st = world.structure.outline
    for kind, poly in zip(world.structure.part_kinds, st.parts(), strict=True):
        ax.add_patch(
            Polygon(
                poly, closed=True, fc=_STRUCTURE_COLOURS.get(kind, "#999999"), ec="none", alpha=0.8
            )
        )

    t_end = float(result.ego_log["t_s"][-1])
    ghost_times = np.arange(0.0, t_end + 1e-9, 2.0)
    for t in ghost_times:
        for polys, col in zip(world.object_polygons(float(t)), colours, strict=True):
            for p in polys:
                ax.add_patch(Polygon(p, closed=True, fc="none", ec=col, lw=0.6, alpha=0.35))
    for polys, col in zip(world.object_polygons(t_key), colours, strict=True):
        for p in polys:
            ax.add_patch(Polygon(p, closed=True, fc=col, ec="black", lw=0.8, alpha=0.9))
    tt = np.linspace(0.0, t_end, 400)  # objects drawn until the run ended
    for obj, col in zip(world.objects, colours, strict=True):
        s = obj.trajectory.at(tt)
        ax.plot(
            s["x_m"],
            s["y_m"],
            color=col,
            lw=1.2,
            label=f"{obj.object_id} {obj.name} ({obj.model.kind.value})",
        )
        ax.plot(s["x_m"][0], s["y_m"][0], "o", color=col, ms=4)

    log = result.ego_log
    ax.plot(log["x_m"], log["y_m"], color="black", lw=2.0, label="ego robot path")
    ego_at = np.interp(t_key, log["t_s"], log["arc_m"])
    _draw_ego(ax, result, ego_at, Polygon)
    for t in ghost_times:
        _draw_ego(ax, result, float(np.interp(t, log["t_s"], log["arc_m"])), Polygon, ghost=True)

    truth = frame.truth
    ranges = frame.scan.ranges_m
    ok = np.isfinite(ranges)
    sx, sy, syaw = truth.scanner_pose
    ang = frame.scan.angles_rad[ok] + syaw
    px = sx + ranges[ok] * np.cos(ang)
    py = sy + ranges[ok] * np.sin(ang)
    owner = truth.beams.owner_id[ok]
    pc = np.array(["#555555" if o == STRUCTURE_ID else "red" for o in owner])
    ax.scatter(
        px, py, s=2.5, c=pc, zorder=5, label=f"scan at t = {t_key:.1f} s ({ok.sum()} returns)"
    )
    if result.contact:
        i = int(np.nanargmin(result.contact_time_s))
        tc = float(result.contact_time_s[i])
        cx, cy = (np.interp(tc, log["t_s"], log["x_m"]), np.interp(tc, log["t_s"], log["y_m"]))
        ax.plot(
            cx,
            cy,
            "X",
            color="red",
            ms=14,
            zorder=6,
            label=f"contact with {world.objects[i].name} at {tc:.2f} s",
        )
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        f"{result.name}, seed {result.seed}: scene, trajectories (outlines every 2 s), "
        f"scan at {t_key:.1f} s",
        fontsize=10,
    )
    ax.legend(loc="lower left", fontsize=7, framealpha=0.85)

    # State bands of one forklift only (the moving one that came closest), to stay readable.
    banded = [
        i
        for i, o in enumerate(world.objects)
        if o.model.kind in FORKLIFT_KINDS
        and o.motion is not None
        and np.abs(o.trajectory.speed_mps).max() > 0.05
    ]
    if banded:
        closest = min(banded, key=lambda j: float(result.min_separation_m[j]))
        motion = world.objects[closest].motion
        assert motion is not None
        states = forklift_states(motion, tt, result.label_rules)
        for code, colour in _STATE_COLOURS.items():
            ax_v.fill_between(tt, -2.5, 2.5, where=states == code, color=colour, alpha=0.6, lw=0)
    for obj, col in zip(world.objects, colours, strict=True):
        s = obj.trajectory.at(tt)
        ax_v.plot(tt, s["speed_mps"], color=col, label=obj.name)
    ax_v.plot(log["t_s"], log["speed_mps"], color="black", lw=2, label="ego")
    ax_v.plot(log["t_s"], log["command_mps"], color="black", lw=1, ls=":", label="ego command")
    ax_v.axvline(t_key, color="grey", lw=0.8)
    ax_v.set_ylim(-2.5, 3.5)
    ax_v.set_ylabel("signed speed (m/s)")
    ax_v.set_title(
        "speeds; forklift bands: moving green, stationary grey, near reversal orange", fontsize=8
    )
    ax_v.legend(fontsize=7, ncol=2)
    for i, col in enumerate(colours):
        ax_d.plot(
            result.separation_t_s,
            result.separation_m[:, i],
            color=col,
            label=f"{world.objects[i].name}: min {result.min_separation_m[i]:.2f} m",
        )
    ax_d.axhline(0.0, color="red", lw=0.8)
    ax_d.set_ylim(-0.2, 8.0)
    ax_d.set_xlabel("t (s)")
    ax_d.set_ylabel("ego footprint to object (m)")
    ax_d.set_title(f"separations (ego braking {result.decel_mps2:.2f} m/s^2)", fontsize=8)
    ax_d.legend(fontsize=7)
    return fig


def _draw_ego(ax: Any, result: SimResult, arc_m: float, polygon: Any, ghost: bool = False) -> None:
    spec = result.ego_spec
    pose = spec.route.pose_at(np.array([arc_m]))[0]
    fp = spec.footprint().vertices_m
    pts = np.stack(to_parent((pose[0], pose[1], pose[2]), fp[:, 0], fp[:, 1]), 1)
    if ghost:
        ax.add_patch(polygon(pts, closed=True, fc="none", ec="black", lw=0.5, alpha=0.3))
    else:
        ax.add_patch(polygon(pts, closed=True, fc="#ffe000", ec="black", lw=1.2, zorder=4))
