"""Which modules are mutated and which tests claim each (SR-EVD-5, SR-EVD-6).

:data:`TARGETS` is every module of ``safety/`` and the core per-cycle stages; the tests that
claim a module (:func:`select_tests`) are the test files under ``tests/`` and ``properties/``
that import it or name its path; :func:`left_out` names the campaign and measurement tests
that mutants are not run against: closed-loop campaigns take tens of seconds each, and a
timing measurement that fails on a loaded machine would count as a kill; leaving them out can
only lower a score, never raise it.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

__all__ = [
    "EXCLUDED_TESTS",
    "LEFT_OUT_FIXTURES",
    "LEFT_OUT_KINDS",
    "LEFT_OUT_TESTS",
    "TARGETS",
    "Target",
    "left_out",
    "select_tests",
]

TEST_ROOTS: tuple[str, ...] = ("tests", "properties")
# Test files never selected, with why: they run no code of the module they mention.
EXCLUDED_TESTS: Mapping[str, str] = {
    "tests/test_layers.py": "checks import-linter contracts on a copy of the packages' sources",
    "properties/test_mutation_score.py": "reads the committed mutation results of the modules",
}


@dataclass(frozen=True, slots=True)
class Target:
    """One module to mutate; ``functions`` limits it to those top-level functions (empty: all).

    ``group`` is ``"safety"`` for a module of ``safety/`` (claimed under SR-EVD-5 once measured
    at the 95 % target, else shown under SR-EVD-6) and ``"stages"`` for a per-cycle pipeline
    stage (SR-EVD-6).
    """

    path: str
    group: Literal["safety", "stages"]
    functions: tuple[str, ...] = ()

    @property
    def dotted(self) -> str:
        """The module's import name (``safety.model.monitors``)."""
        return self.path.removesuffix(".py").replace("/", ".")

    @property
    def slug(self) -> str:
        """File-name form of the path (``safety__model__monitors``)."""
        return self.path.removesuffix(".py").replace("/", "__")


# Mutated first (cheap, central), in this order; every other module of safety/ follows.
_FIRST: tuple[str, ...] = (
    "model/freshness.py",
    "model/stopping.py",
    "model/readings.py",
    "model/governor.py",
    "model/monitors.py",
    "model/decision.py",
    "model/braking.py",
)


def _safety_targets() -> tuple[Target, ...]:
    """Every module of ``safety/`` (a module added later is a target, shown "not measured")."""
    package = Path(__file__).resolve().parents[1] / "safety"
    found = sorted(
        p.relative_to(package).as_posix()
        for p in package.rglob("*.py")
        if p.name != "__init__.py" and "__pycache__" not in p.parts
    )
    names = [*_FIRST, *(name for name in found if name not in _FIRST)]
    return tuple(Target(f"safety/{name}", "safety") for name in names)


TARGETS: tuple[Target, ...] = (
    *_safety_targets(),
    Target("pipeline/cluster/dbscan.py", "stages"),
    Target("pipeline/track/kalman.py", "stages"),
    Target("pipeline/track/associate.py", "stages"),
    Target("pipeline/track/lifecycle.py", "stages"),
    Target("pipeline/track/tracker.py", "stages"),
    Target("pipeline/track/metrics.py", "stages"),
    Target("pipeline/predict.py", "stages"),
    Target("pipeline/static_map.py", "stages"),
    # The drivers' frame checks only: checksums, check bits, sync nibbles.
    Target(
        "pipeline/sources/serial/rplidar.py",
        "stages",
        ("encode_request", "parse_request", "node_validity", "decode_nodes"),
    ),
    Target(
        "pipeline/sources/serial/rplidar_capsule.py",
        "stages",
        ("capsule_validity", "_start", "_with_checksum", "decode_capsule"),
    ),
    Target(
        "pipeline/sources/serial/scip.py",
        "stages",
        ("checksum", "with_checksum", "line_ok", "encoded_line_ok", "decode_info_lines"),
    ),
)


# -- which tests claim a module ------------------------------------------------------------


def _test_files(root: Path) -> list[Path]:
    files: list[Path] = []
    for top in TEST_ROOTS:
        files.extend(sorted((root / top).rglob("test_*.py")))
    return files


def _claims(tree: ast.Module, target: Target) -> bool:
    """True when the parsed test file imports ``target`` or names its path in a string."""
    dotted = target.dotted
    parent, _, leaf = dotted.rpartition(".")
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            if any(alias.name == dotted for alias in node.names):
                return True
        elif isinstance(node, ast.ImportFrom) and node.level == 0:
            if node.module == dotted:
                return True
            if node.module == parent and any(alias.name == leaf for alias in node.names):
                return True
        elif isinstance(node, ast.Constant) and node.value == target.path:
            return True
    return False


