"""Mutation testing of the safety code: what was measured and whether it still holds (SR-EVD-5).

How strong is the harness? Each module in :data:`TARGETS` is mutated one small change at a
time by mutmut (``<`` to ``<=``, ``+`` to ``-``, a constant plus one, ``and`` to ``or``, a string
altered, ...) and the tests that claim the module are run against every mutant
(:mod:`evidence.mutation_run`, what ``make mutation`` runs): a mutant is *killed* when some test
fails (or hangs past mutmut's timeout), and *survives* otherwise. A survivor is either a gap in
the tests or an *equivalent* mutant (no observable behaviour changes); equivalents are listed,
one line each with the reason, in ``safety/mutation-equivalents.toml`` and leave the score's
denominator only once a person has reviewed them.

The tests that claim a module, and those left out, are chosen by
:mod:`evidence.mutation_targets`.

Each module's result is committed evidence: ``safety/mutation/<module>.json`` holds every
mutant's stable description (:func:`mutant_key`) and outcome with the code hash of the module
and of each selected test file (:func:`code_sha256`: the SHA-256 of the syntax tree without
docstrings, comments, layout or line numbers, none of which mutmut mutates or a test run
reads). :func:`load_results` recomputes those hashes: a result is *fresh* when no code
changed, *stale* when the module or its tests changed since (``why`` says what), and *missing*
when the module was never measured. Durations are wall-clock seconds.
"""

from __future__ import annotations

import ast
import difflib
import hashlib
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any, Literal

from evidence.mutation_targets import TARGETS, Target, left_out, select_tests
from pipeline.compat import tomllib

__all__ = [
    "EQUIVALENTS_FILE",
    "RESULTS_DIR",
    "SCHEMA",
    "TARGETS",
    "Equivalent",
    "ModuleResult",
    "MutantOutcome",
    "Status",
    "Target",
    "code_sha256",
    "describe",
    "digest",
    "left_out",
    "load_equivalents",
    "load_results",
    "mutant_key",
    "pytest_args",
    "read_result",
    "result_file",
    "select_tests",
    "write_result",
]

SCHEMA = "safecase-mutation/3"
# Committed beside the equivalents list: CI reads them on a clean clone (out/ is not tracked).
RESULTS_DIR = Path("safety/mutation")
EQUIVALENTS_FILE = Path("safety/mutation-equivalents.toml")
TOOL = "mutmut"
# Passed to pytest for every mutant: derandomized examples, no benchmark rounds, no cache.
PYTEST_ARGS: tuple[str, ...] = (
    "--hypothesis-profile=ci",
    "--benchmark-disable",
    "-p",
    "no:cacheprovider",
)
Status = Literal["killed", "timeout", "survived", "no tests", "suspicious", "not checked"]
DETECTED: frozenset[str] = frozenset({"killed", "timeout"})


_DOCUMENTED = (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)


def code_sha256(source: bytes) -> str:
    """SHA-256 (hex) of Python ``source``'s code: its syntax tree with every docstring (the
    leading string of a module, class or function) taken out, dumped without line numbers.
    Comments and layout never reach the tree. An edit of documentation alone therefore keeps a
    mutation result fresh; any change of code, a constant or a string that is not a docstring
    makes it stale. Source that does not parse is hashed as bytes."""
    try:
        tree = ast.parse(source)
    except (SyntaxError, ValueError):
        return hashlib.sha256(b"bytes:" + source).hexdigest()
    for node in ast.walk(tree):
        if isinstance(node, _DOCUMENTED) and node.body:
            first = node.body[0]
            if (
                isinstance(first, ast.Expr)
                and isinstance(first.value, ast.Constant)
                and isinstance(first.value.value, str)
            ):
                # An emptied body keeps a placeholder so the tree stays a valid one.
                node.body = node.body[1:] or [ast.Pass()]
    return hashlib.sha256(b"ast:" + ast.dump(tree).encode("utf-8")).hexdigest()


def _sha256(path: Path) -> str:
    return code_sha256(path.read_bytes())


def digest(target: Target, root: Path, tests: Sequence[str] | None = None) -> dict[str, Any]:
    """What a cached result was computed from: the module's and each selected test file's
    code hash (:func:`code_sha256`), the function filter, the tool and the pytest arguments."""
    tests = select_tests(target, root) if tests is None else tests
    return {
        "module": target.path,
        "module_code_sha256": _sha256(root / target.path),
        "functions": list(target.functions),
        "tests": {name: _sha256(root / name) for name in tests},
        "tool": f"{TOOL} {_tool_version()}",
        "pytest_args": pytest_args(tests, root),
    }


def pytest_args(tests: Sequence[str], root: Path, failing: Sequence[str] = ()) -> list[str]:
    """What pytest is given for every mutant: the ci profile, the left-out tests and those
    ``failing`` on the unmutated tree deselected."""
    nodes = [*left_out(tests, root), *failing]
    deselect = [arg for node in nodes for arg in ("--deselect", node)]
    return [*PYTEST_ARGS, *deselect]


