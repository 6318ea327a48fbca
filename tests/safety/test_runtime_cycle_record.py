"""What a runtime cycle reports besides its command: the observation of a cycle without a
scan or a driver, its CPU and stage times, the cycle count, a failing perception's STOP and the
stamp of the STOP an unrecordable cycle gives (SR-RUN-2, SR-TIM-3, SR-AUD-1)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pipeline.classify.model import Classifier
from pipeline.config import default_config, overridden
from pipeline.perception import Perceived, Perception, Stopwatch
from pipeline.static_map import StaticMap, map_from_config
from pipeline.types import Action, FloatArray, Frame, Scan
from safety.geometry.path import PathAhead
from safety.model.stopping import StoppingParams
from safety.runtime import CycleInput, Runtime

CONFIG = default_config()
CODE = ["safety/runtime.py"]


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The committed model, loaded once."""
    return Classifier.from_config(CONFIG.classify)


def _scan(stamp_s: float) -> Scan:
    angles = np.linspace(-math.pi, math.pi, 1080, endpoint=False)
    return Scan(stamp_s, angles, np.full(1080, np.inf))


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_cycle_without_a_scan_or_a_driver_observes_none_of_them(
    classifier: Classifier,
) -> None:
    """No scan: no beams counted (so the blinded-scanner monitor has nothing to judge) and no
    driver error; the STOP is for the missing scan alone."""
    out = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(None, 10.1, CONFIG, charge_s=0.01)
    )
    observation = out.record.observation
    assert (observation.n_beams, observation.n_below_min) == (0, 0)
    assert observation.driver_error == ""
    assert observation.driver_state is None
    assert out.command.action is Action.STOP
    assert not any("below the minimum range" in r for r in out.command.reasons)


@pytest.mark.requirement("SR-TIM-3", kind="example", code=CODE)
def test_a_cycle_reports_its_cpu_time_and_stage_times_and_counts_itself(
    classifier: Classifier,
) -> None:
    rt = Runtime(CONFIG, classifier=classifier)
    for k in range(3):
        before = time.perf_counter()
        out = rt.step(CycleInput.standing(_scan(10.0 + 0.1 * k), 10.1 + 0.1 * k, CONFIG))
        wall_s = time.perf_counter() - before
        # thread CPU time of this one thread: positive and never more than the wall clock
        assert 0.0 < out.cpu_s <= wall_s
        assert out.record.timings_s == out.wall_s
        assert {"cluster", "decide"} <= set(out.wall_s)
    assert rt.cycles == 3


class _Broken:
    """A perception chain that fails with an error that is not a stage's."""

    def perceive(
        self,
        frame: Frame,
        *,
        now_s: Callable[[], float] | None = None,
        watch: Stopwatch | None = None,
    ) -> Perceived:
        raise RuntimeError("the chain broke")

    def reset(self) -> None:
        pass


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_a_perception_that_raises_stops_the_robot_and_the_cycle_is_recorded(
    classifier: Classifier,
) -> None:
    rt = Runtime(CONFIG, classifier=classifier, perception=_Broken())
    out = rt.step(CycleInput.standing(_scan(10.0), 10.1, CONFIG, charge_s=0.01))
    assert out.command.action is Action.STOP
    assert any("RuntimeError: the chain broke" in r for r in out.command.reasons)
    assert out.record.inputs["scan"] is not None
    assert out.envelopes is None
    assert rt.cycles == 1


class _FullDisk:
    """An audit writer whose disk is full."""

    def append(self, record: object) -> None:
        raise OSError(28, "No space left on device")


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_the_stop_of_an_unrecordable_cycle_keeps_the_decision_stamp(
    classifier: Classifier,
) -> None:
    rt = Runtime(CONFIG, classifier=classifier, writer=_FullDisk())  # type: ignore[arg-type]
    out = rt.step(CycleInput.standing(_scan(10.0), 10.1, CONFIG, charge_s=0.01))
    assert out.command.action is Action.STOP
    assert out.command.stamp_s == out.decision.command.stamp_s
    assert out.command.stamp_s == pytest.approx(10.11)


