"""The safecase pytest plugin: requirement markers, evidence capture, the bundle (SR-EVD-*).

Registered through the ``pytest11`` entry point, so every pytest run in safecase's virtual
environment has it. It is inert unless asked for output:

* ``@pytest.mark.requirement("SR-STOP-1", kind="proof", code=["safety/model/stopping.py"])`` links a
  test to requirements; an unknown ID fails the collection of that test's module;
* the session fixture ``evidence`` (or :func:`evidence.record.current`) attaches details;
* Hypothesis statistics, pytest-benchmark results and failures are captured per test;
* ``--safecase-out DIR`` writes evidence.json, report.html, report.md, junit.xml and the
  signed manifest at the end of the session;
* ``--safecase-enforce`` fails the session when a claimed requirement is not SATISFIED.
"""

from __future__ import annotations

import hashlib
import re
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pytest
from hypothesis import settings as hypothesis_settings
from hypothesis.statistics import collector

from evidence.catalogue import EVIDENCE_KINDS, Catalogue, load_catalogue
from evidence.environment import collect_environment, git_state
from evidence.manifest import check_key_outside
from evidence.model import Bundle, EvidenceItem, Outcome, compute_verdicts
from evidence.profiles import active_profile, register_profiles, set_active_profile
from evidence.record import Recorder, current
from evidence.report import write_bundle
from evidence.safety_case import SafetyCase, load_safety_case
from pipeline.classify.model import model_provenance
from pipeline.config import SafecaseConfig, config_hash, load_config
from pipeline.errors import ConfigError, RequirementsError, SafecaseError
from safety.audit.keys import load_or_create_key

register_profiles()

_MAX_TEXT = 20_000


@dataclass
class _State:
    catalogue: Catalogue
    config: SafecaseConfig
    config_path: str | None
    safety_case: SafetyCase | None = None
    started: float = field(default_factory=time.time)
    items: dict[str, EvidenceItem] = field(default_factory=dict)
    stats: dict[str, dict[str, Any]] = field(default_factory=dict)
    reports: dict[str, dict[str, pytest.TestReport]] = field(default_factory=dict)
    benchmarks: dict[str, dict[str, Any]] = field(default_factory=dict)
    bundle_dir: Path | None = None
    bundle: Bundle | None = None
    n_deselected: int = 0


