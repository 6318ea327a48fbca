"""The runtime on any source: one loop over frames, audited (SR-RUN-*).

:func:`run` is THE loop: for every frame of a source (:mod:`pipeline.sources`: the simulator,
a serial scanner or its emulator, a recorded log) the runtime decides once, and a closed-loop
source (the simulator) receives the command at the decision time, which its robot follows
after its actuation latency. The robot's path ahead is its route when the source knows one,
else straight ahead of its odometry pose (of the identity without odometry: a robot standing
on a bench). A live source's cycles are charged their measured time; any other is charged
``runtime.sim_cycle_s`` on its own clock, so a run is reproducible whatever the machine's load
(``measured_clock`` charges measured time there too).

:func:`run_audited` wraps the loop with the audit writer (off the cycle's thread for a live
source); :func:`run_scenario` runs a named simulator scenario and returns a
:class:`RunSummary` holding the simulator's verdict (contacts, the robot's speed at each
contact, minimum separations, progress) beside the runtime's (commands, reasons, timings).
"""

from __future__ import annotations

import contextlib
import hashlib
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.frames import IDENTITY
from pipeline.sources import ClosedLoopSource, FrameSource
from pipeline.sources.sim.rig import sim_source
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import SimResult, Simulation
from pipeline.static_map import StaticMap, checked_map, map_from_config
from pipeline.types import FloatArray, Frame
from safety.audit.log import AuditWriter, BackgroundAuditWriter
from safety.foxglove import McapRecorder
from safety.foxglove_scene import scene_of
from safety.geometry.path import PathAhead
from safety.model.stopping import StoppingParams
from safety.runtime import CycleInput, CycleOutput, Runtime

__all__ = [
    "RunSummary",
    "Stepper",
    "contact_speeds",
    "cycle_input",
    "run",
    "run_audited",
    "run_scenario",
    "run_simulation",
    "site_map",
]


class Stepper(Protocol):
    """What decides once per frame: the :class:`~safety.runtime.Runtime`, or a baseline policy
    (:class:`safety.baseline.Nav2Baseline`) run in the same loop."""

    def step(self, inp: CycleInput) -> CycleOutput: ...


@dataclass
class RunSummary:
    """What a run did: the command mix, every distinct reason's count, per-stage wall-clock
    samples [s], the cycle durations [s], the cycles' thread CPU times [s] and, for a
    simulation, its result.

    ``cycles`` and the counters count every cycle. The samples are every cycle's up to
    ``SAMPLES`` cycles; then, each time the lists fill, every other kept cycle is dropped, so
    the kept cycles stay evenly spaced over the run (every ``2**k``-th) and a run of any
    length keeps at most ``SAMPLES`` per series (SR-RUN-5).
    """

    SAMPLES: ClassVar[int] = 8192

    name: str
    cycles: int = 0
    actions: Counter[str] = field(default_factory=Counter)
    reasons: Counter[str] = field(default_factory=Counter)
    stage_s: dict[str, list[float]] = field(default_factory=dict)
    cycle_s: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    sim: SimResult | None = None
    audit_path: Path | None = None
    second_scan: Counter[str] = field(default_factory=Counter)
    """How often the second scanner was merged, stale, blocked, absent (SR-LID-2)."""
    sample_every: int = field(default=1, init=False)
    """Every how many cycles one is kept in the samples now."""

    def add(self, out: CycleOutput) -> None:
        """Fold one cycle in."""
        index = self.cycles
        self.cycles += 1
        self.actions[out.command.action.value] += 1
        for reason in out.command.reasons:
            self.reasons[_reason_kind(reason)] += 1
        second = out.record.inputs.get("second_scan")
        if second is not None:
            self.second_scan[str(second["state"])] += 1
        if index % self.sample_every:
            return
        for stage, dt in out.wall_s.items():
            self.stage_s.setdefault(stage, []).append(dt)
        self.cycle_s.append(float(out.record.observation.cycle_duration_s or 0.0))
        self.cpu_s.append(out.cpu_s)
        if len(self.cycle_s) >= self.SAMPLES:
            for series in (self.cycle_s, self.cpu_s, *self.stage_s.values()):
                del series[1::2]
            self.sample_every *= 2

    @property
    def moving_contacts(self) -> int:
        """Contacts during which the robot was moving (the passive-safety violations)."""
        return int(np.count_nonzero(contact_speeds(self.sim) > 0.0))


