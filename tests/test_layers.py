"""The layer contracts hold, and break when someone imports upwards, imports the command line
or closes an import cycle (the import-linter contracts in pyproject.toml)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("pipeline", "safety", "evidence", "properties")
LINT_IMPORTS = Path(sys.executable).with_name("lint-imports")


@pytest.fixture(scope="module")
def tree(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A copy of the four packages and pyproject.toml, to break on purpose."""
    root = tmp_path_factory.mktemp("tree")
    for package in PACKAGES:
        shutil.copytree(
            ROOT / package, root / package, ignore=shutil.ignore_patterns("__pycache__", "models")
        )
    shutil.copy(ROOT / "pyproject.toml", root / "pyproject.toml")
    return root


def _lint(root: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=str(root))
    return subprocess.run(
        [str(LINT_IMPORTS), "--no-cache"],
        cwd=root,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def _with_line(path: Path, line: str) -> str:
    original = path.read_text()
    path.write_text(original + "\n" + line + "\n")
    return original


@pytest.mark.parametrize(
    ("module", "line", "broken"),
    [
        ("pipeline/points.py", "import safety.runtime  # noqa", "pipeline < safety < evidence"),
        ("safety/runtime.py", "import evidence.report  # noqa", "pipeline < safety < evidence"),
        ("properties/smt.py", "import evidence.cli.main  # noqa", "is imported by nothing"),
        ("pipeline/types/core.py", "import pipeline.features  # noqa", "no import cycle"),
    ],
)
def test_a_contract_breaks_on_a_forbidden_import(
    tree: Path, module: str, line: str, broken: str
) -> None:
    clean = _lint(tree)
    assert clean.returncode == 0, clean.stdout + clean.stderr
    original = _with_line(tree / module, line)
    try:
        done = _lint(tree)
    finally:
        (tree / module).write_text(original)
    assert done.returncode == 1, done.stdout
    verdicts = [ln for ln in done.stdout.splitlines() if ln.endswith(("KEPT", "BROKEN"))]
    assert [ln for ln in verdicts if ln.endswith("BROKEN")] == [
        ln for ln in verdicts if broken in ln
    ], verdicts