STATE = pytest.StashKey[_State]()
_PREVIOUS_PROFILE = pytest.StashKey[tuple[str, str]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("safecase", "safecase certification evidence")
    group.addoption(
        "--safecase-out",
        metavar="DIR",
        default=None,
        help="write the evidence bundle (evidence.json, report.html, report.md, "
        "junit.xml, signed manifest) into DIR",
    )
    group.addoption(
        "--safecase-config",
        metavar="FILE",
        default=None,
        help="configuration TOML used by the tests (default: built-in defaults)",
    )
    group.addoption(
        "--safecase-requirements",
        metavar="FILE",
        default=None,
        help="requirements catalogue (default: the packaged safety/requirements.toml)",
    )
    group.addoption(
        "--safecase-hazards",
        metavar="FILE",
        default=None,
        help="hazard log and assumptions (default: the packaged safety/hazards.toml, used with "
        "the packaged catalogue only)",
    )
    group.addoption(
        "--safecase-key",
        metavar="FILE",
        default=None,
        help="Ed25519 signing key (PEM); created on first use when missing",
    )
    group.addoption(
        "--safecase-enforce",
        action="store_true",
        default=False,
        help="fail the session when a claimed requirement is not SATISFIED",
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "requirement(*ids, kind=None, code=()): link this test to safety requirement IDs; "
        f"kind is one of {', '.join(EVIDENCE_KINDS)} (inferred when omitted)",
    )
    try:
        catalogue = load_catalogue(config.getoption("safecase_requirements"))
    except RequirementsError as exc:
        raise pytest.UsageError(f"safecase: {exc}") from None
    hazards = config.getoption("safecase_hazards")
    try:
        case = (
            load_safety_case(hazards)
            if hazards or not config.getoption("safecase_requirements")
            else None
        )
    except RequirementsError as exc:
        raise pytest.UsageError(f"safecase: {exc}") from None
    config_path = config.getoption("safecase_config")
    try:
        safecase_config = load_config(config_path)
    except ConfigError as exc:
        raise pytest.UsageError("safecase: " + "\n".join(exc.lines)) from None
    profile = config.getoption("hypothesis_profile", None)
    # Remember the outer profile: a test that runs pytest in-process (pytester) must get its
    # own Hypothesis settings back when the inner session ends.
    config.stash[_PREVIOUS_PROFILE] = (
        active_profile(),
        hypothesis_settings.get_current_profile_name(),
    )
    set_active_profile(profile or hypothesis_settings.get_current_profile_name())
    if _distributed(config) and (
        config.getoption("safecase_out") or config.getoption("safecase_enforce")
    ):
        # Workers would each hold part of the evidence and the bundle would record none.
        raise pytest.UsageError(
            "safecase: evidence cannot be collected under pytest-xdist (-n/--dist): run "
            "without -n, or without --safecase-out/--safecase-enforce"
        )
    config.stash[STATE] = _State(catalogue, safecase_config, config_path, case)


def _distributed(config: pytest.Config) -> bool:
    """True when pytest-xdist will spread the tests over worker processes."""
    if not config.pluginmanager.has_plugin("xdist"):
        return False
    workers = getattr(config.option, "numprocesses", None)
    return bool(workers) or getattr(config.option, "dist", "no") != "no"


def pytest_deselected(items: list[pytest.Item]) -> None:
    """Count deselected tests: a session that leaves any out is a slice of the suite."""
    if items:
        state = items[0].config.stash.get(STATE, None)
        if state is not None:
            state.n_deselected += len(items)


def _selection(session: pytest.Session, state: _State) -> dict[str, Any] | None:
    """What the session selected, or None when it ran the whole suite."""
    keyword = session.config.getoption("keyword", "") or ""
    marks = session.config.getoption("markexpr", "") or ""
    if not (keyword or marks or state.n_deselected):
        return None
    expression = " ".join(
        part for part in (keyword and f"-k {keyword!r}", marks and f"-m {marks!r}") if part
    )
    return {
        "expression": expression or "deselected by a plugin",
        "selected": len(session.items),
        "deselected": state.n_deselected,
    }


def pytest_unconfigure(config: pytest.Config) -> None:
    previous = config.stash.get(_PREVIOUS_PROFILE, None)
    if previous is not None:
        set_active_profile(previous[0])
        hypothesis_settings.load_profile(previous[1])


def pytest_sessionstart(session: pytest.Session) -> None:
    current().push_session()


@pytest.fixture(scope="session")
def evidence() -> Recorder:
    """Attach structured details to the running test's evidence (see evidence.record)."""
    return current()


@pytest.fixture(scope="session")
def safecase_config(pytestconfig: pytest.Config) -> SafecaseConfig:
    """The configuration under test (``--safecase-config`` or the built-in defaults)."""
    return pytestconfig.stash[STATE].config


def _marker_problems(item: pytest.Item, catalogue: Catalogue) -> list[str]:
    problems = []
    for marker in item.iter_markers("requirement"):
        if not marker.args:
            problems.append(f"{item.nodeid}: @requirement needs at least one requirement ID")
        for req_id in marker.args:
            if not isinstance(req_id, str) or req_id not in catalogue:
                problems.append(
                    f"{item.nodeid}: unknown requirement ID {req_id!r} (not in {catalogue.path})"
                )
        kind = marker.kwargs.get("kind")
        if kind is not None and kind not in EVIDENCE_KINDS:
            problems.append(
                f"{item.nodeid}: kind={kind!r} is not one of {', '.join(EVIDENCE_KINDS)}"
            )
        unknown = set(marker.kwargs) - {"kind", "code"}
        if unknown:
            problems.append(f"{item.nodeid}: unknown @requirement arguments {sorted(unknown)}")
    return problems


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector: pytest.Collector) -> Generator[None, Any, None]:
    outcome = yield
    report: pytest.CollectReport = outcome.get_result()
    state = collector.config.stash.get(STATE, None)
    if state is None or report.outcome != "passed":
        return
    problems: list[str] = []
    for node in report.result:
        if isinstance(node, pytest.Item):
            problems.extend(_marker_problems(node, state.catalogue))
    if problems:
        report.outcome = "failed"
        report.longrepr = "safecase requirement markers:\n" + "\n".join(problems)
        report.result = []


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_protocol(item: pytest.Item) -> Generator[None, Any, None]:
    recorder = current()
    recorder.begin(item.nodeid)
    try:
        yield
    finally:
        record = recorder.end()
        state = item.config.stash.get(STATE, None)
        if state is not None:
            state.items[item.nodeid] = _build_item(item, state, record)