def _tool_version() -> str:
    try:
        return version(TOOL)
    except PackageNotFoundError:
        return "not installed"


# -- mutant descriptions that survive unrelated edits ----------------------------------------


def _squash(lines: Iterable[str]) -> str:
    return " / ".join(" ".join(line.split()) for line in lines if line.strip())


def mutant_key(module: str, function: str, original: str, mutated: str) -> str:
    """The stable description of a mutant: ``<module> | <function> | <old> -> <new>``.

    ``original`` and ``mutated`` are the function's source before and after the mutation; only
    the changed lines appear, whitespace collapsed, so the key does not depend on line numbers
    or on edits elsewhere in the module (SR-EVD-5: the equivalent-mutant list stays valid).
    """
    old: list[str] = []
    new: list[str] = []
    for line in difflib.ndiff(original.splitlines(), mutated.splitlines()):
        if line.startswith("- "):
            old.append(line[2:])
        elif line.startswith("+ "):
            new.append(line[2:])
    return f"{module} | {function} | {_squash(old)} -> {_squash(new)}"


# -- results ----------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class MutantOutcome:
    """One mutant: the function it is in, its stable key and what the tests did."""

    function: str
    key: str
    status: Status

    @property
    def detected(self) -> bool:
        """True when the tests noticed it (failed or hung past the timeout)."""
        return self.status in DETECTED


@dataclass(frozen=True, slots=True)
class Equivalent:
    """A surviving mutant judged equivalent, with the reason and who reviewed it ("" = not yet)."""

    key: str
    reason: str
    reviewed_by: str

    @property
    def reviewed(self) -> bool:
        """True once a person has confirmed the reason."""
        return bool(self.reviewed_by.strip())


@dataclass(frozen=True, slots=True)
class ModuleResult:
    """A module's recorded campaign and whether it still matches the tree.

    ``state`` is ``fresh`` (module and selected tests unchanged), ``stale`` (``why`` says what
    changed) or ``missing`` (never measured, or the result is unreadable).
    ``failing_before`` lists selected tests that failed on the unmutated tree and were left out.
    """

    target: Target
    state: Literal["fresh", "stale", "missing"]
    why: str = ""
    mutants: list[MutantOutcome] = field(default_factory=list)
    tests: list[str] = field(default_factory=list)
    duration_s: float = 0.0
    finished_utc: str = ""
    tool: str = ""
    failing_before: list[str] = field(default_factory=list)

    def counts(self, equivalents: Mapping[str, Equivalent]) -> dict[str, int]:
        """Mutants by outcome; ``equivalent`` counts reviewed equivalents among the survivors
        and ``pending`` those not reviewed yet (still counted as survivors)."""
        counts = {"total": len(self.mutants), "killed": 0, "timeout": 0, "survived": 0}
        counts |= {"no tests": 0, "equivalent": 0, "pending": 0, "other": 0}
        for mutant in self.mutants:
            if mutant.status in ("killed", "timeout"):
                counts[mutant.status] += 1
                continue
            equivalent = equivalents.get(mutant.key)
            if equivalent is not None and equivalent.reviewed:
                counts["equivalent"] += 1
                continue
            if equivalent is not None:
                counts["pending"] += 1
            if mutant.status in ("survived", "no tests"):
                counts[mutant.status] += 1
            else:
                counts["other"] += 1
        return counts

    def score(self, equivalents: Mapping[str, Equivalent]) -> float | None:
        """Killed (or timed out) over the non-equivalent mutants; None when there are none."""
        counts = self.counts(equivalents)
        judged = counts["total"] - counts["equivalent"]
        return (counts["killed"] + counts["timeout"]) / judged if judged else None

    def survivors(self, equivalents: Mapping[str, Equivalent]) -> list[MutantOutcome]:
        """Undetected mutants not reviewed as equivalent."""
        return [
            m
            for m in self.mutants
            if not m.detected and not (m.key in equivalents and equivalents[m.key].reviewed)
        ]


def result_file(results: Path, target: Target) -> Path:
    """Where ``target``'s result lives in the results folder (``safety/mutation``)."""
    return results / f"{target.slug}.json"


def write_result(
    results: Path,
    target: Target,
    recorded: Mapping[str, Any],
    mutants: Sequence[MutantOutcome],
    duration_s: float,
    failing_before: Sequence[str] = (),
) -> Path:
    """Write ``target``'s result: the digest it was computed from, when, how long it took and
    one ``[status, "<function> | <change>"]`` line per mutant (small, readable diffs)."""
    head = {
        "schema": SCHEMA,
        "finished_utc": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "duration_s": round(duration_s, 1),
        "digest": recorded,
        "failing_before": list(failing_before),
    }
    prefix = f"{target.path} | "
    rows = [json.dumps([m.status, m.key.removeprefix(prefix)], ensure_ascii=False) for m in mutants]
    text = json.dumps(head, indent=1, ensure_ascii=False)[:-2]
    text += ',\n "mutants": [\n  ' + ",\n  ".join(rows) + "\n ]\n}\n"
    file = result_file(results, target)
    file.parent.mkdir(parents=True, exist_ok=True)
    file.write_text(text, encoding="utf-8")
    return file