def _reason_kind(reason: str) -> str:
    """A reason without its numbers (``obstacle 3: free distance ...`` -> ``obstacle``)."""
    head = reason.split(":", 1)[0]
    return head.split(" ", 1)[0] if head.startswith("obstacle") else head


def contact_speeds(result: SimResult | None) -> FloatArray:
    """The robot's speed [m/s] at each object's first contact (empty without contacts)."""
    if result is None:
        return np.zeros(0)
    times = result.contact_time_s[np.isfinite(result.contact_time_s)]
    log = result.ego_log
    # The speed at the step that ended at the contact time (the robot is halted after it).
    idx = np.searchsorted(log["t_s"], times - 1e-12)
    before = np.maximum(idx - 1, 0)
    speeds: FloatArray = np.maximum(log["speed_mps"][before], log["speed_mps"][idx])
    return speeds


def cycle_input(frame: Frame, config: SafecaseConfig, charge_s: float | None) -> CycleInput:
    """What the runtime reads of ``frame``: its path ahead from the route or the pose."""
    rc = config.runtime
    pose = frame.pose if frame.pose is not None else IDENTITY
    if frame.route_m is not None:
        path = PathAhead.along_polyline(
            frame.route_m, frame.route_arc_m, rc.path_lookahead_m, rc.path_step_m
        )
    else:
        path = PathAhead.straight(pose, rc.path_lookahead_m, rc.path_step_m)
    return CycleInput(
        scan=frame.scan,
        now_s=frame.received_s,
        robot_pose=pose,
        path=path,
        thermal=frame.thermal,
        radar=frame.radar,
        driver=frame.health,
        charge_s=charge_s,
        acoustic=frame.acoustic,
        second=frame.second,
        twist=frame.twist,
    )


def run(
    config: SafecaseConfig,
    source: FrameSource,
    runtime: Stepper,
    *,
    max_scans: int | None = None,
    duration_s: float | None = None,
    measured_clock: bool = False,
    observe: Callable[[CycleInput, CycleOutput], None] | None = None,
) -> Iterator[CycleOutput]:
    """One cycle per frame of ``source`` (module docstring), until the source ends, after
    ``max_scans`` frames with a scan, or once ``duration_s`` of its clock has passed.

    ``observe(inp, out)``, when given, sees every cycle's input and output before the command
    goes out (a shadow deciding on the same frames without driving the robot:
    :mod:`safety.availability`)."""
    charge_s = None if (source.live or measured_clock) else config.runtime.sim_cycle_s
    closed_loop = source if isinstance(source, ClosedLoopSource) else None
    first_s: float | None = None
    n_scans = 0
    for frame in source.frames():
        first_s = frame.received_s if first_s is None else first_s
        inp = cycle_input(frame, config, charge_s)
        out = runtime.step(inp)
        if observe is not None:
            observe(inp, out)
        if closed_loop is not None:
            closed_loop.command(out.command.speed_mps, out.record.observation.now_s)
        yield out
        n_scans += frame.scan is not None
        if max_scans is not None and n_scans >= max_scans:
            return
        if duration_s is not None and frame.received_s - first_s >= duration_s:
            return


