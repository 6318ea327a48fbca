"""Soak runs of the runtime: resident memory and cycle time over long runs (SR-RUN-5).

:func:`patrol_spec` is a scene that stays busy for as long as it runs: the robot shuttles up
and down a warehouse aisle's lane, a forklift shuttles in the other lane (driving forward,
stopping, reversing back: every shuttle is a forklift reversal) and a person paces in a cross
aisle; no object ever enters the robot's lane, so no contact ends the run early. Its random
parameters (speeds, dwell times, start positions) come from the generator given.

:func:`soak_simulation` runs it through the runtime in closed loop
(:func:`safety.run.run_simulation`, bounded retention) and :func:`soak_device` serves a
scenario's scans from the RPLIDAR emulator on a pty and reads them back through the serial
driver (:class:`~pipeline.sources.serial.source.EmulatedSource`); both sample the process's
resident set size (``VmRSS`` of ``/proc/self/status``) every ``every`` cycles and time every
cycle, simulator or driver included: its wall time and the main thread's CPU time (which other
processes on the machine do not inflate by preempting it). Buffers are allocated before the
run, so the measurement itself does not grow.
"""

from __future__ import annotations

import ctypes
import itertools
import math
import resource
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.config import SafecaseConfig, overridden
from pipeline.sources.serial.source import EmulatedSource
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import Route
from pipeline.sources.sim.layouts import warehouse_aisle
from pipeline.sources.sim.objects import counterbalance_forklift, person
from pipeline.sources.sim.scenarios import ScenarioSpec, place, simulation_for_spec
from pipeline.sources.sim.simulation import BOUNDED
from pipeline.sources.sim.world import World
from pipeline.types import FloatArray, Scan
from safety.run import run_audited, run_simulation

__all__ = [
    "SOAK_FILE",
    "Soak",
    "SoakCall",
    "patrol_spec",
    "rss_mb",
    "soak_calls",
    "soak_device",
    "soak_simulation",
]

_STATUS = Path("/proc/self/status")
_LANE_Y_M = -0.7  # the robot's lane; the forklift's is at +0.95 (3.5 m aisle)
_AISLE_X_M = (1.0, 27.0)  # where the robot turns round
_MAX_SPEED_MPS = 2.0  # the route is long enough for a robot this fast

SOAK_FILE = "test_soak.py"  # the tests that take these figures
# By profile; any other: SHORT_SIM_CYCLES / SHORT_DEVICE_SCANS. certify-full: one simulated hour
# at 10 Hz and 30,000 scans; certify: a quarter of an hour and 10,000 scans (its half-hour).
SIM_CYCLES = {"certify-full": 36_000, "certify": 9_000}
DEVICE_SCANS = {"certify-full": 30_000, "certify": 10_000}
SHORT_SIM_CYCLES, SHORT_DEVICE_SCANS = 1_200, 300
DEVICE_RATE_HZ = 40.0  # the fastest the driver and the runtime take every scan on 2 cores
SEED = 20_240_601
# Cycles before the bounds apply, at least (10 % of a longer run): caches, the classifier, the
# allocator's arenas, and in the patrol the robot's first turn at the aisle's far end (cycles
# 363-425 of the 1,200-cycle run at SEED), where the swept-path check meets the racking of the
# aisle's end and its scratch (safety.geometry.sat, bounded by its chunks) grows by 2-5 MB,
# which a warm-up of 100 cycles counted as growth.
PATROL_WARMUP_CYCLES = 450
DEVICE_WARMUP_SCANS = 100


def _load_libc() -> ctypes.CDLL | None:
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.malloc_trim.argtypes = [ctypes.c_size_t]
    except (OSError, AttributeError):  # not glibc: RSS as the allocator leaves it
        return None
    return libc


_LIBC = _load_libc()


def _trim() -> None:
    """Give the C allocator's free pages back to the system (glibc's ``malloc_trim``), so that
    the RSS follows the memory in use: freed memory kept by the allocator would otherwise hide
    new allocations until it is used up (an early transient of 50-100 MB hides a growth of
    50 KB a cycle for a thousand cycles)."""
    if _LIBC is not None:
        _LIBC.malloc_trim(0)


def rss_mb() -> float:
    """The process's resident set size [MB] now (``VmRSS``, after :func:`_trim`); where
    ``/proc`` is missing, the peak so far (``ru_maxrss``), which cannot show a decrease."""
    _trim()
    try:
        for line in _STATUS.read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _shuttle(
    rng: np.random.Generator, speed_mps: float, run_s: float, duration_s: float
) -> mo.Motion:
    """Forward ``run_s`` at ``speed_mps``, stop, dwell, the same distance backwards, stop,
    dwell, again until ``duration_s``: it ends where it started every round. Braking and
    accelerating at 1 m/s^2; dwells of 0.5-3 s drawn from ``rng``."""
    ramp = speed_mps  # at 1 m/s^2
    t, kt, kv = 0.0, [0.0], [0.0]
    sign = 1.0
    while t < duration_s:
        for v in (sign * speed_mps, sign * speed_mps, 0.0):
            t += ramp if v != kv[-1] else run_s
            kt.append(t)
            kv.append(v)
        t += float(rng.uniform(0.5, 3.0))
        kt.append(t)
        kv.append(0.0)
        sign = -sign
    return mo.Motion(np.array(kt), np.array(kv), np.zeros(1), np.zeros(1), "shuttle")


