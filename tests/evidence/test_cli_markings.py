"""``safecase run --markings``: the marking localisation beside a closed-loop run (SR-MRK-5)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from properties.cli_runner import run_safecase

CODE = ["evidence/cli/run.py", "pipeline/sources/sim/markings_source.py"]


def _commands(audit: Path) -> list[tuple[str, float]]:
    rows = [json.loads(line) for line in audit.read_text().splitlines()]
    return [
        (r["command"]["action"], r["command"]["speed_mps"]) for r in rows if r["kind"] == "cycle"
    ]


@pytest.mark.requirement("SR-MRK-5", kind="example", code=CODE)
def test_run_with_markings_prints_the_aid_and_decides_as_without_it(tmp_path: Path) -> None:
    runs = {}
    for flag in ("--markings", "--no-markings"):
        audit = tmp_path / f"{flag}.jsonl"
        done = run_safecase(
            "run",
            "--scenario",
            "crossing_pedestrian",
            "--duration",
            "2",
            flag,
            "--no-plot",
            "--audit",
            str(audit),
            cwd=tmp_path,
        )
        assert done.returncode == 0, done.stdout + done.stderr
        runs[flag] = (done.stdout, _commands(audit))
    aided, plain = runs["--markings"], runs["--no-markings"]
    assert "markings: 20 of 20 scans corrected" in aided[0], aided[0]
    assert "markings:" not in plain[0]
    assert aided[1] == plain[1]
    assert len(aided[1]) == 20


@pytest.mark.requirement("SR-MRK-5", kind="example", code=CODE)
def test_markings_with_compare_is_refused(tmp_path: Path) -> None:
    done = run_safecase("run", "--markings", "--compare", "--duration", "1", cwd=tmp_path)
    assert done.returncode == 2
    assert "--markings applies to a simulator run without --compare" in done.stdout + done.stderr
