"""Examples for the runtime cycle and `safecase run` (SR-RUN-*)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import default_config, overridden
from pipeline.static_map import StaticMap
from pipeline.types import Action, RadarDetections, Scan, ThermalDetections
from properties.cli_runner import run_safecase
from safety.runtime import CycleInput, Levers, Runtime

CONFIG = default_config()


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The committed model, loaded once."""
    return Classifier.from_config(CONFIG.classify)


def _scan(ranges_m: np.ndarray, stamp_s: float = 10.0) -> Scan:
    angles = np.linspace(-math.pi, math.pi, ranges_m.size, endpoint=False)
    return Scan(stamp_s, angles, ranges_m)


def _empty_scan() -> Scan:
    return _scan(np.full(1080, np.inf))


@pytest.mark.requirement("SR-RUN-1", kind="example", code=["safety/runtime.py"])
def test_an_empty_world_proceeds_at_full_speed(classifier: Classifier) -> None:
    rt = Runtime(CONFIG, classifier=classifier)
    out = rt.step(CycleInput.standing(_empty_scan(), 10.1, CONFIG, charge_s=0.01))
    assert out.command.action is Action.PROCEED
    assert out.command.speed_mps == CONFIG.stopping.robot_max_speed_mps


@pytest.mark.requirement("SR-RUN-1", kind="example", code=["safety/runtime.py"])
def test_a_thermal_only_pedestrian_ahead_stops_the_robot(classifier: Classifier) -> None:
    rt = Runtime(CONFIG, classifier=classifier)
    person = ThermalDetections(np.array([10.05]), np.array([1.2]), np.array([0.0]), np.array([0.9]))
    out = rt.step(CycleInput.standing(_empty_scan(), 10.1, CONFIG, charge_s=0.01, thermal=person))
    assert out.command.action is Action.STOP
    assert out.record.inputs["fusion"]["n_thermal_only"] == 1
    assert out.record.inputs["path"]["nearest_pedestrian_m"] < 1.0
    # 5 m to the side, walking at 1.6 m/s, it still slows the robot (passive safety).
    aside = ThermalDetections(np.array([10.15]), np.array([0.0]), np.array([5.0]), np.array([0.9]))
    scan = _scan(np.full(1080, np.inf), stamp_s=10.1)
    far = rt.step(CycleInput.standing(scan, 10.2, CONFIG, charge_s=0.01, thermal=aside))
    assert far.command.action in (Action.SLOW, Action.PROCEED)


@pytest.mark.requirement(
    "SR-RUN-1", kind="example", code=["safety/runtime.py", "safety/geometry/path.py"]
)
def test_a_wall_too_long_to_cluster_still_limits_the_speed(classifier: Classifier) -> None:
    # A wall 1.0 m ahead across the whole front: one cluster of ~500 points, more than the
    # cluster filter keeps (200), so no track: the loose-point path check must see it.
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    with np.errstate(divide="ignore"):
        ranges = np.where(np.cos(angles) > 0.05, 1.0 / np.cos(angles), np.inf)
    ranges = np.where(ranges < 20.0, ranges, np.inf)
    scan = Scan(10.0, angles, ranges)
    rt = Runtime(CONFIG, classifier=classifier)
    out = rt.step(CycleInput.standing(scan, 10.1, CONFIG, charge_s=0.01))
    assert out.record.inputs["clusters"]["n_too_large"] >= 1
    assert out.record.inputs["path"]["loose_points_on_path"] > 0
    # The robot's front is 0.45 m ahead of its centre: 0.55 m free, sampled down to 0.5 m. By
    # default loose points may be a moving object merged with structure: they close at 1.6 m/s.
    assert out.command.action is Action.STOP, out.command
    assert "free distance 0.500 m, closing 1.60 m/s" in out.command.reasons[0]
    # Declared static, the same wall only slows the robot.
    static = overridden(CONFIG, {"runtime": {"loose_points": "static"}})
    rt = Runtime(static, classifier=classifier)
    out = rt.step(CycleInput.standing(scan, 10.1, static, charge_s=0.01))
    assert out.command.action is Action.SLOW, out.command
    assert "free distance 0.500 m, closing 0.00 m/s, margin 1.00 m" in out.command.reasons[0]