def run_audited(
    config: SafecaseConfig,
    source: FrameSource,
    *,
    audit_path: Path | None,
    params: StoppingParams | None = None,
    runtime: Stepper | None = None,
    max_scans: int | None = None,
    duration_s: float | None = None,
    measured_clock: bool = False,
    recording: Path | None = None,
    observe: Callable[[CycleInput, CycleOutput], None] | None = None,
    static_map: StaticMap | None = None,
) -> Iterator[CycleOutput]:
    """:func:`run` with one audit record per cycle in ``audit_path`` (none when None) and,
    with ``recording``, every cycle in that MCAP file for Foxglove (:mod:`safety.foxglove`,
    SR-RUN-7; an existing file is refused before any cycle runs).

    With ``audit.sign_head`` the head anchor is signed with the key of
    :func:`safety.audit.log.signing_key_for` (SR-AUD-1). That key is loaded here, when this
    function is called: a key that cannot be used raises
    :class:`~safety.audit.keys.SigningKeyError` naming its path before any cycle runs and
    before the log is created. A live source's log is written off the cycle's thread (fsync
    stalls of 15-100 ms here). An audit log needs a :class:`~safety.runtime.Runtime` (its
    records replay); ``observe`` is :func:`run`'s; ``static_map`` the site map of a runtime
    made here (default: ``map.file``'s).
    """
    from safety.audit.log import signing_key_for

    if audit_path is not None and runtime is not None and not isinstance(runtime, Runtime):
        raise ValueError(f"run_audited: an audit log needs a Runtime, got {type(runtime).__name__}")
    key = signing_key_for(config.audit) if audit_path is not None else None

    def cycles() -> Iterator[CycleOutput]:
        rt = (
            runtime
            if runtime is not None
            else Runtime(config, params=params, static_map=static_map)
        )
        with contextlib.ExitStack() as stack:
            if audit_path is not None:
                assert isinstance(rt, Runtime)
                writer = stack.enter_context(
                    AuditWriter(
                        audit_path,
                        config,
                        model_hash=rt.classifier.model_sha256,
                        params=rt.params,
                        signing_key=key,
                    )
                )
                if source.live:
                    background = BackgroundAuditWriter(writer)
                    stack.callback(background.close)
                    rt.writer = background
                else:
                    rt.writer = writer
            recorder = None if recording is None else stack.enter_context(McapRecorder(recording))
            for out in run(
                config,
                source,
                rt,
                max_scans=max_scans,
                duration_s=duration_s,
                measured_clock=measured_clock,
                observe=observe,
            ):
                if recorder is not None:
                    recorder.write(scene_of(out, config))
                yield out

    return cycles()


def site_map(config: SafecaseConfig, sim: Simulation) -> StaticMap | None:
    """The map a runtime in ``sim`` is given (SR-AVL-8): ``map.file``'s when set, else with
    ``map.simulated_world`` the world's fixed structure rasterised at ``map.resolution_m``,
    else none."""
    section = config.map
    if section.file or not section.simulated_world:
        return map_from_config(config)
    outline = sim.world.structure.outline
    key = (
        hashlib.sha256(outline.vertices_m.tobytes() + outline.part_starts.tobytes()).hexdigest(),
        section.resolution_m,
        section.tolerance_m,
    )
    if key not in _WORLD_MAPS:
        if len(_WORLD_MAPS) >= _WORLD_MAPS_KEPT:
            _WORLD_MAPS.pop(next(iter(_WORLD_MAPS)))
        raster = StaticMap.from_parts(
            list(outline.parts()), section.resolution_m, section.tolerance_m, f"sim:{sim.name}"
        )
        _WORLD_MAPS[key] = checked_map(raster, config)
    return _WORLD_MAPS[key]


# Rasterising a world takes about 0.3 s; the runs of a named scenario share its layout.
_WORLD_MAPS: dict[tuple[str, float, float], StaticMap] = {}
_WORLD_MAPS_KEPT = 8


def run_simulation(
    config: SafecaseConfig,
    sim: Simulation,
    *,
    params: StoppingParams | None = None,
    runtime: Stepper | None = None,
    audit_path: Path | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured_clock: bool = False,
    observe: Callable[[CycleInput, CycleOutput], None] | None = None,
) -> RunSummary:
    """Run ``sim`` to its end with the runtime deciding after every scan (module docstring).

    ``observe`` is :func:`run`'s. With ``scan2.enabled`` the robot has its second scanner too
    (:func:`~pipeline.sources.sim.second_lidar.sim_source`). A runtime made here has the site
    map of :func:`site_map`.
    """
    source = sim_source(config, sim)
    summary = RunSummary(sim.name, audit_path=audit_path)
    for out in run_audited(
        config,
        source,
        audit_path=audit_path,
        params=params,
        runtime=runtime,
        measured_clock=measured_clock,
        observe=observe,
        static_map=site_map(config, sim),
    ):
        summary.add(out)
        if progress is not None:
            progress(summary.cycles, source.n_frames)
    summary.sim = source.result()
    return summary


def run_scenario(
    config: SafecaseConfig,
    name: str | None = None,
    seed: int | None = None,
    duration_s: float | None = None,
    *,
    audit_path: Path | None = None,
    params: StoppingParams | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured_clock: bool = False,
) -> RunSummary:
    """A named scenario (default ``sim.scenario``) in closed loop, optionally audited."""
    sim = make_simulation(config, name, seed, duration_s)
    return run_simulation(
        config,
        sim,
        params=params,
        audit_path=audit_path,
        progress=progress,
        measured_clock=measured_clock,
    )
