"""Run the mutation campaign of :mod:`evidence.mutation` (``make mutation``; SR-EVD-5).

Each module runs in a scratch copy of the four packages, ``tests/``, ``examples/``,
``pyproject.toml`` and ``requirements.lock`` under ``out/mutation/work/`` (the working tree is
never touched; mutmut writes its own ``mutants/`` copy there) under the ``ci`` Hypothesis
profile (derandomized, so a re-run gives the same verdicts). mutmut runs, for each mutant,
only the selected tests that executed the mutated function in a clean run. The result goes to
``safety/mutation/<module>.json`` (committed; :func:`evidence.mutation.write_result`), the
mutmut log to ``out/mutation/logs/``. ``run`` redoes only modules whose result is not fresh.

Command line: ``python -m evidence.mutation_run run|status|survivors`` (``--help``).
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import json
import os
import re
import shutil
import subprocess
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

from evidence.mutation import (
    EQUIVALENTS_FILE,
    RESULTS_DIR,
    TARGETS,
    TOOL,
    Equivalent,
    ModuleResult,
    MutantOutcome,
    Status,
    Target,
    describe,
    digest,
    load_equivalents,
    load_results,
    mutant_key,
    pytest_args,
    read_result,
    select_tests,
    write_result,
)

__all__ = ["SCRATCH_DIR", "main", "markdown_table", "run", "run_target"]

SCRATCH_DIR = Path("out/mutation")
PACKAGES: tuple[str, ...] = ("pipeline", "safety", "evidence", "properties")
# Copied beside the packages: the tests, the configurations some of them read, and the lock
# file the evidence plugin records.
ALSO_COPY: tuple[str, ...] = ("tests", "examples", "requirements.lock")
TIMEOUT_CONSTANT_S = 10.0
"""Seconds added to a mutant's estimated test time before mutmut's CPU limit (x 30) applies."""
# mutmut's exit codes per mutant (mutmut.stats.status_by_exit_code), folded to what counts.
_STATUS_BY_EXIT: Mapping[int | None, Status] = {
    1: "killed",
    3: "killed",
    0: "survived",
    5: "no tests",
    33: "no tests",
    36: "timeout",
    -24: "timeout",
    24: "timeout",
    152: "timeout",
    255: "timeout",
    -11: "killed",
    -9: "timeout",
    None: "not checked",
}


def _function_name(mangled: str) -> str:
    """mutmut's mangled name to the function's: ``x_clock`` -> ``clock``,
    ``xǁMonitorVerdictǁslow`` -> ``MonitorVerdict.slow``."""
    if mangled.startswith("xǁ"):
        _, cls, name = mangled.split("ǁ", 2)
        return f"{cls}.{name}"
    return mangled.removeprefix("x_")


def _function_sources(mutated_file: Path) -> dict[str, str]:
    """Every top-level function and method of mutmut's generated file, by generated name,
    with its source dedented and its ``def`` renamed to a common name."""
    text = mutated_file.read_text(encoding="utf-8")
    lines = text.splitlines()
    sources: dict[str, str] = {}

    def add(node: ast.FunctionDef | ast.AsyncFunctionDef) -> None:
        start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
        assert node.end_lineno is not None
        body = lines[start - 1 : node.end_lineno]
        indent = len(body[0]) - len(body[0].lstrip())
        dedented = [line[indent:] for line in body]
        sources[node.name] = "\n".join(dedented).replace(f"def {node.name}(", "def _(", 1)

    for node in ast.parse(text).body:
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            add(node)
        elif isinstance(node, ast.ClassDef):
            for child in node.body:
                if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef):
                    add(child)
    return sources


def _mutmut_config(target: Target, tests: Sequence[str], pytest_args: Sequence[str]) -> str:
    def toml_list(values: Iterable[str]) -> str:
        return "[" + ", ".join(json.dumps(v) for v in values) + "]"

    return (
        "\n[tool.mutmut]\n"
        f"source_paths = {toml_list(PACKAGES)}\n"
        f"only_mutate = {toml_list([target.path])}\n"
        f"pytest_add_cli_args_test_selection = {toml_list(tests)}\n"
        f"pytest_add_cli_args = {toml_list(pytest_args)}\n"
        f"also_copy = {toml_list(ALSO_COPY)}\n"
        "use_git_change_detection = false\n"
        'on_dependency_change = "ignore"\n'
        "use_setproctitle = false\n"
        # mutmut limits a mutant's CPU time to 30 x (its tests' estimate + this constant), and
        # the estimate times the test bodies only: a fixture that runs a scenario is not in it,
        # so with mutmut's 1 s a mutant whose tests set one up could be killed for the fixture.
        f"timeout_constant = {TIMEOUT_CONSTANT_S}\n"
    )


def _prepare(
    root: Path, work: Path, target: Target, tests: Sequence[str], failing: Sequence[str]
) -> None:
    if work.exists():
        shutil.rmtree(work)
    work.mkdir(parents=True)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".hypothesis", ".pytest_cache")
    for name in (*PACKAGES, *ALSO_COPY):
        if (root / name).is_dir():
            shutil.copytree(root / name, work / name, ignore=ignore)
        elif (root / name).exists():
            shutil.copy2(root / name, work / name)
    pyproject = (root / "pyproject.toml").read_text(encoding="utf-8")
    (work / "pyproject.toml").write_text(
        pyproject + _mutmut_config(target, tests, pytest_args(tests, root, failing)),
        encoding="utf-8",
    )


def _failing_before(work: Path, tests: Sequence[str], args: Sequence[str], log: Path) -> list[str]:
    """Node IDs of the selected tests that fail on the unmutated copy (another change in a
    shared tree, an unrelated regression): mutmut needs a green clean run, so they are
    deselected and recorded; leaving tests out can only lower the score."""
    command = [sys.executable, "-m", "pytest", "-q", "-rfE", *args, *tests]
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    done = subprocess.run(command, cwd=work, env=env, capture_output=True, text=True)
    with log.open("a", encoding="utf-8") as stream:
        stream.write(f"$ pytest (clean run) exit {done.returncode}\n{done.stdout[-4000:]}\n")
    failing = []
    for line in done.stdout.splitlines():
        head, _, rest = line.partition(" ")
        if head in ("FAILED", "ERROR") and "::" in rest:
            failing.append(rest.split(" - ", 1)[0].strip())
    if done.returncode not in (0, 1):  # 1: tests failed; anything else: pytest could not run
        raise RuntimeError(f"the clean test run failed (exit {done.returncode}); see {log}")
    return sorted(set(failing))


def _mutmut(work: Path, args: Sequence[str], log: Path) -> int:
    executable = Path(sys.executable).parent / TOOL
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONDONTWRITEBYTECODE="1")
    with log.open("a", encoding="utf-8") as stream:
        stream.write(f"$ {TOOL} {' '.join(args)}\n")
        stream.flush()
        done = subprocess.run(
            [str(executable), *args], cwd=work, env=env, stdout=stream, stderr=subprocess.STDOUT
        )
    return done.returncode


def _order(name: str) -> tuple[str, int]:
    stem, _, number = name.rpartition("__mutmut_")
    return stem, int(number) if number.isdigit() else 0


def _collect(work: Path, target: Target) -> list[MutantOutcome]:
    meta_file = work / "mutants" / f"{target.path}.meta"
    meta = json.loads(meta_file.read_text(encoding="utf-8"))
    sources = _function_sources(work / "mutants" / target.path)
    outcomes: list[MutantOutcome] = []
    seen: dict[str, int] = {}
    prefix = target.dotted + "."
    for name, code in sorted(meta["exit_code_by_key"].items(), key=lambda kv: _order(kv[0])):
        generated = name.removeprefix(prefix)
        mangled, _, _ = generated.rpartition("__mutmut_")
        function = _function_name(mangled)
        if target.functions and function not in target.functions:
            continue
        original = sources.get(f"{mangled}__mutmut_orig", "")
        mutated = sources.get(generated, "")
        key = mutant_key(target.path, function, original, mutated)
        seen[key] = seen.get(key, 0) + 1
        if seen[key] > 1:  # two mutations giving the same text: numbered, in mutmut's order
            key = f"{key} [{seen[key]}]"
        outcomes.append(MutantOutcome(function, key, _STATUS_BY_EXIT.get(code, "suspicious")))
    return outcomes


def run_target(
    target: Target, root: Path, results: Path, scratch: Path, *, jobs: int, keep: bool = False
) -> ModuleResult:
    """Mutate one module against its selected tests and write its result (SR-EVD-5)."""
    tests = select_tests(target, root)
    recorded = digest(target, root, tests)
    work = scratch / "work" / target.slug
    log = scratch / "logs" / f"{target.slug}.log"
    log.parent.mkdir(parents=True, exist_ok=True)
    log.write_text(f"{target.path}: {len(tests)} test files: {', '.join(tests)}\n")
    started = time.monotonic()
    mutants: list[MutantOutcome] = []
    failing: list[str] = []
    if tests:
        _prepare(root, work, target, tests, [])
        failing = _failing_before(work, tests, pytest_args(tests, root), log)
        if failing:
            _prepare(root, work, target, tests, failing)
        patterns = [f"{target.dotted}.x_{name}__mutmut_*" for name in target.functions]
        code = _mutmut(work, ["run", "--max-children", str(jobs), *patterns], log)
        if code != 0:
            raise RuntimeError(f"{TOOL} failed on {target.path} (exit {code}); see {log}")
        mutants = _collect(work, target)
        if not keep:
            shutil.rmtree(work)
    write_result(results, target, recorded, mutants, time.monotonic() - started, failing)
    return read_result(target, root, results)


def run(
    root: Path,
    results: Path,
    scratch: Path,
    *,
    only: Sequence[str] = (),
    jobs: int = 2,
    force: bool = False,
    keep: bool = False,
) -> list[ModuleResult]:
    """Run every target (or those whose path matches one of ``only``) whose result is not
    fresh; print one line per module with its score and the time it took."""
    equivalents = load_equivalents(root / EQUIVALENTS_FILE)
    chosen = [t for t in TARGETS if not only or any(re.search(p, t.path) for p in only)]
    done = []
    for target in chosen:
        result = read_result(target, root, results)
        if force or result.state != "fresh":
            print(f"{target.path}: {result.state}{': ' + result.why if result.why else ''}")
            print(f"  mutating against {len(select_tests(target, root))} test files ...", end="")
            sys.stdout.flush()
            result = run_target(target, root, results, scratch, jobs=jobs, keep=keep)
            print(f" {result.duration_s:.0f} s")
        done.append(result)
        print(describe(result, equivalents))
    return done


def markdown_table(results: Sequence[ModuleResult], equivalents: Mapping[str, Equivalent]) -> str:
    """The measured modules as Markdown rows: test files, mutants, killed, equivalents reviewed
    and pending, score, the run's wall-clock time [s] and whether the result is fresh."""
    lines = [
        "| module | test files | mutants | killed | equivalent: reviewed / pending | score "
        "| time [s] | result |",
        "|---|---:|---:|---:|---:|---:|---:|---|",
    ]
    for r in results:
        if r.state == "missing":
            continue
        c = r.counts(equivalents)
        score = r.score(equivalents)
        shown = "n/a" if score is None else f"{100 * score:.1f} %"
        lines.append(
            f"| `{r.target.path}` | {len(r.tests)} | {c['total']} | {c['killed'] + c['timeout']} "
            f"| {c['equivalent']} / {c['pending']} | {shown} | {r.duration_s:.0f} | {r.state} |"
        )
    return "\n".join(lines)


