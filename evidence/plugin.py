"""The safecase pytest plugin: requirement markers, evidence capture, the bundle (SR-EVD-*).

Registered through the ``pytest11`` entry point, so pytest loads it wherever safecase is
installed; it acts only for a project that asks (evidence.plugin_settings, docs/plugin.md):
naming a requirements catalogue (ini ``safecase_catalogue`` or ``--safecase-requirements``)
activates it. Inactive, it only registers the ``requirement`` marker (SR-EVD-7). Active:

* ``@pytest.mark.requirement("SR-STOP-1", kind="proof", code=["safety/model/stopping.py"])`` links a
  test to requirements; an ID not in the catalogue fails the collection of that test's module;
* the session fixture ``evidence`` (or :func:`evidence.record.current`) attaches details;
* Hypothesis statistics, pytest-benchmark results and failures are captured per test;
* ``--safecase-out DIR`` writes evidence.json, report.html, report.md, junit.xml and the
  signed manifest at the end of the session, with the provenance of the project under test
  (SR-EVD-8); safecase's own configuration and model only when asked (``safecase_runtime``);
* ``--safecase-enforce`` fails the session when a claimed requirement is not SATISFIED.

Safecase's runtime (configuration, classifier, safety case) is imported only when used, so the
plugin stays light in another project's test run.
"""

from __future__ import annotations

import hashlib
import time
from collections.abc import Callable, Generator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest
from hypothesis import settings as hypothesis_settings
from hypothesis.statistics import collector

from evidence.catalogue import EVIDENCE_KINDS, Catalogue, load_catalogue
from evidence.environment import collect_environment, git_state, project_provenance
from evidence.plugin_capture import benchmark_detail, build_item, summarise_stats
from evidence.plugin_settings import PluginSettings, add_options, resolve_settings
from evidence.plugin_xdist import (
    Gatherer,
    attach,
    join_benchmark_parts,
    restore_benchmarks,
    worker_id,
)
from evidence.profiles import active_profile, register_profiles, set_active_profile
from evidence.record import Recorder, current
from pipeline.compat import UTC
from pipeline.errors import ConfigError, EvidenceError, RequirementsError, SafecaseError

if TYPE_CHECKING:
    from evidence.model import Bundle, EvidenceItem
    from evidence.safety_case import SafetyCase
    from pipeline.config import SafecaseConfig

register_profiles()


@dataclass
class _State:
    settings: PluginSettings
    catalogue: Catalogue
    project: dict[str, Any]
    safety_case: SafetyCase | None = None
    started: float = field(default_factory=time.time)
    items: dict[str, EvidenceItem] = field(default_factory=dict)
    stats: dict[str, dict[str, Any]] = field(default_factory=dict)
    reports: dict[str, dict[str, pytest.TestReport]] = field(default_factory=dict)
    benchmarks: dict[str, dict[str, Any]] = field(default_factory=dict)
    bundle_dir: Path | None = None
    bundle: Bundle | None = None
    n_deselected: int = 0

    def take(self, item: EvidenceItem, provenance: dict[str, Any], deselected: int) -> None:
        """Add a test's evidence that an xdist worker sent (evidence.plugin_xdist)."""
        self.items[item.nodeid] = item
        self.n_deselected = max(self.n_deselected, deselected)
        current().session_provenance.update(provenance)


STATE = pytest.StashKey[_State]()
_RUNTIME_CONFIG = pytest.StashKey["SafecaseConfig"]()
_PREVIOUS_PROFILE = pytest.StashKey[tuple[str, str]]()


def pytest_addoption(parser: pytest.Parser) -> None:
    add_options(parser)


def _runtime_config(config: pytest.Config) -> SafecaseConfig:
    """Safecase's configuration under test (``--safecase-config`` or the built-in defaults),
    loaded once per session; a bad file is a usage error."""
    loaded = config.stash.get(_RUNTIME_CONFIG, None)
    if loaded is None:
        from pipeline.config import load_config

        try:
            loaded = load_config(config.getoption("safecase_config"))
        except ConfigError as exc:
            raise pytest.UsageError("safecase: " + "\n".join(exc.lines)) from None
        config.stash[_RUNTIME_CONFIG] = loaded
    return loaded


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "requirement(*ids, kind=None, code=()): link this test to safety requirement IDs; "
        f"kind is one of {', '.join(EVIDENCE_KINDS)} (inferred when omitted)",
    )
    settings = resolve_settings(config)
    if settings is None:
        return
    try:
        catalogue = load_catalogue(settings.catalogue, settings.id_pattern)
        case = None
        if settings.hazards is not None:
            from evidence.safety_case import load_safety_case

            case = load_safety_case(settings.hazards)
        project = project_provenance(
            settings.root,
            name=settings.project_name,
            version=settings.project_version,
            files=settings.provenance_files,
        )
    except (RequirementsError, EvidenceError) as exc:
        raise pytest.UsageError(f"safecase: {exc}") from None
    if settings.config_path is not None:
        _runtime_config(config)  # a bad --safecase-config fails now, not in the first test
    profile = config.getoption("hypothesis_profile", None)
    # Remember the outer profile: a test that runs pytest in-process (pytester) must get its
    # own Hypothesis settings back when the inner session ends.
    config.stash[_PREVIOUS_PROFILE] = (
        active_profile(),
        hypothesis_settings.get_current_profile_name(),
    )
    set_active_profile(profile or hypothesis_settings.get_current_profile_name())
    state = _State(settings, catalogue, project, case)
    config.stash[STATE] = state
    if worker_id(config) is None:
        config.pluginmanager.register(Gatherer(state.take), "safecase-xdist-gatherer")


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
        # under xdist the controller collects nothing: the tests it heard of were selected
        "selected": len(session.items) or len(state.items),
        "deselected": state.n_deselected,
    }