def patrol_spec(rng: np.random.Generator, duration_s: float) -> ScenarioSpec:
    """The busy scene of the module docstring, for ``duration_s`` seconds."""
    layout = warehouse_aisle(rng, cross_aisles_m=((12.6, 15.6),))
    fork_speed = float(rng.uniform(0.8, 1.4))
    fork = place(
        1,
        "forklift_shuttle",
        counterbalance_forklift(),
        _shuttle(rng, fork_speed, float(rng.uniform(8.0, 12.0)) / fork_speed, duration_s),
        (float(rng.uniform(4.0, 8.0)), 0.95, 0.0),
        duration_s,
    )
    walk = float(rng.uniform(0.8, 1.2))
    pacer = place(
        2,
        "person_pacing",
        person(),
        # 2 m each way (ramps included): y -5 .. -3, short of the rack face at -1.75 m.
        _shuttle(rng, walk, (2.0 - walk**2) / walk, duration_s),
        (14.1, -5.0, math.pi / 2),
        duration_s,
    )
    world = World("soak_patrol", layout.structure, (fork, pacer), layout.bounds_m)
    lo, hi = _AISLE_X_M
    laps = math.ceil(duration_s * _MAX_SPEED_MPS / (hi - lo)) + 1  # more than it can drive
    xs = np.where(np.arange(laps + 1) % 2 == 0, lo, hi)
    route = Route(np.column_stack([xs, np.full(xs.size, _LANE_Y_M)]))
    return ScenarioSpec(world, route)


