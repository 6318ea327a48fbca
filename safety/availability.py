"""Availability: ours against the oracle and the Nav2-style baseline, same seed (SR-AVL-1..4).

:func:`compare` runs one scenario three times, each in its own closed-loop
:class:`~pipeline.sources.sim.simulation.Simulation` built from the same seed (same world, same
scanner noise, same braking draw):

* **ours**: the runtime as configured (the perception chain, the governor, the monitors);
* **oracle**: the same runtime with :class:`pipeline.oracle.GroundTruthPerception` in place of
  the chain: the best progress any perception could allow under the same proofs;
* **baseline**: :class:`safety.baseline.Nav2Baseline` on the raw scan points.

During ours a *shadow* oracle decides on every one of our frames without driving the robot (a
second runtime with the ground-truth chain, fed the same :class:`~safety.runtime.CycleInput`).
A **nuisance STOP** is a cycle where we command STOP while the shadow, in that very situation,
commands PROCEED or SLOW; its time is the cycle's share of the run (one scan period). The
shadow's braking watch follows the STOP actually in force on the robot (ours), so it never
reads our robot's motion as its own weak braking.

Progress is compared over the time both runs lasted (a run ends early at a contact): our arc
length at that time over the oracle's. Time to goal is the first time the robot is within
:data:`GOAL_TOLERANCE_M` of its route's end (None when it is not reached).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.oracle import GroundTruthPerception
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import SimResult, Simulation
from pipeline.types import Action, PredictionMode
from safety.baseline import Nav2Baseline
from safety.run import RunSummary, contact_speeds, run_simulation, site_map
from safety.runtime import CycleInput, CycleOutput, Levers, Runtime

__all__ = [
    "GOAL_TOLERANCE_M",
    "Campaign",
    "Comparison",
    "RunMetrics",
    "Shadow",
    "binding_kind",
    "common_progress_m",
    "compare",
    "compare_all",
    "our_runtime",
    "progress_share",
    "run_baseline",
    "run_metrics",
    "run_oracle",
    "run_ours",
]

GOAL_TOLERANCE_M = 0.05
"""How close to the route's end counts as there [m]."""


def binding_kind(out: CycleOutput) -> str:
    """What set a cycle's command: a monitor's or stage's name, the prediction mode of the
    binding zone (``zone:UNKNOWN``, ``zone:CONE``, ...), ``pedestrian``, ``path end`` or
    ``loose point``; ``-`` for PROCEED."""
    command = out.command
    if command.action is Action.PROCEED:
        return "-"
    for reason in command.reasons:
        if not reason.startswith("obstacle"):
            return reason.split(": ", 1)[0]
    row = int(command.reasons[0].split(":", 1)[0].split()[1]) if command.reasons else -1
    env, inputs = out.envelopes, out.record.governor_inputs
    n_env = 0 if env is None else int(env.track_id.shape[0])
    if env is not None and 0 <= row < n_env:
        return "zone:" + PredictionMode(int(env.mode[row])).name
    n_rows = 0 if inputs is None else int(inputs.free_distance_m.shape[0])
    has_point = out.distances is not None and out.distances.n_points_on_path > 0
    end = n_rows - 1 - int(has_point)
    if row == end:
        return "path end"
    return "loose point" if row > end else "pedestrian"


@dataclass
class Shadow:
    """The oracle deciding on our frames without driving the robot (module docstring).

    ``rows`` holds per cycle: (decision time [s], our action, our speed [m/s], the shadow's
    action, its speed, what set our command)."""

    runtime: Runtime
    rows: list[tuple[float, str, float, str, float, str]] = field(default_factory=list)

    @classmethod
    def for_simulation(
        cls, config: SafecaseConfig, sim: Simulation, classifier: Classifier
    ) -> Shadow:
        """A shadow oracle over ``sim``'s world."""
        truth = GroundTruthPerception.for_simulation(config, sim)
        return cls(Runtime(config, classifier=classifier, perception=truth))

    def observe(self, inp: CycleInput, out: CycleOutput, stop_since_s: float | None) -> None:
        """Decide on ``inp`` as the oracle; ``stop_since_s`` is the STOP in force on the robot."""
        self.runtime.stop_since_s = stop_since_s
        seen = self.runtime.step(inp)
        ours = out.command
        self.rows.append(
            (
                out.record.observation.now_s,
                ours.action.value,
                ours.speed_mps,
                seen.command.action.value,
                seen.command.speed_mps,
                binding_kind(out),
            )
        )

    def observer(self, ours: Runtime) -> Callable[[CycleInput, CycleOutput], None]:
        """The ``observe`` callback of :func:`safety.run.run` for the run ``ours`` drives."""

        def observe(inp: CycleInput, out: CycleOutput) -> None:
            self.observe(inp, out, ours.stop_since_s)

        return observe

    def nuisance(self) -> list[bool]:
        """Per cycle: we STOP while the oracle would PROCEED or SLOW."""
        stop = Action.STOP.value
        return [ours == stop and theirs != stop for _, ours, _, theirs, _, _ in self.rows]


