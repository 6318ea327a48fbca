"""``safecase run --scenario reversing_beeper``: the microphone array in the closed loop
(SR-ACU-5)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from properties.cli_runner import run_safecase

CODE = ["evidence/cli/run.py", "pipeline/sources/sim/acoustic_scenarios.py"]


@pytest.mark.requirement("SR-ACU-5", kind="example", code=CODE)
def test_run_the_beeper_scenario_prints_the_alert_and_slows_for_it(tmp_path: Path) -> None:
    audit = tmp_path / "beep.jsonl"
    done = run_safecase(
        "run",
        "--scenario",
        "reversing_beeper",
        "--duration",
        "6",
        "--no-plot",
        "--audit",
        str(audit),
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert "alert(s) heard (beeper)" in done.stdout, done.stdout
    rows = [json.loads(line) for line in audit.read_text().splitlines()]
    cycles = [r for r in rows if r["kind"] == "cycle"]
    cautious = [r for r in cycles if "acoustic" in " ".join(r["command"]["reasons"])]
    assert cautious, "no cycle was made cautious by the alert"
    assert all(r["command"]["action"] != "PROCEED" for r in cautious)


@pytest.mark.requirement("SR-ACU-5", kind="example", code=CODE)
def test_the_beeper_scenario_is_refused_with_compare(tmp_path: Path) -> None:
    done = run_safecase("run", "--scenario", "reversing_beeper", "--compare", cwd=tmp_path)
    assert done.returncode == 2
    assert "a closed-loop simulator run only" in done.stdout + done.stderr