def select_tests(target: Target, root: Path) -> list[str]:
    """Test files (paths relative to ``root``, sorted) that claim ``target``.

    A file claims a module when it imports it (``import a.b``, ``from a.b import x``,
    ``from a import b``) or holds its path as a string (``code=["safety/model/governor.py"]``,
    a ``CODE`` list). Files in :data:`EXCLUDED_TESTS` are never selected.
    """
    selected = []
    for file in _test_files(root):
        relative = file.relative_to(root).as_posix()
        if relative in EXCLUDED_TESTS:
            continue
        tree = _parsed(file)
        if tree is None:  # not valid Python (being edited?): judged by its text
            text = file.read_text(encoding="utf-8", errors="replace")
            claims = target.path in text or target.dotted in text
        else:
            claims = _claims(tree, target)
        if claims:
            selected.append(relative)
    return selected


LEFT_OUT_KINDS: frozenset[str] = frozenset({"campaign", "measurement"})

# Fixtures whose tests mutants are not run against, with why.
LEFT_OUT_FIXTURES: Mapping[str, str] = {
    "client": "a Dask LocalCluster: its workers are processes of their own that mutmut's "
    "per-mutant fork does not reach, and a cluster started in a forked child can hang, which "
    "mutmut would count as a kill (a timeout)",
}

# Tests whose body starts a Dask cluster in the test's own process (the campaign command run in
# process with its workers, the availability campaign on a LocalCluster), with why.
_IN_PROCESS_CLUSTER = (
    "starts a Dask LocalCluster in the test's own process, inside mutmut's forked child, where "
    "it can hang; mutmut then counts the mutant as killed (a timeout) whatever it changed"
)
LEFT_OUT_TESTS: Mapping[str, str] = {
    "tests/safety/test_campaign.py::test_the_command_runs_reports_and_resumes": (
        _IN_PROCESS_CLUSTER
    ),
    "tests/safety/test_campaign.py::test_ctrl_c_keeps_the_finished_runs_and_says_how_to_resume": (
        _IN_PROCESS_CLUSTER
    ),
    "tests/safety/test_availability_workers.py::"
    "test_two_workers_give_the_same_comparisons_in_the_same_order": _IN_PROCESS_CLUSTER,
}


def _marker_kind(decorator: ast.expr) -> str | None:
    """The ``kind=`` of a ``@pytest.mark.requirement(...)`` decorator, else None."""
    if not isinstance(decorator, ast.Call):
        return None
    func = decorator.func
    if not (isinstance(func, ast.Attribute) and func.attr == "requirement"):
        return None
    for keyword in decorator.keywords:
        if keyword.arg == "kind" and isinstance(keyword.value, ast.Constant):
            return str(keyword.value.value)
    return None


def left_out(tests: Sequence[str], root: Path) -> list[str]:
    """Node IDs (``file::test``) of the tests in ``tests`` that mutants are not run against:
    those marked ``kind="campaign"`` or ``kind="measurement"`` (long, or timing-dependent),
    those asking for a fixture of :data:`LEFT_OUT_FIXTURES` and those of
    :data:`LEFT_OUT_TESTS`."""
    ids = []
    for name in tests:
        tree = _parsed(root / name)
        for node in tree.body if tree is not None else []:
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            kinds = {_marker_kind(d) for d in node.decorator_list}
            fixtures = {arg.arg for arg in node.args.args}
            node_id = f"{name}::{node.name}"
            long_or_timed = bool(kinds & LEFT_OUT_KINDS)
            if long_or_timed or fixtures & LEFT_OUT_FIXTURES.keys() or node_id in LEFT_OUT_TESTS:
                ids.append(node_id)
    return ids


_PARSED: dict[Path, tuple[tuple[int, int], ast.Module | None]] = {}


def _parsed(file: Path) -> ast.Module | None:
    """The file's syntax tree (None when it is not valid Python), parsed once per content."""
    stat = file.stat()
    stamp = (stat.st_mtime_ns, stat.st_size)
    cached = _PARSED.get(file)
    if cached is None or cached[0] != stamp:
        try:
            tree: ast.Module | None = ast.parse(file.read_bytes(), filename=str(file))
        except (SyntaxError, ValueError):
            tree = None
        cached = (stamp, tree)
        _PARSED[file] = cached
    return cached[1]
