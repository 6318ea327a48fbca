"""``python -m evidence.durations``: where a suite's time went, from its evidence bundle."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from evidence.durations import WORKER_TIME, by_file, by_kind, worker_s

RAN_AHEAD = {"type": "counts", "name": WORKER_TIME, "values": {"wall s": 61.5}}
TESTS = [
    {"file": "a.py", "kind": "property", "duration_s": 1.5},
    {"file": "b.py", "kind": "campaign", "duration_s": 4.0, "details": [RAN_AHEAD]},
    {"file": "a.py", "kind": "example", "duration_s": 3.0, "details": []},
]


def test_times_are_summed_per_file_and_kind_slowest_first() -> None:
    assert by_file(TESTS) == [("a.py", 4.5, 2), ("b.py", 4.0, 1)]
    assert by_kind(TESTS) == [("campaign", 4.0, 1), ("example", 3.0, 1), ("property", 1.5, 1)]
    assert [worker_s(t) for t in TESTS] == [0.0, 61.5, 0.0]


def test_the_command_prints_the_table_and_refuses_a_folder_without_evidence(
    tmp_path: Path,
) -> None:
    (tmp_path / "evidence.json").write_text(json.dumps({"profile": "ci", "tests": TESTS}))
    run = [sys.executable, "-m", "evidence.durations"]
    done = subprocess.run([*run, str(tmp_path)], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert "ci profile: 3 tests, 8 s in tests" in done.stdout
    assert "| a.py | 4 | 52.9% | 2 | 0 |" in done.stdout
    assert "| b.py | 4 | 47.1% | 1 | 62 |" in done.stdout
    assert "62 s more in workers beside the suite" in done.stdout
    empty = tmp_path / "empty"
    empty.mkdir()
    refused = subprocess.run([*run, str(empty)], capture_output=True, text=True, check=False)
    assert refused.returncode == 2
    assert "empty/evidence.json: not an evidence bundle" in refused.stderr
