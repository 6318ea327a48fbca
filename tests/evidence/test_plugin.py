"""Tests of the evidence plugin itself, on small projects run in-process with pytester."""

from __future__ import annotations

import json
import platform
import re
from pathlib import Path
from typing import Any

import pytest

from evidence.manifest import verify_bundle
from pipeline.config import config_hash, default_config

CATALOGUE = """
schema_version = 1
[families]
X = "Example family"

[[requirement]]
id = "SR-X-1"
family = "X"
status = "claimed"
claim = "Numbers stay small."
source = "test"
evidence_kinds = ["property", "example"]
minimum = { property = 1 }
code = ["m.py"]

[[requirement]]
id = "SR-X-2"
family = "X"
status = "claimed"
claim = "Nobody tests this."
source = "test"
evidence_kinds = ["example"]
minimum = { example = 1 }
code = ["m.py"]

[[requirement]]
id = "SR-X-3"
family = "X"
status = "planned"
claim = "Not built yet."
source = "test"
evidence_kinds = ["example"]
minimum = { example = 1 }
code = ["later.py"]

[[requirement]]
id = "SR-X-4"
family = "X"
status = "claimed"
claim = "An arithmetic fact."
source = "test"
evidence_kinds = ["proof", "example"]
minimum = { proof = 1 }
code = ["m.py"]
"""

FAILING_PROPERTY = """
import pytest
from hypothesis import given, strategies as st

@pytest.mark.requirement("SR-X-1")
@given(st.integers(0, 1000))
def test_small(x):
    assert x < 500
"""

PASSING_SUITE = """
import pytest
from hypothesis import given, strategies as st

@pytest.mark.requirement("SR-X-1")
@given(st.integers(0, 1000))
def test_small(x):
    assert x <= 1000

@pytest.mark.requirement("SR-X-4")
def test_fact(evidence):
    evidence.smt("two-plus-two", "PROVED", "(assert (not (= (+ 2 2) 4)))\\n(check-sat)\\n",
                 solver="hand", time_s=0.0)
    evidence.count("examples", "checked", 3)
    evidence.samples("latency", [0.001, 0.002, 0.003], unit="s")
    evidence.table("t", ["a", "b"], [[1, 2]])
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    evidence.plot("diagonal", fig, caption="a line")
    plt.close(fig)

@pytest.mark.requirement("SR-X-3")
def test_planned_but_tested():
    pass

def test_not_linked():
    pass
"""


def _run(pytester: pytest.Pytester, *args: str) -> tuple[pytest.RunResult, Path]:
    pytester.makefile(".toml", catalogue=CATALOGUE)
    out = pytester.path / "bundle"
    key = pytester.path / "key.pem"
    result = pytester.runpytest(
        "--safecase-requirements=catalogue.toml",
        f"--safecase-out={out}",
        f"--safecase-key={key}",
        "--hypothesis-profile=ci",
        "-p",
        "no:cacheprovider",
        *args,
    )
    return result, out


def _evidence(out: Path) -> dict[str, Any]:
    data: dict[str, Any] = json.loads((out / "evidence.json").read_text())
    return data


def _verdicts(data: dict[str, Any]) -> dict[str, str]:
    return {r["id"]: r["verdict"] for r in data["requirements"]}


@pytest.mark.requirement("SR-EVD-2")
def test_failing_property_makes_requirement_violated_with_falsifying_example(
    pytester: pytest.Pytester,
) -> None:
    pytester.makepyfile(test_m=FAILING_PROPERTY)
    result, out = _run(pytester)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    data = _evidence(out)
    assert _verdicts(data)["SR-X-1"] == "VIOLATED"
    (item,) = [t for t in data["tests"] if t["nodeid"].endswith("test_small")]
    hyp = item["hypothesis"]
    assert hyp["falsifying_example"].startswith(("Falsifying example", "Failing test case"))
    assert "x=500" in hyp["falsifying_example"]
    assert hyp["reproduce_blob"].startswith("@reproduce_failure(")
    assert hyp["failing"] >= 1
    html = (out / "report.html").read_text()
    assert "x=500" in html
    assert "VIOLATED" in html