@dataclass(frozen=True)
class RunMetrics:
    """One closed-loop run: how long it lasted [s], progress [m], time to goal [s] (None: not
    reached), the robot's speed at each contact [m/s], the closest approach [m] and the
    command mix."""

    duration_s: float
    progress_m: float
    route_m: float
    time_to_goal_s: float | None
    contact_speeds_mps: tuple[float, ...]
    closest_m: float
    actions: dict[str, int]

    @property
    def moving_contacts(self) -> int:
        """Contacts with the robot moving (passive-safety violations)."""
        return sum(v > 0.0 for v in self.contact_speeds_mps)


def run_metrics(summary: RunSummary) -> RunMetrics:
    """The metrics of a finished simulation run."""
    sim = summary.sim
    if sim is None:
        raise ValueError("run_metrics: the run has no simulation result")
    log = sim.ego_log
    route = float(sim.ego_spec.route.length_m)
    there = np.flatnonzero(log["arc_m"] >= route - GOAL_TOLERANCE_M)
    return RunMetrics(
        duration_s=float(log["t_s"][-1]),
        progress_m=float(log["arc_m"][-1]),
        route_m=route,
        time_to_goal_s=float(log["t_s"][there[0]]) if there.size else None,
        contact_speeds_mps=tuple(float(v) for v in contact_speeds(sim)),
        closest_m=float(np.min(sim.min_separation_m, initial=np.inf)),
        actions=dict(summary.actions),
    )


def _arc_at(result: SimResult, t_s: float) -> float:
    log = result.ego_log
    return float(np.interp(t_s, log["t_s"], log["arc_m"]))


def common_progress_m(run: RunSummary, oracle: RunSummary) -> tuple[float, float]:
    """``run``'s and ``oracle``'s arc length [m] at the end of the shorter of the two (module
    docstring: a run ends early at a contact)."""
    mine, best = run.sim, oracle.sim
    assert mine is not None  # run_simulation always sets it
    assert best is not None
    common = min(float(mine.ego_log["t_s"][-1]), float(best.ego_log["t_s"][-1]))
    return _arc_at(mine, common), _arc_at(best, common)


def progress_share(run: RunSummary, oracle: RunSummary) -> float:
    """``run``'s progress over ``oracle``'s over the time both lasted (1 when the oracle did
    not move either); SR-AVL-1."""
    mine, theirs = common_progress_m(run, oracle)
    return 1.0 if theirs <= 0.0 else mine / theirs