@pytest.hookimpl(hookwrapper=True, trylast=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, None]:
    state = item.config.stash.get(STATE, None)
    outer: Callable[[dict[str, Any]], None] | None = collector.value

    def note(stats: dict[str, Any]) -> None:
        if state is not None:
            state.stats[item.nodeid] = _summarise_stats(stats, item)
        if outer is not None:
            outer(stats)

    with collector.with_value(note):  # type: ignore[arg-type]
        yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(
    item: pytest.Item, call: pytest.CallInfo[None]
) -> Generator[None, Any, None]:
    outcome = yield
    report: pytest.TestReport = outcome.get_result()
    state = item.config.stash.get(STATE, None)
    if state is None:
        return
    state.reports.setdefault(item.nodeid, {})[report.when] = report
    if report.when == "call":
        # funcargs are cleared at teardown, so read the benchmark's statistics now.
        bench = _benchmark_detail(item)
        if bench is not None:
            state.benchmarks[item.nodeid] = bench
    if report.when == "call" and report.passed:
        record = current().peek()
        unproved = [
            d
            for d in (record.details if record else [])
            if d["type"] == "smt" and d["required"] and d["verdict"] != "PROVED"
        ]
        if unproved:
            # A test that attaches an obligation and passes anyway must not turn an UNKNOWN or
            # REFUTED verdict into evidence: the obligation itself is the claim.
            report.outcome = "failed"
            report.longrepr = "\n".join(
                f"obligation {d['name']}: {d['verdict']} (only PROVED counts as a proof)"
                for d in unproved
            )


_FALSIFYING_START = re.compile(r"^(Falsifying (explicit )?example|Failing test case)\b")
_BLOB = re.compile(r"@reproduce_failure\([^)]*\)")


def _falsifying_example(text: str) -> str:
    """The falsifying example Hypothesis printed (pytest prefixes such lines with 'E')."""
    lines = [re.sub(r"^E {0,7}", "", line) for line in text.splitlines()]
    for start, line in enumerate(lines):
        if _FALSIFYING_START.match(line):
            block = [line]
            for follow in lines[start + 1 :]:
                if not follow.strip():
                    break
                block.append(follow)
                if follow.rstrip() == ")":
                    break
            return "\n".join(block)
    return ""


def _summarise_stats(stats: dict[str, Any], item: pytest.Item) -> dict[str, Any]:
    counts = {"valid": 0, "invalid": 0, "overrun": 0, "interesting": 0}
    for phase in ("reuse-phase", "generate-phase", "explain-phase"):
        for case in stats.get(phase, {}).get("test-cases", []):
            counts[case["status"]] = counts.get(case["status"], 0) + 1
    current_settings = hypothesis_settings()
    return {
        "examples_run": sum(counts.values()),
        "valid": counts["valid"],
        "invalid": counts["invalid"] + counts["overrun"],
        "failing": counts["interesting"],
        "stopped_because": str(stats.get("stopped-because", "")),
        "profile": active_profile(),
        "max_examples": current_settings.max_examples,
        "seed": (
            "derandomized (derived from the test)"
            if current_settings.derandomize
            else str(item.config.getoption("hypothesis_seed", None) or "random")
        ),
    }


def _benchmark_detail(item: pytest.Item) -> dict[str, Any] | None:
    funcargs = getattr(item, "funcargs", None) or {}
    fixture = funcargs.get("benchmark")
    meta = getattr(fixture, "stats", None)
    stats = getattr(meta, "stats", None)
    if stats is None or not getattr(stats, "data", None):
        return None
    return {
        "type": "benchmark",
        "name": getattr(fixture, "name", item.name),
        "group": getattr(fixture, "group", None) or "",
        "rounds": int(stats.rounds),
        "min_s": float(stats.min),
        "max_s": float(stats.max),
        "mean_s": float(stats.mean),
        "median_s": float(stats.median),
        "stddev_s": float(stats.stddev) if stats.rounds > 1 else 0.0,
        "extra_info": dict(getattr(fixture, "extra_info", {}) or {}),
    }


def _build_item(item: pytest.Item, state: _State, record: Any) -> EvidenceItem:
    reports = state.reports.get(item.nodeid, {})
    outcome: Outcome = "passed"
    message = ""
    longrepr = ""
    duration = sum(r.duration for r in reports.values())
    for when in ("setup", "call", "teardown"):
        report = reports.get(when)
        if report is None:
            continue
        if report.failed:
            outcome = "failed" if when == "call" else "error"
            longrepr = str(report.longreprtext)[-_MAX_TEXT:]
            message = longrepr.strip().splitlines()[-1][:500] if longrepr.strip() else ""
            break
        if report.skipped:
            outcome = "skipped"
            message = _skip_reason(report)
            break
    ids: list[str] = []
    code: list[str] = []
    kind: str | None = None
    for marker in item.iter_markers("requirement"):
        ids.extend(a for a in marker.args if a not in ids)
        code.extend(marker.kwargs.get("code", ()))
        kind = kind or marker.kwargs.get("kind")
    details: list[dict[str, Any]] = list(record.details) if record else []
    for group, values in record.counters.items() if record else []:
        details.append({"type": "counts", "name": group, "values": dict(values)})
    bench = state.benchmarks.get(item.nodeid)
    if bench is not None:
        details.append(bench)
    hyp = state.stats.get(item.nodeid)
    if hyp is not None:
        info = str(getattr(item, "hypothesis_report_information", "")) + "\n" + longrepr
        hyp["falsifying_example"] = _falsifying_example(info)
        blob = _BLOB.search(info)
        hyp["reproduce_blob"] = blob.group(0) if blob else ""
    inferred = (
        kind
        or (record.kind if record else None)
        or ("measurement" if bench is not None else None)
        or ("property" if hyp is not None else "example")
    )
    return EvidenceItem(
        nodeid=item.nodeid,
        file=str(item.path.relative_to(item.config.rootpath))
        if item.path.is_relative_to(item.config.rootpath)
        else str(item.path),
        requirement_ids=ids,
        kind=inferred,
        outcome=outcome,
        duration_s=duration,
        code=code,
        message=message,
        longrepr=longrepr,
        hypothesis=hyp,
        details=details,
    )


