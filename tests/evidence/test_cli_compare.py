"""``safecase run --compare``: progress vs the oracle, nuisance STOPs, three speeds (SR-AVL-1)."""

from __future__ import annotations

from pathlib import Path

import pytest

from properties.cli_runner import run_safecase

CODE = ["evidence/cli/run.py", "evidence/cli/availability.py", "safety/run_plot.py"]


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_run_compare_prints_progress_against_the_oracle_and_nuisance_stops(
    tmp_path: Path,
) -> None:
    audit = tmp_path / "pj.jsonl"
    done = run_safecase(
        "run",
        "--scenario",
        "pallet_jack_slow",
        "--duration",
        "2",
        "--compare",
        "--audit",
        str(audit),
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    for text in (
        "progress vs oracle",
        "nuisance STOPs",
        "speed given up vs oracle",
        "ours",
        "oracle",
        "baseline",
    ):
        assert text in done.stdout, text
    assert audit.with_suffix(".png").stat().st_size > 10_000
    assert audit.stat().st_size > 0


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (("--emulate", "rplidar"), "--compare applies to simulator runs only"),
        (("--scenario", "pallet_jack_slow", "--scans", "5"), "give its length with --duration"),
    ],
)
def test_run_compare_refuses_what_it_cannot_compare(
    tmp_path: Path, extra: tuple[str, ...], message: str
) -> None:
    done = run_safecase("run", "--compare", *extra, cwd=tmp_path)
    assert done.returncode == 2, done.stdout + done.stderr
    assert message in done.stderr
    assert "Traceback" not in done.stderr