@dataclass
class Comparison:
    """Ours, the oracle and the baseline on one scenario and seed, plus our shadow oracle."""

    name: str
    seed: int
    ours: RunSummary
    oracle: RunSummary
    baseline: RunSummary
    shadow: Shadow
    period_s: float

    def metrics(self) -> dict[str, RunMetrics]:
        """Each run's :class:`RunMetrics`, by role."""
        return {k: run_metrics(s) for k, s in self.runs().items()}

    def runs(self) -> dict[str, RunSummary]:
        """The three runs by role."""
        return {"ours": self.ours, "oracle": self.oracle, "baseline": self.baseline}

    def progress_share(self, role: str = "ours") -> float:
        """``role``'s progress over the oracle's, over the time both lasted (1 when the oracle
        did not move either)."""
        return progress_share(self.runs()[role], self.oracle)

    def time_to_goal_share(self) -> float | None:
        """Our time to goal over the oracle's (None unless both reached it)."""
        m = self.metrics()
        ours, best = m["ours"].time_to_goal_s, m["oracle"].time_to_goal_s
        return None if ours is None or best is None or best <= 0.0 else ours / best

    def nuisance_episodes_s(self) -> list[float]:
        """Durations of the runs of consecutive nuisance cycles [s]."""
        out, length = [], 0
        for flag in [*self.shadow.nuisance(), False]:
            if flag:
                length += 1
            elif length:
                out.append(length * self.period_s)
                length = 0
        return out

    def nuisance_times_s(self) -> tuple[float, ...]:
        """Decision times of the nuisance cycles [s]."""
        flags = self.shadow.nuisance()
        return tuple(row[0] for row, flag in zip(self.shadow.rows, flags, strict=True) if flag)

    def others(self) -> dict[str, SimResult]:
        """The oracle's and the baseline's simulation results (for the run's picture)."""
        out = {}
        for role in ("oracle", "baseline"):
            result = self.runs()[role].sim
            if result is not None:
                out[role] = result
        return out

    @property
    def nuisance_cycles(self) -> int:
        """Cycles with a nuisance STOP."""
        return sum(self.shadow.nuisance())

    @property
    def nuisance_share(self) -> float:
        """Nuisance STOP time over the run's driving time."""
        duration = run_metrics(self.ours).duration_s
        return self.nuisance_cycles * self.period_s / duration if duration > 0 else 0.0

    def nuisance_causes(self) -> Counter[str]:
        """What set our command in the nuisance cycles."""
        flags = self.shadow.nuisance()
        return Counter(row[5] for row, flag in zip(self.shadow.rows, flags, strict=True) if flag)

    def speed_given_up_m(self) -> dict[str, float]:
        """Per cause of our command, largest first: the distance our commands gave up against
        the shadow oracle's on the same frames [m], the sum over cycles of (its speed - ours) x
        the scan period where it commanded faster. A diagnostic, not progress: the robot does
        not reach a commanded speed at once, and the oracle's own run drives other frames."""
        lost: dict[str, float] = {}
        for _, _, ours, _, theirs, cause in self.shadow.rows:
            if theirs > ours:
                lost[cause] = lost.get(cause, 0.0) + (theirs - ours) * self.period_s
        return dict(sorted(lost.items(), key=lambda kv: -kv[1]))


def run_ours(
    config: SafecaseConfig,
    sim: Simulation,
    classifier: Classifier,
    levers: Levers | None = None,
) -> tuple[RunSummary, Shadow]:
    """``sim`` in closed loop with :func:`our_runtime`, and the shadow oracle that decided on
    its frames."""
    shadow = Shadow.for_simulation(config, sim, classifier)
    ours = our_runtime(config, sim, classifier, levers)
    return run_simulation(config, sim, runtime=ours, observe=shadow.observer(ours)), shadow


def our_runtime(
    config: SafecaseConfig,
    sim: Simulation,
    classifier: Classifier,
    levers: Levers | None = None,
) -> Runtime:
    """The runtime as configured for ``sim`` (``levers``: the runtime's), with the site's map
    (:func:`safety.run.site_map`, SR-AVL-8)."""
    return Runtime(config, classifier=classifier, levers=levers, static_map=site_map(config, sim))