def pytest_unconfigure(config: pytest.Config) -> None:
    previous = config.stash.get(_PREVIOUS_PROFILE, None)
    if previous is not None:
        set_active_profile(previous[0])
        hypothesis_settings.load_profile(previous[1])


def pytest_sessionstart(session: pytest.Session) -> None:
    current().push_session()
    if session.config.stash.get(STATE, None) is not None:
        restore_benchmarks(session.config)


@pytest.fixture(scope="session")
def evidence() -> Recorder:
    """Attach structured details to the running test's evidence (see evidence.record)."""
    return current()


@pytest.fixture(scope="session")
def safecase_config(pytestconfig: pytest.Config) -> SafecaseConfig:
    """Safecase's configuration under test (``--safecase-config`` or the built-in defaults)."""
    return _runtime_config(pytestconfig)


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
        # an xdist worker built the item with the teardown report (pytest_runtest_makereport)
        if state is not None and worker_id(item.config) is None:
            state.items[item.nodeid] = build_item(
                item,
                state.reports.get(item.nodeid, {}),
                record,
                state.benchmarks.get(item.nodeid),
                state.stats.get(item.nodeid),
            )


@pytest.hookimpl(hookwrapper=True, trylast=True)
def pytest_runtest_call(item: pytest.Item) -> Generator[None, Any, None]:
    state = item.config.stash.get(STATE, None)
    outer: Callable[[dict[str, Any]], None] | None = collector.value

    def note(stats: dict[str, Any]) -> None:
        if state is not None:
            state.stats[item.nodeid] = summarise_stats(stats, item)
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
    if report.when == "teardown" and worker_id(item.config) is not None:
        # The teardown report is a test's last: it carries the evidence to the controller.
        built = build_item(
            item,
            state.reports[item.nodeid],
            current().peek(),
            state.benchmarks.get(item.nodeid),
            state.stats.get(item.nodeid),
        )
        state.items[item.nodeid] = built
        attach(report, built, current().session_provenance, state.n_deselected)
    if report.when == "call":
        # funcargs are cleared at teardown, so read the benchmark's statistics now.
        bench = benchmark_detail(item)
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


def _provenance(session: pytest.Session, state: _State) -> dict[str, Any]:
    """Where this evidence comes from: the project under test and its tree, the catalogue,
    Hypothesis and pytest; safecase's configuration and classifier model only when the
    settings ask for them (``runtime``, SR-EVD-8)."""
    cfg = session.config
    current_settings = hypothesis_settings()
    catalogue_bytes = Path(state.catalogue.path).read_bytes()
    provenance: dict[str, Any] = {
        "project": state.project,
        "catalogue_sha256": hashlib.sha256(catalogue_bytes).hexdigest(),
        "id_pattern": state.catalogue.id_pattern,
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
    }
    if state.settings.runtime:
        from pipeline.classify.model import model_provenance
        from pipeline.config import config_hash

        runtime = _runtime_config(cfg)
        provenance |= {
            "config_hash": config_hash(runtime),
            "config_path": state.settings.config_path or "<built-in defaults>",
            "config": runtime.model_dump(mode="json"),
            "classifier_model": model_provenance(runtime.classify),
        }
    return provenance | current().session_provenance


def build_bundle(session: pytest.Session, exitstatus: int) -> Bundle:
    """Assemble the evidence of this session (used at session end and by tests)."""
    from evidence.model import Bundle, compute_verdicts

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
        settings = state.settings
        if settings.out is None and not settings.enforce:
            return
        if worker_id(session.config) is not None:
            return  # the controller writes the bundle from what the workers sent
        join_benchmark_parts(session.config)
        bundle = build_bundle(session, exitstatus)
        state.bundle = bundle
        if settings.out is not None:
            from evidence.manifest import check_key_outside
            from evidence.report import write_bundle
            from safety.audit.keys import load_or_create_key

            state.bundle_dir = settings.out
            try:
                # A key inside the bundle would be shipped with it (SR-EVD-1).
                check_key_outside(state.bundle_dir, settings.key)
                key, _, _ = load_or_create_key(settings.key)
                write_bundle(state.bundle_dir, bundle, key)
            except SafecaseError as exc:
                raise pytest.UsageError(f"safecase: {exc}") from None
        if settings.enforce and bundle.summary["blocking_requirements"] and session.exitstatus == 0:
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
