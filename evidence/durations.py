"""Where a suite's time went: the tests of an evidence bundle summed by file (SR-EVD-1).

``python -m evidence.durations BUNDLE [--top N]`` reads ``BUNDLE/evidence.json`` (what
``make certify`` and ``make test`` write) and prints, slowest first, each test file's summed
wall-clock time [s], its share of the whole and its number of tests, then the totals by
evidence kind. The times are the tests' own (setup, call and teardown); work a test hands to
other processes while it waits (a Dask cluster, the soaks beside the suite) is in its wait.
A campaign whose body ran ahead in a worker beside the suite (properties.ahead) waited only for
what was left of it; the body's own wall time in the worker is the ``worker s`` column.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

__all__ = ["WORKER_TIME", "by_file", "by_kind", "main", "worker_s"]

WORKER_TIME = "run ahead in a worker beside the suite"
"""The counters a test run ahead carries (properties.ahead records them)."""


def worker_s(test: Mapping[str, Any]) -> float:
    """The wall time [s] the test's body took in a worker beside the suite (0 when it ran in
    the session)."""
    for detail in test.get("details", ()):
        if detail.get("type") == "counts" and detail.get("name") == WORKER_TIME:
            return float(detail["values"]["wall s"])
    return 0.0


def _summed(tests: Iterable[Mapping[str, Any]], key: str) -> list[tuple[str, float, int]]:
    seconds: dict[str, float] = {}
    count: Counter[str] = Counter()
    for test in tests:
        name = str(test[key])
        seconds[name] = seconds.get(name, 0.0) + float(test["duration_s"])
        count[name] += 1
    return sorted(((n, s, count[n]) for n, s in seconds.items()), key=lambda row: -row[1])


def by_file(tests: Iterable[Mapping[str, Any]]) -> list[tuple[str, float, int]]:
    """``(file, seconds, tests)`` per test file, slowest first."""
    return _summed(tests, "file")


def by_kind(tests: Iterable[Mapping[str, Any]]) -> list[tuple[str, float, int]]:
    """``(evidence kind, seconds, tests)``, slowest first."""
    return _summed(tests, "kind")


def main(argv: list[str] | None = None) -> None:
    """Print the summary of one bundle (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bundle", type=Path, help="an evidence bundle folder")
    parser.add_argument("--top", type=int, default=25, help="how many files to list")
    args = parser.parse_args(argv)
    path = args.bundle / "evidence.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        tests = data["tests"]
    except (OSError, ValueError, KeyError) as exc:
        parser.exit(2, f"error: {path}: not an evidence bundle's evidence.json ({exc})\n")
    total = sum(float(t["duration_s"]) for t in tests) or 1.0
    print(f"{data.get('profile', '?')} profile: {len(tests)} tests, {total:.0f} s in tests")
    beside: dict[str, float] = {}
    for test in tests:
        beside[test["file"]] = beside.get(test["file"], 0.0) + worker_s(test)
    print(f"{sum(beside.values()):.0f} s more in workers beside the suite (properties.ahead)")
    print("| file | s | share | tests | worker s |\n|---|---:|---:|---:|---:|")
    for name, seconds, n in by_file(tests)[: args.top]:
        print(f"| {name} | {seconds:.0f} | {seconds / total:.1%} | {n} | {beside[name]:.0f} |")
    print("\n| kind | s | share | tests |\n|---|---:|---:|---:|")
    for kind, seconds, n in by_kind(tests):
        print(f"| {kind} | {seconds:.0f} | {seconds / total:.1%} | {n} |")


if __name__ == "__main__":
    main()
