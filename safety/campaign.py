"""Closed-loop campaigns: many seeded encounters, one row each, kept as they arrive (SR-RUN-8).

An :class:`~safety.campaign_plan.Encounter` is a scenario (a clear-air one, or an airside one in
a weather), a seed and a length (:mod:`safety.campaign_plan`); :func:`run_encounter` runs it in
closed loop exactly as ``safecase run`` does (the runtime deciding after every scan, the
simulated robot obeying through its actuation latency, with the simulated thermal camera and
radar that ``runtime.sim_sensors`` names, SR-FUS-9) and returns its :class:`CampaignRow`:
contacts with the robot's speed at each, the closest approach, progress along the route, the
command mix and the per-cycle thread CPU time. Everything but the CPU times is a function of
the encounter and the configuration alone, so the same seed gives the same :meth:`outcome` on
any worker.

Availability (SR-AVL-1, SR-RUN-8): a shadow oracle (:class:`safety.availability.Shadow`, the
runtime fed the simulator's ground truth) decides on every one of our frames without driving the
robot, so every row counts its *nuisance STOP* cycles (we STOP, the oracle in the same situation
would PROCEED or SLOW) and what set our command in them; a campaign about the contact rate alone
can leave the shadow out (``shadow=False``). With ``oracle=True`` the oracle also
drives a second simulation of the same seed, and the row holds our progress over the oracle's
over the time both lasted (:meth:`safety.availability.Comparison.progress_share`).

:class:`CampaignLog` is the campaign's JSON Lines file: a header line naming the configuration
hash, then one row per finished encounter, flushed as each arrives, so an interrupted
campaign resumes with the encounters it has not got (:meth:`CampaignLog.done`). An encounter
that raised is a row too, with its error, counted and never silently dropped.
"""

from __future__ import annotations

import functools
import json
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, config_hash
from pipeline.errors import SafecaseError
from pipeline.jsoncodec import dumps
from safety.availability import our_runtime, progress_share, run_oracle, run_ours
from safety.campaign_plan import (
    NAMED,
    Encounter,
    encounter_plan,
    encounter_simulation,
    known_scenario,
)
from safety.run import contact_speeds, run_simulation

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "NAMED",
    "CampaignError",
    "CampaignLog",
    "CampaignRow",
    "Encounter",
    "cpu_summary_ms",
    "encounter_plan",
    "failed_row",
    "pending",
    "run_campaign",
    "run_encounter",
]

FORMAT = "safecase-campaign/1"


class CampaignError(SafecaseError):
    """A campaign file that cannot be resumed (another configuration, not a campaign)."""


