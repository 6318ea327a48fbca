"""What the closed-loop comparison campaigns share: each seed run without and with the thing
compared (a rear scanner, the radar, the thermal camera), and the caption that says how many
seeds ran under which profile and which command reproduces the full table."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TypeVar

from evidence.profiles import active_profile

R = TypeVar("R")


def side_by_side(run: Callable[[int, bool], R], seeds: Iterable[int]) -> list[tuple[R, R]]:
    """Per seed, ``(run(seed, False), run(seed, True))``: the same encounter without and with."""
    return [(run(seed, False), run(seed, True)) for seed in seeds]


def flat(pairs: Iterable[tuple[R, R]]) -> list[R]:
    """The runs of ``pairs`` in order, each without before with (the tables' row order)."""
    return [run for pair in pairs for run in pair]


def caption(n_seeds: int, command: str, duration_s: float | None = None) -> str:
    """A campaign table's caption: seeds, duration, the active profile, the full command."""
    length = "" if duration_s is None else f", {duration_s:g} s"
    return f"{n_seeds} seeds{length} ({active_profile()} profile); {command}"