def _curving(step_m: float = 0.1, n: int = 40) -> PathAhead:
    """A path from the origin, heading 0 there, turning left at 0.5 rad/m."""
    arc = np.arange(n, dtype=np.float64) * step_m
    theta: FloatArray = 0.5 * arc
    # exact positions of the circular arc of radius 2 m
    return PathAhead(arc, 2.0 * np.sin(theta), 2.0 * (1.0 - np.cos(theta)), theta)


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_the_envelopes_are_placed_at_the_path_start_not_further_along(
    classifier: Classifier,
) -> None:
    """The envelopes are moved into the robot's frame at the path's first pose; where the path
    goes after it must not move them (a curving path and a straight one from the same pose)."""
    ranges = np.full(1080, np.inf)
    ranges[600:612] = 3.0  # an object about 3 m away, left of ahead
    scan = _scan(10.0)
    scan = Scan(scan.stamp_s, scan.angles_rad, ranges)
    curving = CycleInput(scan, 10.1, (0.0, 0.0, 0.0), _curving(), charge_s=0.01)
    straight = CycleInput.standing(scan, 10.1, CONFIG, charge_s=0.01)
    bent = Runtime(CONFIG, classifier=classifier).step(curving).envelopes
    plain = Runtime(CONFIG, classifier=classifier).step(straight).envelopes
    assert bent is not None
    assert plain is not None
    assert bent.polygons.n > 0
    np.testing.assert_array_equal(bent.polygons.vertices_m, plain.polygons.vertices_m)


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_only_points_in_no_kept_cluster_are_loose(classifier: Classifier) -> None:
    """An object 3 m ahead (one kept cluster, index 0) and a lone point 1.5 m ahead (noise): the
    path check reads the lone point as loose and the object's points as the object."""
    scan = _scan(10.0)
    ahead = int(np.argmin(np.abs(scan.angles_rad)))
    ranges = np.full(1080, np.inf)
    ranges[ahead - 6 : ahead + 6] = 3.0
    ranges[ahead + 15] = 1.5
    out = Runtime(CONFIG, classifier=classifier).step(
        CycleInput.standing(Scan(10.0, scan.angles_rad, ranges), 10.1, CONFIG, charge_s=0.01)
    )
    assert out.detail is not None
    assert out.detail.perceived is not None
    assert out.detail.perceived.clusters.point_labels.tolist() == [0] * 12 + [-1]
    path = out.record.inputs["path"]
    assert path["loose_points_on_path"] == 1
    assert path["nearest_loose_point_m"] < 1.5


def _object_ahead(distance_m: float = 3.0) -> Scan:
    """One small object ``distance_m`` straight ahead (12 beams)."""
    scan = _scan(10.0)
    ahead = int(np.argmin(np.abs(scan.angles_rad)))
    ranges = np.full(1080, np.inf)
    ranges[ahead - 6 : ahead + 6] = distance_m
    return Scan(10.0, scan.angles_rad, ranges)


@pytest.mark.requirement("SR-AVL-8", kind="example", code=CODE)
def test_an_object_of_unknown_motion_on_the_map_is_counted_in_the_record(
    classifier: Classifier,
) -> None:
    """A new cluster (unknown motion: not yet confirmed) lying on a mapped rack face is
    counted as unknown on the map; off the map it is not."""
    rack = np.array([[2.9, -0.5], [3.3, -0.5], [3.3, 0.5], [2.9, 0.5]])
    inp = CycleInput.standing(_object_ahead(), 10.1, CONFIG, charge_s=0.01)
    mapped = StaticMap.from_parts([rack], 0.05, 0.1)
    elsewhere = StaticMap.from_parts([rack + np.array([0.0, 3.0])], 0.05, 0.1)
    on = Runtime(CONFIG, classifier=classifier, static_map=mapped).step(inp)
    off = Runtime(CONFIG, classifier=classifier, static_map=elsewhere).step(inp)
    assert on.record.inputs["path"]["unknown_on_map"] == 1
    assert off.record.inputs["path"]["unknown_on_map"] == 0


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_the_planner_check_records_its_candidates_and_the_blocked_ones(
    classifier: Classifier,
) -> None:
    config = overridden(CONFIG, {"runtime": {"planner_check": True}})
    out = Runtime(config, classifier=classifier).step(
        CycleInput.standing(_object_ahead(1.0), 10.1, config, charge_s=0.01)
    )
    planner = out.record.inputs["planner"]
    assert set(planner) == {"candidates", "blocked"}
    # one candidate arc per configured speed and yaw rate; an unconfirmed object 1 m ahead
    # (a disc of any direction) blocks more than one of them
    assert planner["candidates"] == config.geometry.n_speeds * config.geometry.n_yaw_rates
    assert 1 < planner["blocked"] <= planner["candidates"]


@pytest.mark.requirement("SR-RUN-2", kind="example", code=CODE)
def test_a_runtime_uses_what_it_is_given_and_the_configured_rest(
    classifier: Classifier, tmp_path: Path
) -> None:
    """Given stopping parameters and a classifier, the runtime and its perception chain use
    those objects; given none, the configuration's (``map.file``'s map among them)."""
    rack = np.array([[2.9, -0.5], [3.3, -0.5], [3.3, 0.5], [2.9, 0.5]])
    site = StaticMap.from_parts([rack], 0.05, 0.1)
    config = overridden(CONFIG, {"map": {"file": str(site.write_nav2(tmp_path / "site.yaml"))}})
    params = replace(StoppingParams.from_config(config), perception_latency_s=0.5)
    given = Runtime(config, params=params, classifier=classifier)
    assert given.params is params
    assert given.classifier is classifier
    assert isinstance(given.perception, Perception)
    assert given.perception.classifier is classifier
    assert given.static_map is not None
    configured = map_from_config(config)
    assert configured is not None
    assert np.array_equal(given.static_map.covered, configured.covered)
    assert given.cycles == 0
    plain = Runtime(CONFIG)
    assert plain.params == StoppingParams.from_config(CONFIG)
    assert plain.static_map is None