@dataclass(frozen=True)
class CampaignRow:
    """What one encounter did. Speeds in m/s, distances in m, times in ms.

    ``moving_contacts_mps``: the robot's speed at each contact made while it moved (each is a
    violation of passive safety); ``contacts``: every first contact, moving or not;
    ``closest_m``: the least ego-to-object separation of the run (``inf`` without objects);
    ``cpu_ms``: percentiles of the cycles' thread CPU time (not part of :meth:`outcome`);
    ``error``: set when the run raised (then the counts are zero).

    Availability (module docstring): ``nuisance_cycles``, the cycles where we commanded STOP
    and the shadow oracle would not have, and ``nuisance_causes``, what set our command in
    them; ``progress_share``, our progress over the oracle's closed loop (None unless the
    encounter ran with ``oracle=True``). A row without the shadow's figures (an encounter
    that raised, or a line that lacks the keys) has ``nuisance_cycles`` None: it counts in the
    contact bound, not in the availability figures.
    """

    encounter: Encounter
    cycles: int
    commands: Mapping[str, int]
    contacts: int
    moving_contacts_mps: tuple[float, ...]
    closest_m: float
    progress_m: float
    route_m: float
    cpu_ms: Mapping[str, float] = field(default_factory=dict)
    error: str | None = None
    nuisance_cycles: int | None = None
    nuisance_causes: Mapping[str, int] = field(default_factory=dict)
    progress_share: float | None = None

    @property
    def nuisance_share(self) -> float | None:
        """Nuisance STOP cycles over all cycles of the run (None without the shadow)."""
        if self.nuisance_cycles is None:
            return None
        return self.nuisance_cycles / self.cycles if self.cycles else 0.0

    def outcome(self) -> dict[str, Any]:
        """The deterministic part of the row (everything but the CPU times)."""
        row = self.to_json()
        del row["cpu_ms"]
        return row

    def to_json(self) -> dict[str, Any]:
        """The row as JSON-ready data (the campaign file's line)."""
        return {
            "scenario": self.encounter.scenario,
            "seed": self.encounter.seed,
            "duration_s": self.encounter.duration_s,
            "weather": self.encounter.weather,
            "cycles": self.cycles,
            "commands": dict(sorted(self.commands.items())),
            "contacts": self.contacts,
            "moving_contacts_mps": list(self.moving_contacts_mps),
            "closest_m": self.closest_m,
            "progress_m": self.progress_m,
            "route_m": self.route_m,
            "cpu_ms": dict(self.cpu_ms),
            "error": self.error,
            "nuisance_cycles": self.nuisance_cycles,
            "nuisance_causes": dict(sorted(self.nuisance_causes.items())),
            "progress_share": self.progress_share,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> CampaignRow:
        """A row read back from its line (``KeyError`` / ``TypeError`` when malformed).

        The availability keys may be missing (the row then has no shadow figures, class
        docstring), and so may ``weather`` (a row of a scenario in its own weather); every
        other key is required. A weather the encounter refuses raises ``ValueError``."""
        nuisance = data.get("nuisance_cycles")
        share = data.get("progress_share")
        weather = data.get("weather")
        return cls(
            encounter=Encounter(
                str(data["scenario"]),
                int(data["seed"]),
                float(data["duration_s"]),
                None if weather is None else str(weather),
            ),
            cycles=int(data["cycles"]),
            commands={str(k): int(v) for k, v in data["commands"].items()},
            contacts=int(data["contacts"]),
            moving_contacts_mps=tuple(float(v) for v in data["moving_contacts_mps"]),
            closest_m=float(data["closest_m"]),
            progress_m=float(data["progress_m"]),
            route_m=float(data["route_m"]),
            cpu_ms={str(k): float(v) for k, v in data["cpu_ms"].items()},
            error=None if data["error"] is None else str(data["error"]),
            nuisance_cycles=None if nuisance is None else int(nuisance),
            nuisance_causes={str(k): int(v) for k, v in data.get("nuisance_causes", {}).items()},
            progress_share=None if share is None else float(share),
        )


def cpu_summary_ms(cpu_s: Sequence[float]) -> dict[str, float]:
    """The median, 99th percentile and maximum [ms] of cycles' CPU times [s] (a row's
    ``cpu_ms``); empty without cycles."""
    cpu = np.asarray(cpu_s, dtype=float) * 1e3
    if not cpu.size:
        return {}
    return {
        "p50": float(np.percentile(cpu, 50)),
        "p99": float(np.percentile(cpu, 99)),
        "max": float(cpu.max()),
    }


def failed_row(encounter: Encounter, error: str) -> CampaignRow:
    """The row of an encounter that raised (or whose workers kept dying): counted, not lost."""
    return CampaignRow(encounter, 0, {}, 0, (), float("inf"), 0.0, 0.0, {}, error=error)


def run_encounter(
    config: SafecaseConfig, encounter: Encounter, *, oracle: bool = False, shadow: bool = True
) -> CampaignRow:
    """Run ``encounter`` in closed loop with the shadow oracle beside it and summarise it;
    with ``oracle`` also the oracle's own closed loop of the same seed (module docstring).

    Without ``shadow`` the run has no shadow oracle (about 40 % less CPU) and its row no
    nuisance figures (``nuisance_cycles`` None): what a campaign about the contact rate alone
    needs. The shadow only watches, so our run, and every other field of the row, is the same
    either way. ``oracle`` needs the shadow (its comparison reads the shadow's cycles).

    Raises whatever the run raises; a campaign turns that into a :func:`failed_row`.
    """
    if not known_scenario(encounter.scenario):
        raise ValueError(f"unknown scenario {encounter.scenario!r}")
    if oracle and not shadow:
        raise ValueError("oracle=True needs the shadow oracle (shadow=True)")
    model = Classifier.from_config(config.classify)  # parsed once per worker thread
    sim = encounter_simulation(config, encounter)
    if shadow:
        summary, watcher = run_ours(config, sim, model)
        flags = watcher.nuisance()
        causes = Counter(row[5] for row, flag in zip(watcher.rows, flags, strict=True) if flag)
        nuisance: int | None = sum(flags)
    else:
        summary = run_simulation(config, sim, runtime=our_runtime(config, sim, model))
        causes, nuisance = Counter(), None
    result = summary.sim
    assert result is not None  # run_simulation always sets it
    speeds = contact_speeds(result)
    share = None
    if oracle:
        share = progress_share(
            summary, run_oracle(config, encounter_simulation(config, encounter), model)
        )
    return CampaignRow(
        encounter=encounter,
        cycles=summary.cycles,
        commands=dict(summary.actions),
        contacts=int(speeds.size),
        moving_contacts_mps=tuple(float(v) for v in speeds[speeds > 0.0]),
        closest_m=float(np.min(result.min_separation_m, initial=np.inf)),
        progress_m=float(result.ego_log["arc_m"][-1]),
        route_m=float(result.ego_spec.route.length_m),
        cpu_ms=cpu_summary_ms(summary.cpu_s),
        nuisance_cycles=nuisance,
        nuisance_causes=dict(causes),
        progress_share=share,
    )


class CampaignLog:
    """A campaign's JSON Lines file (module docstring); open with :meth:`open`."""

    def __init__(self, path: Path, handle: TextIO, rows: list[CampaignRow]) -> None:
        self.path = path
        self._handle = handle
        self.rows = rows

    @classmethod
    def open(cls, path: Path, config: SafecaseConfig) -> CampaignLog:
        """Open ``path`` for appending, creating it with its header, or resume it.

        Raises :class:`CampaignError` naming the file and line when it is not a campaign of
        this configuration (another configuration's rows cannot be pooled with ours). A last
        line cut short by a kill is dropped (its encounter runs again).
        """
        digest = config_hash(config)
        rows: list[CampaignRow] = []
        if path.exists() and path.stat().st_size:
            rows, valid_bytes = _read(path, digest)
            with path.open("r+b") as raw:
                raw.truncate(valid_bytes)
            handle = path.open("a", encoding="utf-8")
        else:
            path.parent.mkdir(parents=True, exist_ok=True)
            handle = path.open("w", encoding="utf-8")
            handle.write(dumps({"format": FORMAT, "config_hash": digest}) + "\n")
            handle.flush()
        return cls(path, handle, rows)

    def done(self) -> set[str]:
        """Keys of the encounters the file already holds."""
        return {row.encounter.key for row in self.rows}

    def add(self, row: CampaignRow) -> None:
        """Append one row and flush it to the file."""
        self.rows.append(row)
        self._handle.write(dumps(row.to_json()) + "\n")
        self._handle.flush()

    def close(self) -> None:
        """Close the file."""
        self._handle.close()

    def __enter__(self) -> CampaignLog:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _read(path: Path, digest: str) -> tuple[list[CampaignRow], int]:
    """The rows of ``path`` and the byte length of its complete lines (see :meth:`open`)."""
    data = path.read_bytes()
    lines = data.split(b"\n")
    complete = lines[:-1]  # the part after the last newline is a line cut short (or empty)
    if not complete:
        raise CampaignError(f"{path}: not a campaign file (no header line)")
    try:
        header = json.loads(complete[0])
    except ValueError:
        header = None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise CampaignError(f"{path}:1: not a campaign file (expected format {FORMAT})")
    if header.get("config_hash") != digest:
        raise CampaignError(
            f"{path}: written with configuration {str(header.get('config_hash'))[:16]}, this "
            f"configuration hashes to {digest[:16]}; start a new file"
        )
    rows = []
    for number, line in enumerate(complete[1:], start=2):
        try:
            rows.append(CampaignRow.from_json(json.loads(line)))
        except (ValueError, KeyError, TypeError, AttributeError) as exc:
            raise CampaignError(f"{path}:{number}: not a campaign row ({exc})") from exc
    return rows, len(data) - len(lines[-1])


def pending(plan: Iterable[Encounter], log: CampaignLog) -> list[Encounter]:
    """The encounters of ``plan`` that ``log`` does not hold yet, in plan order."""
    have = log.done()
    return [e for e in plan if e.key not in have]


def run_campaign(
    client: Client | None,
    config: SafecaseConfig,
    plan: Sequence[Encounter],
    log: CampaignLog,
    on_row: Callable[[CampaignRow], None] | None = None,
    *,
    oracle: bool = False,
    shadow: bool = True,
) -> list[CampaignRow]:
    """Run every encounter of ``plan`` that ``log`` lacks on ``client``'s cluster (without a
    client: here, one after another; :func:`pipeline.distributed.as_done`), with the oracle's
    closed loop too when ``oracle`` and without the shadow oracle unless ``shadow``
    (:func:`run_encounter`), appending each row to ``log`` as it arrives (a failure as a
    :func:`failed_row`, and ``on_row`` told of each); all of the log's rows, resumed ones first
    (kept as they were written, with or without the oracle)."""
    from pipeline.distributed import TaskFailed, as_done  # Dask loads only for a campaign

    todo = pending(plan, log)
    task = functools.partial(run_encounter, config, oracle=oracle, shadow=shadow)
    for done in as_done(client, task, todo):
        encounter = todo[done.index]
        result = done.result
        row = failed_row(encounter, result.error) if isinstance(result, TaskFailed) else result
        log.add(row)
        if on_row is not None:
            on_row(row)
    return list(log.rows)
