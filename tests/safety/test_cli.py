"""The ``safecase`` command line, run as a real subprocess."""

from __future__ import annotations

import base64
import os
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from rich.console import Console

from evidence.manifest import SIGNATURE, write_manifest
from evidence.run import run_certification
from properties.cli_runner import run_safecase


@pytest.mark.requirement("SR-CFG-1", kind="example")
def test_invalid_config_exits_2_with_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[cluster]\neps_m = -0.15\n")
    done = run_safecase("config", "check", str(bad))
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert lines == [
        f"config error: {bad}: cluster.eps_m = -0.15: Input should be greater than 0; "
        "allowed: a number > 0.0 and <= 2.0"
    ]
    done = run_safecase("certify", "--config", str(bad))
    assert done.returncode == 2
    assert "cluster.eps_m = -0.15" in done.stderr


@pytest.mark.requirement("SR-CFG-1", kind="example")
def test_a_cross_section_rule_is_checked_at_load(tmp_path: Path) -> None:
    unsafe = tmp_path / "unsafe.toml"
    unsafe.write_text("[fusion]\nthermal_only_confidence = 0.9\n")
    done = run_safecase("config", "check", str(unsafe))
    assert done.returncode == 2
    assert done.stderr.strip() == (
        f"config error: {unsafe}: fusion.thermal_only_confidence (0.9) must be below "
        "classify.medium_confidence_min (0.5) so that thermal-only pedestrians get the most "
        "cautious margin tier"
    )


@pytest.mark.requirement("SR-CFG-1", kind="example")
def test_unreadable_configurations_get_one_line_not_a_traceback(tmp_path: Path) -> None:
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b"[cluster]\neps_m = 0.15 # \xe9t\xe9\n")
    nested = tmp_path / "nested.toml"
    nested.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    cases = {
        latin: "not UTF-8 text (byte 25: b'\\xe9')",
        nested: "not valid TOML: nested too deeply",
        Path("/dev/zero"): "cannot read the configuration file: not a regular file",
        tmp_path: "cannot read the configuration file: a folder",
        tmp_path / "missing.toml": "cannot read the configuration file: no such file",
    }
    for path, message in cases.items():
        done = run_safecase("config", "check", str(path), timeout_s=30)
        assert done.returncode == 2, (path, done.stderr)
        assert done.stderr.strip() == f"config error: {path}: {message}", done.stderr
        assert "Traceback" not in done.stderr


def test_config_show_round_trips(tmp_path: Path) -> None:
    shown = run_safecase("config", "show")
    assert shown.returncode == 0
    (tmp_path / "c.toml").write_text(shown.stdout)
    checked = run_safecase("config", "check", str(tmp_path / "c.toml"))
    assert checked.returncode == 0
    assert shown.stdout.splitlines()[0].split()[-1] in checked.stdout


@pytest.mark.requirement("SR-EVD-1", kind="example")
def test_evidence_verify_names_changes_and_wrong_signatures(tmp_path: Path) -> None:
    bundle = tmp_path / "b"
    bundle.mkdir()
    (bundle / "evidence.json").write_text("{}\n")
    (bundle / "report.html").write_text("<html></html>\n")
    key = Ed25519PrivateKey.from_private_bytes(bytes(range(32)))
    write_manifest(bundle, {"config_hash": "x"}, key)
    ok = run_safecase("evidence", "verify", str(bundle))
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert ok.stdout.startswith("OK: 2 files match")
    # No trusted key given: who signed is printed, and said to be untrusted.
    assert "NOT a trusted key" in ok.stdout

    (bundle / "report.html").write_text("<html>changed</html>\n")
    bad = run_safecase("evidence", "verify", str(bundle))
    assert bad.returncode == 1
    assert "FAIL changed: report.html" in bad.stdout

    write_manifest(bundle, {"config_hash": "x"}, key)
    other = Ed25519PrivateKey.from_private_bytes(bytes(range(1, 33)))
    manifest = (bundle / "manifest.json").read_bytes()
    (bundle / SIGNATURE).write_bytes(base64.b64encode(other.sign(manifest)))
    bad = run_safecase("evidence", "verify", str(bundle))
    assert bad.returncode == 1
    assert "signature does not match" in bad.stdout