@dataclass(frozen=True)
class Soak:
    """One soak run: ``rss_cycle`` / ``rss_mb`` sampled every few cycles; ``wall_s`` and
    ``cpu_s`` the wall time and the main thread's CPU time [s] of every cycle (the simulator
    or the serial driver with the runtime); ``run_s`` the whole run's wall time [s];
    ``warmup`` the cycles before the bounds apply (``max(scene's warm-up, 10 %)``)."""

    label: str
    cycles: int
    warmup: int
    run_s: float
    rss_cycle: FloatArray
    rss_mb: FloatArray
    wall_s: FloatArray
    cpu_s: FloatArray
    actions: dict[str, int]

    def after(self, warmup: int) -> tuple[FloatArray, FloatArray]:
        """The RSS samples from cycle ``warmup`` on."""
        keep = self.rss_cycle >= warmup
        return self.rss_cycle[keep], self.rss_mb[keep]

    def growth_mb(self, warmup: int) -> float:
        """RSS growth [MB] after ``warmup`` cycles: the median of the last tenth of the samples
        less the median of the first tenth (medians: one sample's allocator noise is not
        growth)."""
        _, rss = self.after(warmup)
        tenth = max(1, rss.size // 10)
        return float(np.median(rss[-tenth:]) - np.median(rss[:tenth]))

    def slope_mb_per_h(self, warmup: int, cycles_per_h: float = 36_000.0) -> float:
        """Least-squares RSS slope [MB per ``cycles_per_h`` cycles: an hour at 10 Hz]."""
        cycle, rss = self.after(warmup)
        if cycle.size < 2:
            return math.nan
        return float(np.polyfit(cycle, rss, 1)[0] * cycles_per_h)

    def tenth(self, which: str, part: str, start: int = 0) -> FloatArray:
        """The ``wall`` or ``cpu`` times [s] of the first tenth of the run's cycles (from
        cycle ``start``) or of the last tenth."""
        values = self.wall_s if which == "wall" else self.cpu_s
        n = max(1, self.cycles // 10)
        return values[start : start + n] if part == "first" else values[-n:]

    def ms(self, which: str, part: str, start: int = 0) -> tuple[float, float]:
        """p50 and p99 [ms] of :meth:`tenth`."""
        span = self.tenth(which, part, start)
        return float(np.median(span) * 1e3), float(np.percentile(span, 99) * 1e3)


class _Probe:
    """Per-cycle timing and periodic RSS into buffers allocated up front."""

    def __init__(self, n_cycles: int, every: int) -> None:
        self.every = every
        self.wall_s = np.full(n_cycles, np.nan)
        self.cpu_s = np.full(n_cycles, np.nan)
        self.rss_cycle = np.full(n_cycles // every + 2, np.nan)
        self.rss_mb = np.full(n_cycles // every + 2, np.nan)
        self.n = 0
        self.k = 0
        self.sample()
        self.start = self.last = time.perf_counter()
        self.last_cpu = time.thread_time()

    def sample(self) -> None:
        self.rss_cycle[self.k] = self.n
        self.rss_mb[self.k] = rss_mb()
        self.k += 1

    def tick(self) -> None:
        """One cycle done (an RSS sample, when due, is charged to no cycle)."""
        now, cpu = time.perf_counter(), time.thread_time()
        if self.n < self.wall_s.size:
            self.wall_s[self.n] = now - self.last
            self.cpu_s[self.n] = cpu - self.last_cpu
        self.n += 1
        if self.n % self.every == 0 and self.k < self.rss_mb.size:
            self.sample()
        self.last, self.last_cpu = time.perf_counter(), time.thread_time()

    def result(self, label: str, actions: dict[str, int], warmup: int) -> Soak:
        n = min(self.n, self.wall_s.size)
        return Soak(
            label,
            self.n,
            max(warmup, self.n // 10),
            self.last - self.start,
            self.rss_cycle[: self.k].copy(),
            self.rss_mb[: self.k].copy(),
            self.wall_s[:n].copy(),
            self.cpu_s[:n].copy(),
            actions,
        )


def soak_simulation(config: SafecaseConfig, seed: int, cycles: int, every: int) -> Soak:
    """``cycles`` scans of :func:`patrol_spec` (seeded by ``seed``) through the runtime in
    closed loop, bounded retention; RSS every ``every`` cycles."""
    period = 1.0 / config.sim.scan_rate_hz
    duration = cycles * period
    spec = patrol_spec(np.random.default_rng(seed), duration)
    sim = simulation_for_spec(config, spec, "soak_patrol", seed, duration, retention=BOUNDED)
    probe = _Probe(sim.n_scans, every)

    def progress(done: int, total: int) -> None:
        probe.tick()

    summary = run_simulation(config, sim, progress=progress)
    label = f"simulator, {config.sim.scan_rate_hz:g} Hz"
    return probe.result(label, dict(summary.actions), PATROL_WARMUP_CYCLES)


def _pool(config: SafecaseConfig, seed: int, n: int) -> list[Scan]:
    """``n`` scans of :func:`patrol_spec` (bounded retention: only the scans are kept)."""
    duration = n / config.sim.scan_rate_hz
    spec = patrol_spec(np.random.default_rng(seed), duration)
    sim = simulation_for_spec(config, spec, "soak_patrol", seed, duration, retention=BOUNDED)
    return list(sim.scans())


def soak_device(
    config: SafecaseConfig, seed: int, scans: int, every: int, rate_hz: float, pool: int = 600
) -> Soak:
    """``scans`` scans served by the RPLIDAR emulator on a pty at ``rate_hz`` and read through
    the serial driver, each decided by the runtime; RSS every ``every`` cycles (a cycle without
    a scan counts too). The scans are ``pool`` scans of :func:`patrol_spec` (robot standing,
    the RPLIDAR A2's layout) made before the run and served round and round, so the device
    path alone is measured. A cycle's wall time is mostly the wait for the next scan; its
    CPU time is the driver's and the runtime's work."""
    bench = overridden(config, {"sim": {"ego_speed_mps": 0.0, "lidar_device": "rplidar_a2"}})
    driver = bench.driver.model_copy(update={"protocol": "rplidar", "port_url": "emulated"})
    served = itertools.cycle(_pool(bench, seed, min(pool, scans)))
    source = EmulatedSource(driver, bench.track.frame_period_s, served, rate_hz)
    probe = _Probe(2 * scans, every)
    actions: dict[str, int] = {}
    for out in run_audited(bench, source, audit_path=None, max_scans=scans):
        probe.tick()
        key = out.command.action.value
        actions[key] = actions.get(key, 0) + 1
    label = f"RPLIDAR emulator on a pty, {rate_hz:g} Hz"
    return probe.result(label, actions, DEVICE_WARMUP_SCANS)


SoakCall = tuple[Callable[..., Soak], tuple[Any, ...]]


def soak_calls(config: SafecaseConfig, profile: str) -> tuple[SoakCall, SoakCall]:
    """The simulator soak and the device soak ``profile`` runs, as (function, arguments): one
    simulated hour and 30,000 scans under certify-full, 9,000 cycles and 10,000 scans under
    certify, 1,200 cycles and 300 scans otherwise."""
    cycles = SIM_CYCLES.get(profile, SHORT_SIM_CYCLES)
    scans = DEVICE_SCANS.get(profile, SHORT_DEVICE_SCANS)
    return (
        (soak_simulation, (config, SEED, cycles, max(10, cycles // 400))),
        (soak_device, (config, SEED, scans, max(10, scans // 400), DEVICE_RATE_HZ)),
    )