def _skip_reason(report: pytest.TestReport) -> str:
    longrepr = report.longrepr
    if isinstance(longrepr, tuple) and len(longrepr) == 3:
        return str(longrepr[2])
    return str(longrepr)


def _provenance(session: pytest.Session, state: _State) -> dict[str, Any]:
    cfg = session.config
    current_settings = hypothesis_settings()
    catalogue_bytes = Path(state.catalogue.path).read_bytes()
    return {
        "config_hash": config_hash(state.config),
        "config_path": state.config_path or "<built-in defaults>",
        "config": state.config.model_dump(mode="json"),
        "catalogue_sha256": hashlib.sha256(catalogue_bytes).hexdigest(),
        "git": git_state(cfg.rootpath),
        "hypothesis_profile": active_profile(),
        "hypothesis_settings": {
            "max_examples": current_settings.max_examples,
            "derandomize": current_settings.derandomize,
            "database": None if current_settings.database is None else "in use",
            "print_blob": current_settings.print_blob,
            "seed": cfg.getoption("hypothesis_seed", None),
        },
        "pytest_args": list(cfg.invocation_params.args),
        "classifier_model": model_provenance(state.config.classify),
        **current().session_provenance,
    }


def build_bundle(session: pytest.Session, exitstatus: int) -> Bundle:
    """Assemble the evidence of this session (used at session end and by tests)."""
    state = session.config.stash[STATE]
    items = list(state.items.values())
    return Bundle(
        created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        profile=active_profile(),
        provenance=_provenance(session, state),
        environment=collect_environment(),
        catalogue_path=state.catalogue.path,
        families=dict(state.catalogue.families),
        requirements=compute_verdicts(state.catalogue, items),
        tests=items,
        session_exit_status=int(exitstatus),
        selection=_selection(session, state),
        safety_case=state.safety_case,
    )


@pytest.hookimpl(trylast=True)
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    state = session.config.stash.get(STATE, None)
    try:
        if state is None:
            return
        out = session.config.getoption("safecase_out")
        enforce = session.config.getoption("safecase_enforce")
        if not out and not enforce:
            return
        bundle = build_bundle(session, exitstatus)
        state.bundle = bundle
        if out:
            key_option = session.config.getoption("safecase_key")
            key_path = Path(key_option) if key_option else None
            state.bundle_dir = Path(out)
            try:
                # A key inside the bundle would be shipped with it (SR-EVD-1).
                check_key_outside(state.bundle_dir, key_path)
                key, _, _ = load_or_create_key(key_path)
                write_bundle(state.bundle_dir, bundle, key)
            except SafecaseError as exc:
                raise pytest.UsageError(f"safecase: {exc}") from None
        if enforce and bundle.summary["blocking_requirements"] and session.exitstatus == 0:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED
    finally:
        current().pop_session()


def pytest_terminal_summary(terminalreporter: Any, config: pytest.Config) -> None:
    state = config.stash.get(STATE, None)
    if state is None or state.bundle is None:
        return
    bundle = state.bundle
    terminalreporter.section("safecase requirements")
    for family, counts in bundle.family_verdicts().items():
        shown = ", ".join(f"{n} {verdict}" for verdict, n in sorted(counts.items()))
        terminalreporter.write_line(f"{family:5s} {bundle.families.get(family, '')}: {shown}")
    blocking = bundle.summary["blocking_requirements"]
    if blocking:
        terminalreporter.write_line(f"not satisfied (claimed): {', '.join(blocking)}", red=True)
    if state.bundle_dir is not None:
        terminalreporter.write_line(f"evidence bundle: {state.bundle_dir / 'report.html'}")
