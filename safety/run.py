"""The runtime on its sources: the simulator in closed loop, a serial scanner (SR-RUN-*).

:func:`run_scenario` drives a named (or given) simulator scenario with the runtime in the loop:
after every scan the runtime decides, and its command reaches the simulated robot at the
decision time (the scan's delivery plus the cycle's measured duration) plus the robot's
actuation latency. The robot's path ahead is its own route; its pose at the scan's stamp is its
odometry. The result holds the simulator's verdict (contacts, the robot's speed at each contact,
minimum separations, progress) and the runtime's (commands, reasons, stage timings).

:func:`run_device` reads a serial scanner (any pyserial URL: a device, a pty, ``socket://``)
with the robot standing still (identity pose, straight path ahead) and prints and logs a
command per scan.
"""

from __future__ import annotations

import contextlib
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pipeline.config import SafecaseConfig
from pipeline.drivers import Driver
from pipeline.sim.scenarios import make_simulation
from pipeline.sim.simulation import SimResult, Simulation
from pipeline.types import DriverState, FloatArray
from safety.audit import AuditWriter, BackgroundAuditWriter
from safety.path import PathAhead
from safety.runtime import CycleInput, CycleOutput, Runtime
from safety.stopping import StoppingParams

__all__ = ["RunSummary", "run_device", "run_scenario", "run_simulation"]


@dataclass
class RunSummary:
    """What a run did: the command mix, every distinct reason's count, per-stage wall-clock
    samples [s], the cycle durations [s] and, for a simulation, its result."""

    name: str
    cycles: int = 0
    actions: Counter[str] = field(default_factory=Counter)
    reasons: Counter[str] = field(default_factory=Counter)
    stage_s: dict[str, list[float]] = field(default_factory=dict)
    cycle_s: list[float] = field(default_factory=list)
    cpu_s: list[float] = field(default_factory=list)
    sim: SimResult | None = None
    audit_path: Path | None = None

    def add(self, out: CycleOutput) -> None:
        """Fold one cycle in."""
        self.cycles += 1
        self.actions[out.command.action.value] += 1
        for reason in out.command.reasons:
            self.reasons[_reason_kind(reason)] += 1
        for stage, dt in out.wall_s.items():
            self.stage_s.setdefault(stage, []).append(dt)
        self.cycle_s.append(float(out.record.observation.cycle_duration_s or 0.0))
        self.cpu_s.append(out.cpu_s)

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


def run_simulation(
    config: SafecaseConfig,
    sim: Simulation,
    *,
    params: StoppingParams | None = None,
    writer: AuditWriter | None = None,
    runtime: Runtime | None = None,
    progress: Callable[[int, int], None] | None = None,
    measured_clock: bool = False,
) -> RunSummary:
    """Run ``sim`` to its end with the runtime deciding after every scan (module docstring).

    Each cycle takes ``runtime.sim_cycle_s`` on the simulated clock (reproducible whatever the
    machine's load), or its measured duration with ``measured_clock``.
    """
    rt = runtime if runtime is not None else Runtime(config, params=params, writer=writer)
    summary = RunSummary(sim.name)
    route = sim.ego_spec.route
    rc = config.runtime
    charge_s = None if measured_clock else rc.sim_cycle_s
    sim.command(sim.ego_spec.initial_speed_mps)
    busy_until = -np.inf
    while (frame := sim.next_frame()) is not None:
        # A scan that arrives while the previous cycle still runs waits for it.
        delivered = max(frame.observation.stamp_s, busy_until)
        at_stamp = sim.ego.poses_at(np.array([frame.scan.stamp_s]))[0]
        path = PathAhead.along_polyline(
            route.points_m, sim.ego.arc_m, rc.path_lookahead_m, rc.path_step_m
        )
        out = rt.step(
            CycleInput(
                scan=frame.scan,
                now_s=delivered,
                robot_pose=(float(at_stamp[0]), float(at_stamp[1]), float(at_stamp[2])),
                path=path,
                charge_s=charge_s,
            )
        )
        issued = busy_until = out.record.observation.now_s
        sim.ego.command(out.command.speed_mps, issued)
        summary.add(out)
        if progress is not None:
            progress(summary.cycles, sim.n_scans)
    summary.sim = sim.result()
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
    rt = Runtime(config, params=params)
    with contextlib.ExitStack() as stack:
        if audit_path is not None:
            rt.writer = stack.enter_context(
                AuditWriter(
                    audit_path, config, model_hash=rt.classifier.model_sha256, params=rt.params
                )
            )
        summary = run_simulation(
            config, sim, runtime=rt, progress=progress, measured_clock=measured_clock
        )
    summary.audit_path = audit_path
    return summary


def run_device(
    config: SafecaseConfig,
    url: str,
    *,
    audit_path: Path,
    max_scans: int | None = None,
    clock: Callable[[], float] | None = None,
) -> Iterator[CycleOutput]:
    """Cycles over a serial scanner at ``url`` (robot standing still; module docstring).

    One cycle per received revolution (the newest, when several arrived at once); while none
    arrives, one cycle without a scan every ``track.frame_period_s``, which the monitors turn
    into STOP with the driver's state as the reason. Ends after ``max_scans`` scans or once the
    driver has given up (FAILED).
    """
    now = clock or time.monotonic
    params = StoppingParams.from_config(config)
    rt = Runtime(config, params=params)
    driver_config = config.driver.model_copy(update={"port_url": url})
    with (
        AuditWriter(
            audit_path, config, model_hash=rt.classifier.model_sha256, params=params
        ) as writer,
        Driver(driver_config, clock=now) as driver,
    ):
        # fsync stalls of 15-100 ms here: the log is written off the cycle's thread.
        background = BackgroundAuditWriter(writer)
        rt.writer = background
        try:
            yield from _device_cycles(rt, driver, config, now, max_scans)
        finally:
            background.close()


def _device_cycles(
    rt: Runtime,
    driver: Driver,
    config: SafecaseConfig,
    now: Callable[[], float],
    max_scans: int | None,
) -> Iterator[CycleOutput]:
    """The device loop of :func:`run_device`."""
    period = config.track.frame_period_s
    n = 0
    last = now()
    while max_scans is None or n < max_scans:
        scans = driver.poll(period)
        t = now()
        if not scans and t - last < period:
            time.sleep(min(period - (t - last), 0.01))
            continue
        last = t
        scan = scans[-1] if scans else None
        health = driver.health(t)
        yield rt.step(CycleInput.standing(scan, t, config, driver=health))
        n += scan is not None
        if health.state is DriverState.FAILED:
            return