def run_oracle(
    config: SafecaseConfig,
    sim: Simulation,
    classifier: Classifier,
    progress: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """``sim`` in closed loop with the runtime fed the simulator's ground truth."""
    truth = GroundTruthPerception.for_simulation(config, sim)
    runtime = Runtime(config, classifier=classifier, perception=truth)
    return run_simulation(config, sim, runtime=runtime, progress=progress)


def run_baseline(
    config: SafecaseConfig,
    sim: Simulation,
    policy: Nav2Baseline | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> RunSummary:
    """``sim`` in closed loop with the Nav2-style baseline (default parameter file)."""
    chosen = policy if policy is not None else Nav2Baseline.from_file(config)
    return run_simulation(config, sim, runtime=chosen, progress=progress)


def compare(
    config: SafecaseConfig,
    name: str,
    seed: int,
    duration_s: float | None = None,
    *,
    classifier: Classifier | None = None,
    baseline: Nav2Baseline | None = None,
    levers: Levers | None = None,
) -> Comparison:
    """Ours, the oracle and the baseline on scenario ``name`` with ``seed`` (module docstring);
    ``baseline`` replaces the default parameter file's policy, ``levers`` our runtime's."""
    model = classifier if classifier is not None else Classifier.from_config(config.classify)
    sims = [make_simulation(config, name, seed, duration_s) for _ in range(3)]
    ours_run, shadow = run_ours(config, sims[0], model, levers)
    return Comparison(
        name,
        sims[0].seed,
        ours_run,
        run_oracle(config, sims[1], model),
        run_baseline(config, sims[2], baseline),
        shadow,
        sims[0].lidar.spec.scan_period_s,
    )


def _compare_task(item: tuple[SafecaseConfig, str, int, float | None]) -> Comparison:
    """One comparison on a worker (module level, so that a Dask worker can import it)."""
    config, name, seed, duration_s = item
    return compare(config, name, seed, duration_s)


def compare_all(
    config: SafecaseConfig,
    runs: Sequence[tuple[str, int, float | None]],
    *,
    workers: int = 1,
    classifier: Classifier | None = None,
) -> Campaign:
    """Every ``(scenario, seed, duration_s)`` of ``runs`` compared (:func:`compare`), in the
    order given. With ``workers`` > 1 the runs go to a LocalCluster of that many processes
    (:mod:`pipeline.distributed`); each run is seeded by its item alone, so the figures do not
    depend on the number of workers. A run that raised raises here, naming it."""
    if workers <= 1:
        model = classifier if classifier is not None else Classifier.from_config(config.classify)
        return Campaign([compare(config, n, s, d, classifier=model) for n, s, d in runs])
    from pipeline.distributed import TaskFailed, in_order, open_client  # Dask only when asked

    items = [(config, n, s, d) for n, s, d in runs]
    done: list[Comparison] = []
    with open_client(workers=workers) as client:
        for outcome in in_order(client, _compare_task, items):
            if isinstance(outcome.result, TaskFailed):
                name, seed, _ = runs[outcome.index]
                raise RuntimeError(f"{name} seed {seed}: {outcome.result.error}")
            done.append(outcome.result)
    return Campaign(done)


@dataclass(frozen=True)
class Campaign:
    """Figures over several comparisons: progress shares, nuisance, contacts by role."""

    comparisons: Sequence[Comparison]

    def total_progress_share(self, role: str = "ours") -> float:
        """Sum of ``role``'s progress over the sum of the oracle's (over common times)."""
        mine = theirs = 0.0
        for c in self.comparisons:
            a, b = common_progress_m(c.runs()[role], c.oracle)
            mine += a
            theirs += b
        return mine / theirs if theirs > 0 else 1.0

    def worst_progress_share(self) -> float:
        """The smallest per-run share of ours."""
        return min((c.progress_share() for c in self.comparisons), default=1.0)

    def nuisance_share(self) -> float:
        """Nuisance STOP time over driving time, all runs together."""
        time = sum(run_metrics(c.ours).duration_s for c in self.comparisons)
        bad = sum(c.nuisance_cycles * c.period_s for c in self.comparisons)
        return bad / time if time > 0 else 0.0

    def contacts(self, role: str) -> tuple[int, int]:
        """(all contacts, contacts while moving) of ``role`` over the campaign."""
        speeds = [
            v for c in self.comparisons for v in run_metrics(c.runs()[role]).contact_speeds_mps
        ]
        return len(speeds), sum(v > 0.0 for v in speeds)

    def nuisance_causes(self) -> Counter[str]:
        """What set our command in the nuisance cycles, all runs together."""
        total: Counter[str] = Counter()
        for c in self.comparisons:
            total.update(c.nuisance_causes())
        return total

    def speed_given_up_m(self) -> dict[str, float]:
        """:meth:`Comparison.speed_given_up_m`, all runs together [m], largest first."""
        total: dict[str, float] = {}
        for c in self.comparisons:
            for cause, metres in c.speed_given_up_m().items():
                total[cause] = total.get(cause, 0.0) + metres
        return dict(sorted(total.items(), key=lambda kv: -kv[1]))
