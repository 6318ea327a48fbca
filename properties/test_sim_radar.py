"""The simulated radar through the radar front-end (SR-SIM-8, SR-FUS-7).

Random apron scenes (people, tugs, containers standing or driving, 1-3 large reflectors) seen by
the simulated radar from a robot that drives and turns: the front-end drops every ground-clutter
return and every multipath ghost lying clearly beyond its reflector, keeps every real return
strong enough by RCS and SNR, and its ego-motion-compensated Doppler of a real return is the
target's own velocity along the ray within the radar's noise. The simulator's returns are
checked against the scene's geometry: range, bearing and Doppler of real returns from the true
states, every ghost the mirror image of a target in a reflector.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.config import SafecaseConfig
from pipeline.frames import to_parent
from pipeline.sensors.radar import RadarFrontEnd
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.layouts import apron_stand
from pipeline.sources.sim.objects import baggage_tug, person, uld_container
from pipeline.sources.sim.radar import CLUTTER_ID, GHOST_ID, RadarSpec, SimRadar
from pipeline.sources.sim.world import SimObject, World
from pipeline.types import FloatArray, IntArray, RadarDetections
from pipeline.types.sensors import Twist
from properties.radar_cases import pose_at

CODE = ["pipeline/sources/sim/radar.py", "pipeline/sensors/radar.py"]


def _line_distance(x: FloatArray, y: FloatArray, seg: FloatArray) -> FloatArray:
    """Distance of each point to the nearest reflector's infinite line ``(n,)``."""
    ex, ey = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    norm = np.hypot(ex, ey)
    d = np.abs((x[:, None] - seg[None, :, 0]) * ey - (y[:, None] - seg[None, :, 1]) * ex) / norm
    out: FloatArray = d.min(axis=1)
    return out


@st.composite
def _scenes(draw: st.DrawFn) -> tuple[World, FloatArray, tuple[float, float, float], Twist, int]:
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    pose = (float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), float(rng.uniform(-3, 3)))
    objects = []
    for i in range(draw(st.integers(1, 6))):
        model = [person(), baggage_tug(), uld_container()][int(rng.integers(0, 3))]
        r, b = float(rng.uniform(3.0, 35.0)), pose[2] + float(rng.uniform(-1.0, 1.0))
        x, y = pose[0] + r * math.cos(b), pose[1] + r * math.sin(b)
        motion = (
            mo.constant(float(rng.uniform(0.5, 2.0))) if rng.random() < 0.5 else mo.stationary()
        )
        heading = float(rng.uniform(-math.pi, math.pi))
        objects.append(SimObject(i + 1, f"o{i}", model, mo.integrate(motion, x, y, heading, 2.0),
                                 motion))  # fmt: skip
    reflectors = []
    for _ in range(draw(st.integers(1, 3))):
        r, b = float(rng.uniform(8.0, 30.0)), pose[2] + float(rng.uniform(-1.0, 1.0))
        cx, cy = pose[0] + r * math.cos(b), pose[1] + r * math.sin(b)
        a, half = float(rng.uniform(-math.pi, math.pi)), float(rng.uniform(3.0, 15.0))
        reflectors.append([cx - half * math.cos(a), cy - half * math.sin(a),
                           cx + half * math.cos(a), cy + half * math.sin(a)])  # fmt: skip
    layout = apron_stand()
    world = World("radar", layout.structure, tuple(objects), layout.bounds_m, "apron")
    twist = Twist(float(rng.uniform(-1.0, 2.5)), 0.0, float(rng.uniform(-0.8, 0.8)))
    return world, np.array(reflectors), pose, twist, seed


@pytest.mark.requirement("SR-SIM-8", kind="property", code=CODE)
@pytest.mark.requirement("SR-FUS-7", kind="property", code=CODE)
@settings(max_examples=examples(100), deadline=None)
@given(scene=_scenes())
def test_ghosts_and_clutter_never_pass_the_front_end(
    safecase_config: SafecaseConfig,
    scene: tuple[World, FloatArray, tuple[float, float, float], Twist, int],
) -> None:
    world, reflectors, pose, twist, seed = scene
    spec = RadarSpec(clutter_per_scan=8.0)
    radar, truth = SimRadar(spec, np.random.default_rng(seed)).scan(
        world, 1.0, pose, twist, reflectors
    )
    front = RadarFrontEnd(safecase_config)
    kept, _ = front.filter(radar, pose, reflectors)
    c = safecase_config.radar
    rec = current()
    clutter = truth == CLUTTER_ID
    assert not kept[clutter].any()
    # A ghost lies behind its reflector by its target's distance to it: beyond the margin (and
    # the noise) it must go; nearer, it sits next to its own target and is counted.
    wx, wy = _world_xy(radar, pose)
    behind = _line_distance(wx, wy, reflectors) > c.ghost_margin_m + 0.7
    ghost = truth == GHOST_ID
    assert not kept[ghost & behind].any(), np.flatnonzero(ghost & behind & kept)
    real = truth >= 0
    assert radar.rcs_dbsm is not None
    assert radar.snr_db is not None
    strong = (radar.rcs_dbsm >= c.min_rcs_dbsm) & (radar.snr_db >= c.min_snr_db)
    clear = _line_distance(wx, wy, reflectors) > 1.0
    assert kept[real & strong & clear].all()
    rec.count("returns", "clutter (all dropped)", int(clutter.sum()))
    rec.count("returns", "ghosts beyond the margin (all dropped)", int((ghost & behind).sum()))
    rec.count("returns", "ghosts within 1 m of their reflector", int((ghost & ~behind).sum()))
    rec.count("returns", "ghosts kept (within 1 m of their reflector)", int((ghost & kept).sum()))
    rec.count("returns", "real, strong (all kept)", int((real & strong & clear).sum()))
    rec.count("returns", "real, too weak (dropped)", int((real & ~strong).sum()))
    # Ego-motion compensation of the kept real returns: the target's own radial speed.
    framed = front.in_tracking_frame(radar, kept, pose, twist, 0.0)
    own = _own_radial_speed(world, truth[kept], framed.bearing_rad)
    noise = spec.doppler_std_mps + 3.0 * spec.azimuth_std_rad * (abs(twist.vx_mps) + 1.0)
    mine = truth[kept] >= 0
    assert np.all(np.abs(framed.radial_velocity_mps[mine] - own[mine]) <= 5.0 * noise)
    rec.count("compensated Doppler", "real returns within 5 sigma", int(mine.sum()))