def _staleness(recorded: Mapping[str, Any], now: Mapping[str, Any]) -> str:
    """Empty when ``recorded`` matches ``now``; else what changed, in words."""
    problems = []
    if recorded.get("module_code_sha256") != now["module_code_sha256"]:
        problems.append(f"{now['module']} changed")
    old_tests: Mapping[str, str] = recorded.get("tests", {})
    new_tests: Mapping[str, str] = now["tests"]
    added = sorted(set(new_tests) - set(old_tests))
    removed = sorted(set(old_tests) - set(new_tests))
    changed = sorted(t for t in set(new_tests) & set(old_tests) if new_tests[t] != old_tests[t])
    for label, names in (("changed", changed), ("new", added), ("no longer selected", removed)):
        if names:
            problems.append(f"{label} tests: {', '.join(names)}")
    for key in ("functions", "tool"):
        if recorded.get(key) != now[key]:
            problems.append(f"{key} {recorded.get(key)!r} -> {now[key]!r}")
    if not problems and recorded.get("pytest_args") != now["pytest_args"]:
        problems.append("the left-out tests changed")
    return "; ".join(problems)


def read_result(target: Target, root: Path, results: Path) -> ModuleResult:
    """``target``'s result from ``results``, fresh, stale or missing against the tree."""
    file = result_file(results, target)
    shown = file.relative_to(root) if file.is_relative_to(root) else file
    try:
        data = json.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return ModuleResult(target, "missing", f"not measured: no {shown}")
    except (OSError, json.JSONDecodeError) as exc:
        return ModuleResult(target, "missing", f"{shown} unreadable: {exc}")
    if data.get("schema") != SCHEMA:
        return ModuleResult(target, "missing", f"{shown}: schema {data.get('schema')!r}")
    mutants = []
    for status, change in data["mutants"]:
        function = change.split(" | ", 1)[0]
        mutants.append(MutantOutcome(function, f"{target.path} | {change}", status))
    why = _staleness(data["digest"], digest(target, root))
    return ModuleResult(
        target,
        "stale" if why else "fresh",
        why,
        mutants,
        list(data["digest"]["tests"]),
        float(data["duration_s"]),
        str(data["finished_utc"]),
        str(data["digest"]["tool"]),
        [str(node) for node in data.get("failing_before", [])],
    )


def load_results(
    root: Path, results: Path | None = None, targets: Sequence[Target] = TARGETS
) -> list[ModuleResult]:
    """Every target's result, marked fresh, stale or missing against the tree at ``root``
    (``results`` defaults to ``root / safety/mutation``)."""
    results = root / RESULTS_DIR if results is None else results
    return [read_result(target, root, results) for target in targets]


def describe(result: ModuleResult, equivalents: Mapping[str, Equivalent]) -> str:
    """One line: the module, mutants killed of those judged, the score and fresh/stale."""
    if result.state == "missing":
        return f"{result.target.path}: {result.why}"
    counts = result.counts(equivalents)
    score = result.score(equivalents)
    shown = "n/a" if score is None else f"{100 * score:.1f} %"
    return (
        f"{result.target.path}: {counts['killed'] + counts['timeout']} of "
        f"{counts['total'] - counts['equivalent']} killed ({shown}; {counts['equivalent']} "
        f"equivalent, {counts['pending']} pending review, {counts['survived']} survived, "
        f"{counts['no tests']} reached by no test) [{result.state}]"
    )


def load_equivalents(path: Path) -> dict[str, Equivalent]:
    """The reviewed list of equivalent mutants: ``[equivalent]`` table, one line each,
    ``"<key>" = { reason = "...", reviewed_by = "..." }``. Raises ValueError on a malformed
    entry (an empty reason, unknown fields)."""
    if not path.exists():
        return {}
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    table = data.get("equivalent", {})
    if not isinstance(table, dict):
        raise ValueError(f"{path}: [equivalent] must be a table of key = {{ reason, reviewed_by }}")
    entries: dict[str, Equivalent] = {}
    for key, value in table.items():
        if not isinstance(value, dict) or set(value) - {"reason", "reviewed_by"}:
            raise ValueError(f"{path}: {key!r}: expected {{ reason = ..., reviewed_by = ... }}")
        reason = str(value.get("reason", "")).strip()
        if not reason:
            raise ValueError(f"{path}: {key!r}: an equivalent mutant needs its reason")
        entries[key] = Equivalent(key, reason, str(value.get("reviewed_by", "")))
    return entries