def test_version_and_help() -> None:
    done = run_safecase("--version")
    assert done.returncode == 0
    assert done.stdout.startswith("safecase ")
    helped = run_safecase("--help")
    assert "certify" in helped.stdout
    assert "evidence" in helped.stdout


def test_run_certification_writes_a_signed_bundle(tmp_path: Path) -> None:
    root = tmp_path / "project"
    (root / "properties").mkdir(parents=True)
    (root / "tests").mkdir()
    (root / "properties" / "test_p.py").write_text(
        "import pytest\n\n@pytest.mark.requirement('SR-EVD-3')\ndef test_a():\n    pass\n"
    )
    (root / "tests" / "test_t.py").write_text("def test_b():\n    assert 1 + 1 == 2\n")
    console = Console(file=open(os.devnull, "w"))  # noqa: SIM115 - closed with the process
    result = run_certification(
        root=root,
        bundle_dir=tmp_path / "bundle",
        config_path=None,
        profile="dev",
        key=tmp_path / "key.pem",
        select=None,
        benchmarks=False,
        console=console,
    )
    assert result.bundle is not None
    assert {t.nodeid for t in result.bundle.tests} == {
        "properties/test_p.py::test_a",
        "tests/test_t.py::test_b",
    }
    # The real catalogue has claimed requirements this tiny project does not evidence.
    assert result.exit_code == 1
    assert "SR-EVD-1" in result.bundle.summary["blocking_requirements"]
    assert (tmp_path / "bundle" / "manifest.json").is_file()
    verified = run_safecase("evidence", "verify", str(tmp_path / "bundle"))
    assert verified.returncode == 0, verified.stdout


@pytest.mark.requirement("SR-EVD-1", kind="example")
def test_certify_refuses_a_bad_signing_key_before_running_anything(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = run_safecase("certify", "--signing-key", str(tmp_path), "--out", str(out))
    assert done.returncode == 2
    assert f"--signing-key {tmp_path}:" in done.stderr
    assert not out.exists()  # refused before any test ran
    inside = out / "key.pem"
    done = run_safecase("certify", "--signing-key", str(inside), "--out", str(out))
    assert done.returncode == 2
    assert "keep the key outside it" in done.stderr
    assert not inside.exists()


COMMANDS = (
    ("run",),
    ("certify",),
    ("train",),
    ("requirements",),
    ("config", "show"),
    ("config", "check"),
    ("sim", "list"),
    ("sim", "show"),
    ("sim", "dataset"),
    ("evidence", "verify"),
    ("audit", "verify"),
    ("audit", "show"),
    ("audit", "tail"),
    ("audit", "replay"),
    ("nav2", "check"),
    ("nav2", "export"),
    ("mcap", "show"),
    ("mcap", "check"),
)


@pytest.mark.parametrize("command", COMMANDS, ids=" ".join)
def test_every_command_help_has_an_example_and_its_exit_codes(command: tuple[str, ...]) -> None:
    from typer.testing import CliRunner

    from evidence.cli.main import app

    done = CliRunner().invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
    assert done.exit_code == 0, done.output
    text = " ".join(done.output.split())
    assert "Example" in text, text[:300]
    assert "Exit codes" in text, text[:300]
    assert f"safecase {' '.join(command)}" in text, text[:300]


# Modules only `run`, `campaign` and `train` need; a light command must not import them.
HEAVY = ("pipeline.perception", "safety.runtime", "scipy.optimize")


def test_a_command_imports_only_what_it_runs() -> None:
    """`safecase config check` and `--version` import no runtime, simulator or scipy; `run`'s
    help does (its module is imported when the command is looked up)."""
    import subprocess
    import sys

    probe = (
        "import sys\n"
        "from typer.testing import CliRunner\n"
        "from evidence.cli.main import app\n"
        "r = CliRunner().invoke(app, sys.argv[1:])\n"
        "assert r.exit_code == 0, r.output\n"
        f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))\n"
    )
    root = Path(__file__).resolve().parents[2]

    def imported(*args: str) -> str:
        done = subprocess.run(
            [sys.executable, "-c", probe, *args], capture_output=True, text=True, cwd=root
        )
        assert done.returncode == 0, done.stderr
        return done.stdout.strip()

    assert imported("config", "check", "examples/source-warehouse.toml") == "[]"
    assert imported("--version") == "[]"
    assert imported("run", "--help") == str(sorted(HEAVY))
