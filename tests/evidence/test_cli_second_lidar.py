"""``safecase run`` on a robot with a front and a rear scanner (SR-LID-2, SR-LID-4)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from properties.cli_runner import run_safecase

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "front-rear-scanners.toml"
CODE = ["evidence/cli/run.py", "pipeline/sources/sim/second_lidar.py", "safety/run.py"]


@pytest.mark.requirement("SR-LID-2", kind="example", code=CODE)
def test_run_with_the_example_config_renders_and_merges_the_rear_scanner(tmp_path: Path) -> None:
    audit = tmp_path / "overtaking.jsonl"
    done = run_safecase(
        "run",
        "--config",
        str(EXAMPLE),
        "--scenario",
        "tug_overtaking",
        "--duration",
        "2",
        "--no-plot",
        "--audit",
        str(audit),
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "second scanner" in done.stdout
    assert "merged 20" in done.stdout, done.stdout
    cycles = [json.loads(line) for line in audit.read_text().splitlines()]
    parts = [c["inputs"]["second_scan"] for c in cycles if c["kind"] == "cycle"]
    assert len(parts) == 20
    # The tug, behind the robot, is seen by the rear scanner from the first cycle.
    assert all(p["state"] == "merged" for p in parts)
    assert parts[0]["n_points"] > 0