def _yield_the_machine() -> None:
    """Lower this process group's CPU share for real. Under Linux's autogroup scheduling (the
    default on desktops and many servers) ``nice -n 19`` only ranks a process against its own
    session's, so a mutation run took a full core from the test suite beside it; the autogroup's
    own niceness ranks it against the others. A kernel without autogroup has no such file: the
    ``nice`` of ``make mutation`` is then enough."""
    with contextlib.suppress(OSError):
        Path("/proc/self/autogroup").write_text("19\n", encoding="ascii")


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m evidence.mutation_run run|status|survivors``; exit 2 on bad input."""
    parser = argparse.ArgumentParser(prog="python -m evidence.mutation_run", description=__doc__)
    parser.add_argument("--root", type=Path, default=Path.cwd())
    parser.add_argument("--results", type=Path, default=None, help="default: ROOT/safety/mutation")
    parser.add_argument("--scratch", type=Path, default=None, help="default: ROOT/out/mutation")
    sub = parser.add_subparsers(dest="command", required=True)
    run_cmd = sub.add_parser("run", help="mutate every module whose result is not fresh")
    run_cmd.add_argument("--only", action="append", default=[], help="regex on module paths")
    run_cmd.add_argument("--jobs", type=int, default=2, help="mutants run at once (default 2)")
    run_cmd.add_argument("--force", action="store_true", help="re-run fresh modules too")
    run_cmd.add_argument("--keep", action="store_true", help="keep the scratch copy")
    sub.add_parser("status", help="each module's score and whether it is fresh")
    sub.add_parser("table", help="the measured modules as a Markdown table (docs/findings)")
    survivors = sub.add_parser("survivors", help="list surviving mutants not listed equivalent")
    survivors.add_argument("--only", action="append", default=[], help="regex on module paths")
    args = parser.parse_args(argv)
    root: Path = args.root.resolve()
    results: Path = args.results or root / RESULTS_DIR
    scratch: Path = args.scratch or root / SCRATCH_DIR
    try:
        for pattern in getattr(args, "only", []):
            re.compile(pattern)
        if not (root / "safety").is_dir():
            raise ValueError(f"--root {root}: not a safecase checkout (no safety/ folder)")
        if getattr(args, "jobs", 1) < 1:
            raise ValueError(f"--jobs must be at least 1, got {args.jobs}")
        equivalents = load_equivalents(root / EQUIVALENTS_FILE)
    except (re.error, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.command == "run":
        _yield_the_machine()
        try:
            run(
                root,
                results,
                scratch,
                only=args.only,
                jobs=args.jobs,
                force=args.force,
                keep=args.keep,
            )
        except RuntimeError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        return 0
    if args.command == "table":
        print(markdown_table(load_results(root, results), equivalents))
        return 0
    for result in load_results(root, results):
        if args.command == "status":
            stale = result.state == "stale"
            print(describe(result, equivalents) + (f" ({result.why})" if stale else ""))
        elif not args.only or any(re.search(p, result.target.path) for p in args.only):
            for mutant in result.survivors(equivalents):
                print(f"{mutant.status:9s} {mutant.key}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