def _world_xy(
    radar: RadarDetections, pose: tuple[float, float, float]
) -> tuple[FloatArray, FloatArray]:
    """Returns in the world frame (the robot at ``pose``)."""
    x, y = to_parent(pose, radar.x_m, radar.y_m)
    return x, y


def _own_radial_speed(world: World, ids: IntArray, bearing_rad: FloatArray) -> FloatArray:
    """Each real return's target velocity along the (world-frame) ray; NaN for the others."""
    out = np.full(ids.shape[0], np.nan)
    by_id = {o.object_id: o for o in world.objects}
    for k, oid in enumerate(ids):
        if oid >= 0:
            state = by_id[int(oid)].trajectory.at(np.array([1.0]))
            out[k] = (
                math.cos(bearing_rad[k]) * state["vx_mps"][0]
                + math.sin(bearing_rad[k]) * state["vy_mps"][0]
            )
    return out


@pytest.mark.requirement("SR-SIM-8", kind="property", code=["pipeline/sources/sim/radar.py"])
@settings(max_examples=examples(100), deadline=None)
@given(scene=_scenes())
def test_simulated_returns_follow_the_geometry(
    scene: tuple[World, FloatArray, tuple[float, float, float], Twist, int],
) -> None:
    """Noise-free returns: real ones at their target's nearest vertex with its range rate; each
    ghost the mirror image, in some reflector, of a target the radar sees."""
    world, reflectors, pose, twist, seed = scene
    spec = RadarSpec(range_std_m=0.0, azimuth_std_rad=0.0, doppler_std_mps=0.0,
                     clutter_per_scan=0.0)  # fmt: skip
    radar, truth = SimRadar(spec, np.random.default_rng(seed)).scan(
        world, 1.0, pose, twist, reflectors
    )
    wx, wy = _world_xy(radar, pose)
    mx, my = to_parent(pose, np.array([spec.mount_x_m]), np.array([spec.mount_y_m]))
    # Each object's return point: its outline vertex nearest the radar.
    points = {}
    for obj, parts in zip(world.objects, world.object_polygons(1.0), strict=True):
        verts = np.concatenate(parts)
        near = int(np.argmin(np.hypot(verts[:, 0] - mx[0], verts[:, 1] - my[0])))
        points[obj.object_id] = (float(verts[near, 0]), float(verts[near, 1]))
    for k in np.flatnonzero(truth >= 0):
        px, py = points[int(truth[k])]
        assert math.hypot(px - wx[k], py - wy[k]) < 1e-9
    for k in np.flatnonzero(truth == GHOST_ID):
        # Mirrored back across one of the reflector lines, a ghost is some target's point.
        found = False
        for x0, y0, x1, y1 in reflectors:
            ex, ey = x1 - x0, y1 - y0
            nx, ny = -ey / math.hypot(ex, ey), ex / math.hypot(ex, ey)
            d = (wx[k] - x0) * nx + (wy[k] - y0) * ny
            bx, by = wx[k] - 2 * d * nx, wy[k] - 2 * d * ny
            found |= any(math.hypot(bx - px, by - py) < 1e-6 for px, py in points.values())
        assert found, k
    # The Doppler: the range rate of the target's point from the moving mount, by finite
    # differences of the true geometry (objects here drive straight, so the point translates).
    h = 1e-5
    states = {o.object_id: o.trajectory.at(np.array([1.0])) for o in world.objects}

    def ranges(dt: float) -> FloatArray:
        p = pose_at(pose, twist, dt)
        ax, ay = to_parent(p, np.array([spec.mount_x_m]), np.array([spec.mount_y_m]))
        out = np.full(truth.shape[0], np.nan)
        for k in np.flatnonzero(truth >= 0):
            st_k = states[int(truth[k])]
            px, py = points[int(truth[k])]
            qx = px + float(st_k["vx_mps"][0]) * dt
            qy = py + float(st_k["vy_mps"][0]) * dt
            out[k] = math.hypot(qx - ax[0], qy - ay[0])
        return out

    rate = (ranges(h) - ranges(-h)) / (2 * h)
    real = truth >= 0
    assert np.allclose(radar.radial_velocity_mps[real], rate[real], rtol=0.0, atol=1e-4)
    current().count("returns", "real", int(real.sum()))
    current().count("returns", "ghost", int((truth == GHOST_ID).sum()))
