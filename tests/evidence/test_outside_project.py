"""Another project adopts the evidence plugin: its own catalogue, ID pattern and provenance.

Each test builds a tiny outside project with pytester, the worked example of docs/plugin.md
(examples/plugin-project: a robot team's navigation library with its own pyproject.toml,
requirements catalogue, configuration file and tests), and runs pytest on it as that team's CI
would.
"""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from evidence.manifest import verify_bundle

_QUIET = ("-p", "no:cacheprovider")
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "plugin-project"


def _outside_project(pytester: pytest.Pytester, pyproject_edit: tuple[str, str] = ("", "")) -> None:
    """The documented example project, copied into the pytester folder (docs/plugin.md)."""
    shutil.copytree(EXAMPLE, pytester.path, dirs_exist_ok=True)
    if pyproject_edit[0]:
        pyproject = pytester.path / "pyproject.toml"
        text = pyproject.read_text()
        assert pyproject_edit[0] in text
        pyproject.write_text(text.replace(*pyproject_edit))


def _git_commit(root: Path) -> str:
    def git(*args: str) -> str:
        done = subprocess.run(
            ["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args],
            cwd=root,
            capture_output=True,
            text=True,
            check=True,
        )
        return done.stdout.strip()

    git("init", "-q")
    git("add", "-A")
    git("commit", "-q", "-m", "navigation library")
    return git("rev-parse", "HEAD")


def _evidence(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / "evidence.json").read_text())
    return data


@pytest.mark.requirement(
    "SR-EVD-7",
    "SR-EVD-8",
    kind="example",
    code=["evidence/plugin.py", "evidence/plugin_settings.py", "evidence/environment.py"],
)
def test_an_outside_project_is_certified_with_its_own_catalogue_and_provenance(
    pytester: pytest.Pytester,
) -> None:
    _outside_project(pytester)
    commit = _git_commit(pytester.path)
    out, key = pytester.path.parent / "nav-bundle", pytester.path.parent / "nav-key.pem"
    result = pytester.runpytest(
        f"--safecase-out={out}", f"--safecase-key={key}", "--safecase-enforce", *_QUIET
    )
    result.assert_outcomes(passed=2)
    assert result.ret == pytest.ExitCode.OK
    data = _evidence(out)
    assert {r["id"]: r["verdict"] for r in data["requirements"]} == {
        "NAV-BRK-001": "SATISFIED",
        "NAV-BRK-002": "SATISFIED",
    }
    assert data["summary"]["certification"] == "CERTIFIED"
    prov = data["provenance"]
    robot_sha = hashlib.sha256((EXAMPLE / "config" / "robot.yaml").read_bytes()).hexdigest()
    assert prov["project"] == {
        "name": "forklift-nav",
        "version": "2.3.1",
        "root": str(pytester.path),
        "files": {"config/robot.yaml": robot_sha},
    }
    assert prov["git"]["commit"] == commit
    assert prov["git"]["dirty"] is False
    assert prov["id_pattern"] == "NAV-(?P<family>[A-Z]+)-[0-9]{3}"
    catalogue = pytester.path / "safety" / "nav-requirements.toml"
    assert prov["catalogue_sha256"] == hashlib.sha256(catalogue.read_bytes()).hexdigest()
    # safecase's own configuration and classifier model are not this project's provenance.
    assert not {"config_hash", "config", "config_path", "classifier_model"} & set(prov)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["provenance"]["project"]["files"] == {"config/robot.yaml": robot_sha}
    assert verify_bundle(out).ok
    assert "forklift-nav 2.3.1" in (out / "report.md").read_text()


@pytest.mark.requirement("SR-EVD-7", kind="example", code=["evidence/catalogue.py"])
def test_the_project_id_pattern_is_enforced_on_catalogue_and_markers(
    pytester: pytest.Pytester,
) -> None:
    _outside_project(pytester)
    # A marker naming an ID of the right shape that the catalogue lacks: a collection error.
    (pytester.path / "tests" / "test_extra.py").write_text(
        "import pytest\n\n@pytest.mark.requirement('NAV-BRK-009')\ndef test_x():\n    pass\n"
    )
    result = pytester.runpytest(*_QUIET)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    result.stdout.fnmatch_lines(["*unknown requirement ID 'NAV-BRK-009'*"])
    # safecase's own ID shape is not this project's: the catalogue is refused as a whole.
    result = pytester.runpytest(*_QUIET, "-o", "safecase_id_pattern=SR-(?P<family>[A-Z]+)-[0-9]+")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert (
        "'NAV-BRK-001' does not match the ID pattern 'SR-(?P<family>[A-Z]+)-[0-9]+'"
        in result.stderr.str()
    )
    # An ID whose family group disagrees with its family.
    result = pytester.runpytest(*_QUIET, "-o", "safecase_id_pattern=(?P<family>NAV)-BRK-[0-9]{3}")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["*'NAV-BRK-001' must carry its family 'BRK'*"])
    result = pytester.runpytest(*_QUIET, "-o", "safecase_id_pattern=NAV-([A-Z]+")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert "ID pattern 'NAV-([A-Z]+' is not a regular expression" in result.stderr.str()


@pytest.mark.requirement("SR-EVD-8", kind="example", code=["evidence/environment.py"])
def test_a_listed_provenance_file_that_is_missing_is_refused(pytester: pytest.Pytester) -> None:
    _outside_project(pytester, ('["config/*.yaml"]', '["config/*.yml"]'))
    result = pytester.runpytest(f"--safecase-out={pytester.path.parent / 'b'}", *_QUIET)
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    assert result.stderr.lines[0].startswith(
        "ERROR: safecase: provenance file 'config/*.yml' matches no file under "
    )


INACTIVE_TEST = """
import sys

import pytest


@pytest.mark.requirement("ANYTHING-1")
def test_marker_and_fixture_are_harmless(evidence):
    evidence.note("dropped: the plugin is inactive")
    # The inactive plugin brought none of safecase's runtime into this run.
    heavy = {"pipeline.config", "pipeline.classify.model", "evidence.safety_case", "xgboost"}
    assert not heavy & set(sys.modules)
"""


@pytest.mark.requirement("SR-EVD-7", kind="example", code=["evidence/plugin_settings.py"])
def test_without_a_catalogue_the_plugin_only_registers_the_marker(
    pytester: pytest.Pytester,
) -> None:
    pytester.makefile(
        ".toml", pyproject='[tool.pytest.ini_options]\naddopts = ["--strict-markers"]\n'
    )
    pytester.makepyfile(test_plain=INACTIVE_TEST)
    # A fresh interpreter: what the plugin imports is seen in sys.modules.
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)
    assert "safecase requirements" not in result.stdout.str()
    assert not list(pytester.path.rglob("evidence.json"))
    # Asking for output without naming a catalogue is a one-line usage error.
    result = pytester.runpytest(f"--safecase-out={pytester.path / 'b'}", "-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(
        ["ERROR: safecase: --safecase-out needs a requirements catalogue: set safecase_catalogue*"]
    )
