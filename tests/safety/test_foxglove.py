"""A run recorded for Foxglove: the MCAP file holds every cycle and agrees with the audit log
record by record (SR-RUN-7)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipeline.config import default_config
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from properties.cli_runner import run_safecase
from safety.foxglove import TOPICS
from safety.foxglove_view import compare_with_audit, cycle_stamps, read_cycle, read_records
from safety.run import run_audited
from safety.runtime import CycleOutput

CODE = [
    "safety/foxglove.py",
    "safety/foxglove_scene.py",
    "safety/foxglove_view.py",
    "safety/run.py",
    "evidence/cli/mcap.py",
]


def _record(tmp: Path, name: str, seed: int) -> tuple[Path, Path, list[CycleOutput]]:
    config = default_config()
    sim = make_simulation(config, name, seed, 3.0)
    mcap, audit = tmp / f"{name}.mcap", tmp / f"{name}.jsonl"
    outs = list(run_audited(config, SimSource(sim), audit_path=audit, recording=mcap))
    return mcap, audit, outs


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, list[CycleOutput]]:
    return _record(tmp_path_factory.mktemp("mcap"), "reversing_forklift_aisle", 1)


def _messages(path: Path, topic: str) -> list[Any]:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    with AnyReader([path], default_typestore=store) as reader:
        chosen = [c for c in reader.connections if c.topic == topic]
        return [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(chosen)]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_recording_agrees_with_the_audit_log_cycle_by_cycle(
    recorded: tuple[Path, Path, list[CycleOutput]], tmp_path: Path
) -> None:
    mcap, audit, outs = recorded
    assert compare_with_audit(mcap, audit) == []
    records = read_records(mcap)
    assert len(records) == len(outs) == len(cycle_stamps(mcap))
    assert [r["command"]["action"] for r in records] == [o.command.action.value for o in outs]
    # Another run's log disagrees, and says where.
    other_mcap, other_audit, _ = _record(tmp_path, "crossing_pedestrian", 2)
    problems = compare_with_audit(mcap, other_audit)
    assert problems
    assert problems[0].startswith("cycle 0:")
    assert compare_with_audit(other_mcap, other_audit) == []


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_every_cycle_shows_what_the_runtime_saw_and_built(
    recorded: tuple[Path, Path, list[CycleOutput]],
) -> None:
    mcap, _, outs = recorded
    per_topic = {topic: _messages(mcap, topic) for topic in TOPICS}
    assert all(len(per_topic[t]) == len(outs) for t in TOPICS), {
        t: len(m) for t, m in per_topic.items()
    }
    for out, scan, cloud, envelopes, grid, tf, command in zip(
        outs,
        per_topic["/scan"],
        per_topic["/perception/points"],
        per_topic["/safety/envelopes"],
        per_topic["/safety/costmap"],
        per_topic["/tf"],
        per_topic["/safety/command"],
        strict=True,
    ):
        detail = out.detail
        assert detail is not None
        assert detail.perceived is not None
        assert detail.inp.scan is not None
        sent = np.nan_to_num(detail.inp.scan.ranges_m, nan=np.inf).astype(np.float32)
        np.testing.assert_array_equal(np.asarray(scan.ranges), sent)
        assert cloud.width == detail.perceived.points.x_m.shape[0]
        assert out.envelopes is not None
        drawn = [m for m in envelopes.markers if m.action == 0]
        assert len(drawn) == out.envelopes.polygons.n
        marked = int(np.count_nonzero(np.asarray(grid.data) > 0))
        assert marked == out.record.inputs["costmap"]["occupied_cells"]
        base = next(t for t in tf.transforms if t.child_frame_id == "base_link")
        assert base.transform.translation.x == pytest.approx(detail.inp.robot_pose[0])
        assert command.twist.linear.x == out.command.speed_mps


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_safecase_run_records_and_mcap_checks_and_draws(tmp_path: Path) -> None:
    done = run_safecase(
        "run", "--scenario", "forklift_pass_by", "--duration", "2", "--no-plot",
        "--mcap", "pass.mcap", "--audit", "pass.jsonl", cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "recording: pass.mcap" in done.stdout
    checked = run_safecase("mcap", "check", "pass.mcap", "--audit", "pass.jsonl", cwd=tmp_path)
    assert checked.returncode == 0, checked.stdout + checked.stderr
    assert "every cycle agrees" in checked.stdout
    shown = run_safecase("mcap", "show", "pass.mcap", "--at", "1.0", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    assert (tmp_path / "pass.png").stat().st_size > 10_000
    assert read_cycle(tmp_path / "pass.mcap", 1.0)["stamp_s"] == pytest.approx(1.0, abs=0.06)
    again = run_safecase("run", "--duration", "1", "--mcap", "pass.mcap", cwd=tmp_path)
    assert again.returncode == 2
    assert "--mcap pass.mcap: exists" in again.stderr