@pytest.mark.requirement("SR-EVD-2")
def test_verdicts_satisfied_not_evidenced_and_planned(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE)
    result, out = _run(pytester, "--safecase-enforce")
    # Every test passed, but SR-X-2 is claimed and has no evidence: enforce fails the session.
    result.assert_outcomes(passed=4)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    data = _evidence(out)
    assert _verdicts(data) == {
        "SR-X-1": "SATISFIED",
        "SR-X-2": "NOT EVIDENCED",
        "SR-X-3": "PLANNED",
        "SR-X-4": "SATISFIED",
    }
    assert data["summary"]["blocking_requirements"] == ["SR-X-2"]
    assert data["summary"]["requirements"]["PLANNED"] == 1
    planned = next(r for r in data["requirements"] if r["id"] == "SR-X-3")
    assert planned["would_be"] == "SATISFIED"
    kinds = {t["nodeid"].split("::")[-1]: t["kind"] for t in data["tests"]}
    assert kinds == {
        "test_small": "property",
        "test_fact": "proof",
        "test_planned_but_tested": "example",
        "test_not_linked": "example",
    }
    prop = next(t for t in data["tests"] if t["nodeid"].endswith("test_small"))
    assert prop["hypothesis"]["valid"] == 100
    assert prop["hypothesis"]["seed"].startswith("derandomized")
    fact = next(t for t in data["tests"] if t["nodeid"].endswith("test_fact"))
    types = [d["type"] for d in fact["details"]]
    assert types == ["smt", "samples", "table", "plot", "counts"]
    assert len(list((out / "smt").glob("*.smt2"))) == 1
    (png,) = (out / "plots").glob("*.png")
    assert png.read_bytes().startswith(b"\x89PNG")
    assert 'src="data:image/png;base64,' in (out / "report.html").read_text()
    assert "safecase requirements" in result.stdout.str()


@pytest.mark.requirement("SR-EVD-2")
def test_unknown_requirement_id_is_a_collection_error(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_m="""
import pytest

@pytest.mark.requirement("SR-NOPE-1")
def test_x():
    pass
"""
    )
    result, _ = _run(pytester)
    assert result.ret == pytest.ExitCode.INTERRUPTED
    result.stdout.fnmatch_lines(["*ERROR collecting*", "*unknown requirement ID 'SR-NOPE-1'*"])


@pytest.mark.requirement("SR-EVD-2")
def test_unknown_smt_verdict_never_passes(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_m="""
import pytest

@pytest.mark.requirement("SR-X-4")
def test_fact(evidence):
    evidence.smt("hard", "UNKNOWN", "(check-sat)", solver="z3", time_s=1.0)
"""
    )
    result, out = _run(pytester)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["*obligation hard: UNKNOWN (only PROVED counts as a proof)*"])
    assert _verdicts(_evidence(out))["SR-X-4"] == "VIOLATED"


@pytest.mark.requirement("SR-EVD-2")
def test_skipped_evidence_is_not_evidence(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        test_m="""
import pytest

@pytest.mark.requirement("SR-X-2")
def test_x():
    pytest.skip("data folder absent")
"""
    )
    _, out = _run(pytester)
    data = _evidence(out)
    assert _verdicts(data)["SR-X-2"] == "NOT EVIDENCED"
    item = data["tests"][0]
    assert item["outcome"] == "skipped"
    assert "data folder absent" in item["message"]


@pytest.mark.requirement("SR-EVD-1", kind="example")
def test_bundle_tampering_is_detected_and_named(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE)
    _, out = _run(pytester)
    assert verify_bundle(out).ok
    report = out / "report.md"
    original = report.read_bytes()
    report.write_bytes(original[:10] + bytes([original[10] ^ 1]) + original[11:])
    assert verify_bundle(out).problems == ["changed: report.md"]
    report.write_bytes(original)
    (out / "junit.xml").unlink()
    assert verify_bundle(out).problems == ["removed: junit.xml"]


@pytest.mark.requirement("SR-EVD-3")
def test_provenance_records_profile_config_git_and_versions(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE)
    # safecase's own suite asks for its runtime configuration (safecase_runtime in pyproject).
    _, out = _run(pytester, "-o", "safecase_runtime=true")
    data = _evidence(out)
    prov = data["provenance"]
    assert data["profile"] == "ci"
    assert prov["hypothesis_profile"] == "ci"
    assert prov["hypothesis_settings"]["derandomize"] is True
    assert prov["hypothesis_settings"]["database"] is None
    assert prov["config_hash"] == config_hash(default_config())
    assert set(prov["git"]) >= {"commit", "dirty"}
    env = data["environment"]
    assert env["key_packages"]["z3-solver"] != "not installed"
    assert env["python"] == platform.python_version()
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["provenance"]["config_hash"] == prov["config_hash"]


def test_html_report_is_self_contained_with_matrix(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE)
    _, out = _run(pytester)
    html = (out / "report.html").read_text()
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)
    assert "<script" not in html
    assert "Traceability matrix" in html
    for req_id in ("SR-X-1", "SR-X-2", "SR-X-3", "SR-X-4"):
        assert f'id="{req_id}"' in html
    junit = (out / "junit.xml").read_text()
    assert 'name="requirement" value="SR-X-4"' in junit


