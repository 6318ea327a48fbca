"""``safecase nav2 check|export`` on the command line: output and exit codes (SR-NAV-4)."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from evidence.cli.main import app
from properties.cli_runner import run_safecase

ROOT = Path(__file__).resolve().parents[3]
TUTORIAL = str(ROOT / "examples" / "nav2" / "tutorial.yaml")
SMALL = str(ROOT / "examples" / "nav2" / "small-robot.toml")
CODE = ["evidence/cli/nav2.py"]


def _run(*args: str) -> tuple[int, str]:
    done = CliRunner().invoke(app, list(args), env={"COLUMNS": "200"})
    return done.exit_code, done.output


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_bad_input_is_one_line_and_exit_2_never_a_traceback(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        'collision_monitor:\n  ros__parameters:\n    polygons: ["Stop"]\n'
        '    observation_sources: ["scan"]\n    Stop:\n      type: "polygon"\n'
        '      action_type: "stop"\n      points: "[[0.4, 0.3], [0.4]]"\n'
    )
    done = run_safecase("nav2", "check", str(bad), timeout_s=120)
    assert done.returncode == 2
    assert done.stderr.strip().splitlines() == [
        "error: collision_monitor.Stop.points = '[[0.4, 0.3], [0.4]]': allowed: \"[[x, y], [x, "
        'y], ...]" with at least 3 vertices, or a flat list [x1, y1, x2, y2, ...]'
    ]
    done = run_safecase("nav2", "check", TUTORIAL, "--latency", "fast", timeout_s=120)
    assert done.returncode == 2
    assert done.stderr.strip() == "error: --latency 'fast': allowed: nav2 | project"
    assert "Traceback" not in done.stderr


def test_check_prints_the_verdicts_and_exits_1_on_a_refuted_zone() -> None:
    code, text = _run("nav2", "check", TUTORIAL, "--config", SMALL, "--latency", "project")
    assert code == 1
    assert "PolygonStop (forward): in use for every forward speed; counterexample v_mps" in text
    assert "largest safe speed 0.402 m/s (proved)" in text
    assert "verdict: REFUTED (exit 1)" in text


def test_export_writes_a_file_that_check_proves(tmp_path: Path) -> None:
    target = tmp_path / "zones.yaml"
    code, text = _run("nav2", "export", "--out", str(target))
    assert (code, text.strip()) == (0, f"wrote {target}")
    code, text = _run("nav2", "check", str(target))
    assert code == 0, text
    assert "verdict: PROVED (exit 0)" in text
    code, text = _run("nav2", "check", str(target), "--max-speed", "1.2")
    assert code == 1, text
    code, text = _run("nav2", "check", str(target), "--max-speed", "-1")
    assert (code, text.strip()) == (2, "error: --max-speed -1.0: allowed: a number in [0, 100]")


def test_a_zone_shaped_at_run_time_exits_3(tmp_path: Path) -> None:
    path = tmp_path / "dynamic.yaml"
    path.write_text(
        'collision_monitor:\n  ros__parameters:\n    polygons: ["Stop"]\n'
        '    observation_sources: ["scan"]\n    Stop:\n      type: "polygon"\n'
        '      action_type: "stop"\n      polygon_sub_topic: "zone"\n'
    )
    code, text = _run("nav2", "check", str(path))
    assert code == 3, text
    assert "verdict: UNKNOWN (exit 3)" in text