def test_the_envelopes_and_costmap_are_recorded_and_the_planner_can_run(
    classifier: Classifier,
) -> None:
    config = overridden(CONFIG, {"runtime": {"planner_check": True}})
    rt = Runtime(config, classifier=classifier)
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    ranges = np.full(1080, np.inf)
    box = np.abs(angles) < 0.08  # a small object 2 m ahead
    ranges[box] = 2.0
    out = None
    for k in range(5):  # long enough for a confirmed, classified track
        scan = Scan(10.0 + 0.1 * k, angles, ranges, seq=k)
        out = rt.step(CycleInput.standing(scan, scan.stamp_s + 0.1, config, charge_s=0.01))
    assert out is not None
    assert out.envelopes is not None
    assert out.envelopes.n >= 1
    assert out.record.inputs["costmap"]["occupied_cells"] > 0
    assert out.record.inputs["planner"]["blocked"] > 0
    assert set(out.wall_s) >= {"points", "classify", "path", "planner", "costmap", "decide"}


@pytest.mark.requirement("SR-RUN-4", kind="example", code=["evidence/cli/run.py"])
def test_safecase_run_writes_a_log_that_verifies_and_a_plot(tmp_path: Path) -> None:
    log = tmp_path / "run.jsonl"
    done = run_safecase("run", "--duration", "3", "--audit", str(log), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "reversing_forklift_aisle" in done.stdout
    assert log.exists()
    assert log.with_suffix(".png").stat().st_size > 10_000
    verify = run_safecase("audit", "replay", str(log), cwd=tmp_path)
    assert verify.returncode == 0, verify.stdout + verify.stderr
    assert "replayed 30 of 30 cycles exactly" in verify.stdout


def test_safecase_run_refuses_bad_options(tmp_path: Path) -> None:
    done = run_safecase("run", "--scenario", "nowhere", cwd=tmp_path)
    assert done.returncode == 2
    assert "--scenario 'nowhere': unknown; known: reversing_forklift_aisle" in done.stderr
    done = run_safecase("run", "--emulate", "sick", cwd=tmp_path)
    assert done.returncode == 2
    assert "allowed: rplidar, scip" in done.stderr


class _FullDisk:
    """An audit writer whose disk is full."""

    def append(self, record: object) -> None:
        raise OSError(28, "No space left on device")


@pytest.mark.requirement("SR-RUN-2", kind="example", code=["safety/runtime.py"])
def test_a_cycle_that_cannot_be_recorded_is_not_acted_on(classifier: Classifier) -> None:
    rt = Runtime(CONFIG, classifier=classifier, writer=_FullDisk())  # type: ignore[arg-type]
    out = rt.step(CycleInput.standing(_empty_scan(), 10.1, CONFIG, charge_s=0.01))
    assert out.decision.command.action is Action.PROCEED  # what would have been commanded
    assert out.command.action is Action.STOP
    assert out.command.reasons[0].startswith("audit: the cycle could not be recorded (OSError")


def _crossing_fast(rt: Runtime) -> list[str]:
    """The domain monitor's reasons while a 0.3 m object 4 m ahead crosses at 6 m/s."""
    angles = np.linspace(-math.pi, math.pi, 2000, endpoint=False)
    reasons: list[str] = []
    for k in range(8):  # 0.6 m per scan
        cx, cy = 4.0, -2.0 + 0.6 * k
        ranges = np.full(angles.size, np.inf)
        bearing = math.atan2(cy, cx)
        near = np.abs(np.angle(np.exp(1j * (angles - bearing)))) < 0.15 / math.hypot(cx, cy)
        ranges[near] = math.hypot(cx, cy)
        scan = Scan(10.0 + 0.1 * k, angles, ranges, seq=k)
        out = rt.step(CycleInput.standing(scan, scan.stamp_s + 0.1, CONFIG, charge_s=0.01))
        reasons += out.command.reasons
    return [r for r in reasons if r.startswith("domain:object_speed: track")]


@pytest.mark.requirement("SR-AVL-8", kind="property", code=["safety/obstacles.py"])
def test_returns_wholly_on_the_map_are_not_held_to_the_speed_domain(
    classifier: Classifier,
) -> None:
    """The same returns drawn on the site's map (a wall along their path): the structure does
    not move, so the domain monitor leaves them; off the map, or with the lever off, it stops."""
    wall = np.array([[3.9, -3.0], [4.2, -3.0], [4.2, 3.0], [3.9, 3.0]])
    on = StaticMap.from_parts([wall], 0.05, 0.1)
    off = StaticMap.from_parts([wall + np.array([1.0, 0.0])], 0.05, 0.1)
    assert not _crossing_fast(Runtime(CONFIG, classifier=classifier, static_map=on))
    assert _crossing_fast(Runtime(CONFIG, classifier=classifier, static_map=off))
    lever_off = Levers(mapped_structure=False)
    assert _crossing_fast(Runtime(CONFIG, classifier=classifier, static_map=on, levers=lever_off))


@pytest.mark.requirement("SR-RUN-2", kind="example", code=["safety/obstacles.py"])
def test_an_object_faster_than_the_domain_allows_stops_the_robot(classifier: Classifier) -> None:
    fast = _crossing_fast(Runtime(CONFIG, classifier=classifier))
    assert fast
    assert "above predict.max_object_speed_mps = 3.5" in fast[0]


def _three_objects(stamp_s: float, seq: int) -> Scan:
    """Three small objects 3 m away, ahead and 0.6 rad to either side."""
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    ranges = np.full(1080, np.inf)
    for centre in (-0.6, 0.0, 0.6):
        ranges[np.abs(angles - centre) < 0.06] = 3.0
    return Scan(stamp_s, angles, ranges, seq=seq)


def _three_of(sensor: str, stamp_s: float) -> dict[str, object]:
    """Three fresh detections of ``sensor`` at the three objects ("" for none)."""
    bearing = np.array([-0.6, 0.0, 0.6])
    stamp = np.full(3, stamp_s)
    if sensor == "thermal":
        xy = 3.0 * np.cos(bearing), 3.0 * np.sin(bearing)
        return {"thermal": ThermalDetections(stamp, *xy, np.full(3, 0.9))}
    if sensor == "radar":
        return {"radar": RadarDetections(stamp, np.full(3, 3.0), bearing, np.zeros(3))}
    return {}


@pytest.mark.requirement(
    "SR-TIM-3",
    kind="example",
    code=["safety/runtime.py", "safety/cycle.py", "safety/model/monitors.py"],
)
@pytest.mark.parametrize(
    ("cap", "sensor"),
    [
        ("cluster.max_clusters", ""),
        ("track.max_detections", ""),
        ("track.max_tracks", ""),
        ("fusion.max_thermal", "thermal"),
        ("fusion.max_radar", "radar"),
        ("geometry.max_obstacles", ""),
    ],
)
def test_a_cap_that_drops_something_stops_the_cycle_and_the_log_names_it(
    classifier: Classifier, cap: str, sensor: str
) -> None:
    """Three objects against a cap of 1 (confirmed tracks after 5 scans): the cycle's
    observation counts what that cap dropped (two objects; for the obstacle cap every envelope
    row but one, a track may have two), no other cap drops anything, and the command is STOP
    naming the cap and the count."""
    section, key = cap.split(".")
    config = overridden(CONFIG, {section: {key: 1}})
    rt = Runtime(config, classifier=classifier)
    for k in range(5):
        stamp = 10.0 + 0.1 * k
        inp = CycleInput.standing(
            _three_objects(stamp, k), stamp + 0.1, config, charge_s=0.01, **_three_of(sensor, stamp)
        )
        out = rt.step(inp)
    want = 2
    if cap == "geometry.max_obstacles":
        assert out.envelopes is not None
        assert out.envelopes.n >= 3
        want = out.envelopes.n - 1
    dropped = dict(out.record.observation.over_cap)
    assert dropped[cap] == want, dropped
    assert all(n == 0 for name, n in dropped.items() if name != cap), dropped
    assert out.command.action is Action.STOP
    assert f"{cap} dropped {want}" in " ".join(out.command.reasons), out.command.reasons


@pytest.mark.requirement(
    "SR-TRK-1", kind="example", code=["safety/runtime.py", "safety/cycle.py", "pipeline/points.py"]
)
def test_the_record_counts_the_dropped_beams_and_what_the_tracker_did(
    classifier: Classifier,
) -> None:
    """A scan of the three objects with 7 NaN ranges, 4 below the minimum range and 2 beyond
    the maximum: the cycle's record counts each kind of dropped beam and the tracker's
    detections and births."""
    scan = _three_objects(10.0, 0)
    ranges = scan.ranges_m.copy()
    ranges[500:507] = np.nan
    ranges[600:604] = 0.5 * CONFIG.scan.min_range_m
    ranges[700:702] = 2.0 * CONFIG.scan.max_range_m
    scan = Scan(scan.stamp_s, scan.angles_rad, ranges, seq=0)
    out = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(scan, 10.1, CONFIG, charge_s=0.01)
    )
    drops = out.record.inputs["drops"]
    n_inf = int(np.count_nonzero(np.isinf(ranges)))
    assert (drops["n_beams"], drops["n_nan"], drops["n_inf"]) == (1080, 7, n_inf)
    assert (drops["n_below_min"], drops["n_above_max"]) == (4, 2)
    assert drops["n_valid"] == 1080 - 7 - n_inf - 4 - 2
    tracker = out.record.inputs["tracker"]
    assert (tracker["n_detections"], tracker["n_born"], tracker["n_live"]) == (3, 3, 3)