@pytest.mark.requirement("SR-EVD-2")
def test_a_slice_judges_only_the_requirements_it_touches(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE)
    result, out = _run(pytester, "--safecase-enforce", "-k", "test_small")
    result.assert_outcomes(passed=1)
    # SR-X-2 has no evidence, but the slice does not touch it: the slice passes.
    assert result.ret == pytest.ExitCode.OK
    data = _evidence(out)
    s = data["summary"]
    assert s["scope"] == "slice"
    assert s["judged_requirements"] == ["SR-X-1"]
    assert s["blocking_requirements"] == []
    assert s["certification"] == "SLICE PASS"
    assert data["selection"] == {"expression": "-k 'test_small'", "selected": 1, "deselected": 3}
    assert "A slice of the suite, not a certification" in (out / "report.html").read_text()
    junit = (out / "junit.xml").read_text()
    assert '<property name="certification" value="SLICE PASS"' in junit
    # The whole suite with the same evidence missing is not certified, and junit counts it.
    result, out = _run(pytester, "--safecase-enforce")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    assert _evidence(out)["summary"]["certification"] == "NOT CERTIFIED"
    junit = (out / "junit.xml").read_text()
    assert '<property name="certification" value="NOT CERTIFIED"' in junit
    assert re.search(r'<testsuite name="safecase" tests="5" failures="1"', junit), junit[:400]
    assert '<testcase classname="requirements" name="SR-X-2"' in junit


BENCHMARKED = """
import pytest

@pytest.mark.requirement("SR-X-2")
def test_sum_is_fast(benchmark, evidence):
    evidence.provenance("measured on", "this worker")
    assert benchmark(sum, range(100)) == 4950

def test_not_linked_either():
    pass
"""


def _comparable(data: dict[str, Any]) -> dict[str, Any]:
    """A bundle's evidence without what differs from run to run (times, timings, how many
    rounds a benchmark fitted in its time)."""
    tests = {}
    for test in data["tests"]:
        details = [
            {
                k: v
                for k, v in d.items()
                if not k.endswith("_s") and k not in ("png_base64", "rounds")
            }
            for d in test["details"]
        ]
        tests[test["nodeid"]] = (
            test["outcome"],
            test["kind"],
            test["requirement_ids"],
            test["hypothesis"],
            details,
        )
    return {
        "tests": tests,
        "verdicts": _verdicts(data),
        "selection": data["selection"],
        "certification": data["summary"]["certification"],
    }


@pytest.mark.requirement("SR-EVD-10")
@pytest.mark.parametrize("selection", [(), ("-k", "not test_not_linked_either")])
def test_evidence_under_xdist_equals_the_serial_sessions(
    pytester: pytest.Pytester, selection: tuple[str, ...]
) -> None:
    pytester.makepyfile(test_m=PASSING_SUITE, test_bench=BENCHMARKED)
    serial, serial_out = _run(pytester, "--safecase-enforce", *selection)
    serial_out.rename(pytester.path / "serial")
    (pytester.path / "bundle").mkdir()  # pytest-benchmark writes into an existing folder
    spread, spread_out = _run(
        pytester,
        "--safecase-enforce",
        "-n",
        "2",
        "--dist",
        "loadfile",
        f"--benchmark-json={pytester.path / 'bundle' / 'benchmarks.json'}",
        *selection,
    )
    assert spread.ret == serial.ret == pytest.ExitCode.TESTS_FAILED  # SR-X-2 is not evidenced
    serial_data = _evidence(pytester.path / "serial")
    spread_data = _evidence(spread_out)
    # Both test files ran, one in each worker (loadfile), and the evidence is the serial one's:
    # outcomes, kinds, details (the SMT text, counts, samples, tables, plots, benchmark figures),
    # Hypothesis statistics, the verdicts and the selection.
    assert _comparable(spread_data) == _comparable(serial_data)
    assert len(spread_data["tests"]) == (6 if not selection else 5)
    by_id = {t["nodeid"]: t for t in spread_data["tests"]}
    bench = by_id["test_bench.py::test_sum_is_fast"]
    assert bench["kind"] == "measurement"
    assert [d["type"] for d in bench["details"]] == ["benchmark"]
    assert by_id["test_m.py::test_small"]["hypothesis"]["valid"] > 0
    assert spread_data["provenance"]["measured on"] == "this worker"
    # One bundle, written and signed by the controller; the workers' benchmark parts joined.
    assert verify_bundle(spread_out).ok
    joined = json.loads((spread_out / "benchmarks.json").read_text())
    assert [b["name"] for b in joined["benchmarks"]] == ["test_sum_is_fast"]
    assert not list(spread_out.glob("benchmarks.gw*.json"))
