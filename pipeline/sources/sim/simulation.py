"""The closed loop: world, scanner and ego robot stepped together (SR-SIM-2, SR-SIM-5).

Time advances in fixed steps (``step_s`` rounded so that a whole number of steps makes one
scan period). Scan ``k`` starts at ``k * scan_period_s`` and is delivered, with its ground
truth, when its revolution is complete at ``(k + 1) * scan_period_s``; the policy then
returns a speed command, which takes effect after the actuation latency. At every step the
distance from the ego footprint to each object is measured; the minimum per object is kept
and any contact (distance 0) is recorded and halts the robot.

:meth:`Simulation.next_frame` / :meth:`Simulation.command` let an outside loop (the runtime)
drive the simulation; :meth:`Simulation.run` does it with a policy callable.

What a run keeps for its :class:`SimResult` is its :class:`Retention`: :data:`FULL` (the
default) keeps every frame, every step of the ego log and every scan's separations, for
analysis, datasets and pictures of short runs; :data:`BOUNDED` keeps no frames and at most
``max_rows`` evenly thinned rows of the ego log and of the separations, with the steps each
contact's speed is read from pinned, so a closed-loop run of any length holds a bounded
record (SR-RUN-5). The minimum separations and contact times are exact under both, and both
produce the same scans, ground truth and ego motion bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from pipeline.sources.sim.ego import Ego, EgoObservation, EgoSpec, SpeedPolicy
from pipeline.sources.sim.history import ThinnedRows
from pipeline.sources.sim.lidar import Lidar, LidarSpec
from pipeline.sources.sim.shapes import outline_distances, pose_points
from pipeline.sources.sim.truth import LabelRules, ScanTruth, scan_truth
from pipeline.sources.sim.world import World
from pipeline.types import FloatArray, IntArray, Scan

__all__ = ["BOUNDED", "FULL", "Retention", "SimFrame", "SimResult", "Simulation"]


@dataclass(frozen=True, slots=True)
class Retention:
    """What a run keeps for its result (module docstring). ``frames``: every delivered
    :class:`SimFrame`. ``max_rows``: None keeps every step of the ego log and every scan's
    separations; a number keeps at most that many of each (evenly thinned), plus the pinned
    contact steps and the newest."""

    frames: bool = True
    max_rows: int | None = None

    def __post_init__(self) -> None:
        if self.max_rows is not None and (self.max_rows < 2 or self.max_rows % 2):
            raise ValueError(f"Retention: max_rows must be even and >= 2, got {self.max_rows}")


FULL = Retention()
BOUNDED = Retention(frames=False, max_rows=8192)
"""At 100 steps/s every step of the first 81 s is kept; a 1 h run keeps one step in 64."""


@dataclass(frozen=True, slots=True)
class SimFrame:
    """One delivered scan, its ground truth and the observation handed to the policy."""

    scan: Scan
    truth: ScanTruth
    observation: EgoObservation


@dataclass(frozen=True)
class SimResult:
    """A finished run. Per-object arrays follow :attr:`World.objects`; ``contact_time_s`` is
    NaN for objects never touched. ``separation_m`` ``(F, N)`` samples the ego-to-object
    distance at the end of every scan (times ``separation_t_s``); the minima are over every
    step. With ``stop_at_contact`` (the default) a run ends with the scan during which the
    first contact happened. ``frames``, ``ego_log`` and the separation samples are what the
    run's :class:`Retention` kept: all of them, or no frames and a thinned log whose samples
    include the steps before and at every contact."""

    name: str
    seed: int
    world: World
    ego_spec: EgoSpec
    label_rules: LabelRules
    frames: tuple[SimFrame, ...]
    ego_log: dict[str, FloatArray]
    decel_mps2: float
    min_separation_m: FloatArray
    min_separation_time_s: FloatArray
    contact_time_s: FloatArray
    separation_t_s: FloatArray
    separation_m: FloatArray

    @property
    def contact(self) -> bool:
        """Whether the ego touched any object."""
        return bool(np.isfinite(self.contact_time_s).any())


class Simulation:
    """One seeded run of a world with an ego robot and its scanner; ``retention`` is what its
    result keeps (module docstring); ``weather`` names the weather preset the run is set in
    (:data:`pipeline.sources.sim.weather.WEATHER_PRESETS`; None: not stated), for the sensors
    simulated beside it (the scanner given here is already degraded by it)."""

    def __init__(
        self,
        world: World,
        ego: EgoSpec,
        lidar: LidarSpec,
        *,
        rng: np.random.Generator,
        duration_s: float,
        step_s: float,
        rules: LabelRules,
        name: str = "",
        seed: int = 0,
        stop_at_contact: bool = True,
        retention: Retention = FULL,
        weather: str | None = None,
    ) -> None:
        if duration_s <= 0 or step_s <= 0:
            raise ValueError(
                f"Simulation: duration and step must be > 0, got {duration_s}, {step_s}"
            )
        self.world = world
        self.ego_spec = ego
        self.lidar = Lidar(lidar, rng)
        self.rules = rules
        self.name = name
        self.seed = seed
        self.weather = weather
        self.duration_s = float(duration_s)
        self.stop_at_contact = stop_at_contact
        self.steps_per_scan = max(1, round(lidar.scan_period_s / step_s))
        self.dt_s = lidar.scan_period_s / self.steps_per_scan
        n_scans = int(np.floor(self.duration_s / lidar.scan_period_s + 1e-9))
        self.n_scans = n_scans
        self._footprint = ego.footprint()
        n = len(world.objects)
        self._min_sep = np.full(n, np.inf)
        self._min_sep_t = np.full(n, np.nan)
        self._contact_t = np.full(n, np.nan)
        self._k = 0
        self._frames: list[SimFrame] = []
        self._retain(retention)
        if world.objects:
            t0 = np.array([0.0])
            self._record(t0, self._distances(t0, world.object_vertices(t0)), np.zeros(1, int))

    @property
    def retention(self) -> Retention:
        """What the run keeps for its result."""
        return self._retention

    def retain(self, retention: Retention) -> None:
        """Keep ``retention`` instead; only before the first scan."""
        if self._k or self._ego.steps_done:
            raise ValueError("Simulation.retain: the run has started")
        self._retain(retention)
        if np.isfinite(self._contact_t).any():
            self._ego.pin(0)  # a contact at the start, found before this retention

    def _retain(self, retention: Retention) -> None:
        self._retention = retention
        n_steps = self.n_scans * self.steps_per_scan
        self._sep_full: list[FloatArray] = []
        self._sep_rows: ThinnedRows | None = None
        if retention.max_rows is None:
            self._ego = Ego(self.ego_spec, self.dt_s, n_steps)
        else:
            self._sep_rows = ThinnedRows(1 + len(self.world.objects), retention.max_rows)
            # Interpolation reaches back one scan (a scan's stamp and beams); four are kept.
            window = 4 * self.steps_per_scan
            self._ego = Ego(
                self.ego_spec, self.dt_s, n_steps, window_steps=window, log_rows=retention.max_rows
            )

    @property
    def ego(self) -> Ego:
        """The ego robot's state."""
        return self._ego

    def _distances(self, t_s: FloatArray, object_vertices: FloatArray) -> FloatArray:
        """Ego-to-object distances ``(T, N)`` at past step times ``t_s`` given every object's
        posed vertices ``(T, V, 2)`` then."""
        robot = self._ego.poses_at(t_s)
        fp = self._footprint
        ego_verts = pose_points(fp.vertices_m, robot[:, 0], robot[:, 1], robot[:, 2])
        return outline_distances(
            ego_verts,
            fp,
            object_vertices,
            self.world.dynamic_outline,
            self.world.part_owner,
            len(self.world.objects),
        )

    def _record(self, t_s: FloatArray, dist: FloatArray, steps: IntArray) -> None:
        """Fold distances ``(T, N)`` at times ``t_s`` (ego steps ``steps``) into the
        separation and contact record; the ego log keeps each contact's step and the one
        before it (the robot's speed at the contact is read from them)."""
        for k in range(t_s.shape[0]):
            d = dist[k]
            better = d < self._min_sep
            self._min_sep[better] = d[better]
            self._min_sep_t[better] = t_s[k]
            touched = (d <= 0.0) & np.isnan(self._contact_t)
            self._contact_t[touched] = t_s[k]
            if touched.any():
                step = int(steps[k])
                self._ego.pin(step)
                if step:
                    self._ego.pin(step - 1)

    def _separation(self, t_s: float, dist: FloatArray) -> None:
        """Keep one scan's separation sample."""
        row = np.concatenate([[t_s], dist])
        if self._sep_rows is None:
            self._sep_full.append(row)
        else:
            self._sep_rows.append(row)

    def command(self, speed_mps: float) -> None:
        """Command a speed now (it takes effect after the actuation latency)."""
        self._ego.command(speed_mps, self._ego.time_s)

    def next_frame(self) -> SimFrame | None:
        """Advance to the end of the next scan's revolution; None when the run is over."""
        if self._k >= self.n_scans:
            return None
        if self.stop_at_contact and np.isfinite(self._contact_t).any():
            return None  # past a contact objects may drive through the robot and its scanner
        k = self._k
        period = self.lidar.spec.scan_period_s
        n0 = self._ego.steps_done
        for _ in range(self.steps_per_scan):
            self._ego.step()
        if self.world.objects:
            # The distance is checked at every step; it is computed for the steps of a whole
            # scan at once, and on a contact the robot is rewound to that step and halted.
            steps = n0 + np.arange(1, self.steps_per_scan + 1)
            step_t: FloatArray = self.dt_s * steps.astype(np.float64)
            verts = self.world.object_vertices(step_t)
            dist = self._distances(step_t, verts)
            hit_rows = np.flatnonzero((dist <= 0.0).any(axis=1))
            if hit_rows.size and not self._ego.halted:
                j = int(hit_rows[0])
                self._record(step_t[: j + 1], dist[: j + 1], steps[: j + 1])
                self._ego.rewind(n0 + j + 1)
                self._ego.halt()
                for _ in range(self.steps_per_scan - j - 1):
                    self._ego.step()
                rest = step_t[j + 1 :]
                if rest.size:
                    dist = np.concatenate([dist[: j + 1], self._distances(rest, verts[j + 1 :])])
                    self._record(rest, dist[j + 1 :], steps[j + 1 :])
            else:
                self._record(step_t, dist, steps)
            self._separation(float(step_t[-1]), dist[-1])
        self._ego.commit()
        stamp = k * period
        spec = self.ego_spec

        def scanner_poses(t: FloatArray) -> FloatArray:
            return spec.scanner_poses(self._ego.poses_at(t))

        scan, beams = self.lidar.scan(
            self.world, scanner_poses, stamp, seq=k, source=f"sim:{self.name}:{self.seed}"
        )
        at_stamp = self._ego.poses_at(np.array([stamp]))
        truth = scan_truth(
            self.world,
            beams,
            scan.ranges_m,
            stamp_s=stamp,
            seq=k,
            scanner_pose=spec.scanner_poses(at_stamp)[0],
            ego_pose=at_stamp[0],
            ego_speed_mps=float(self._ego.speeds_at(np.array([stamp]))[0]),
            rules=self.rules,
        )
        obs = EgoObservation(
            stamp_s=self._ego.time_s,
            scan=scan,
            pose=self._ego.pose(),
            speed_mps=self._ego.speed_mps,
            truth=truth,
        )
        frame = SimFrame(scan=scan, truth=truth, observation=obs)
        if self._retention.frames:
            self._frames.append(frame)
        self._k += 1
        return frame

    def scans(self, policy: SpeedPolicy | None = None) -> Iterator[Scan]:
        """The run as a scan source: each scan as its revolution completes; ``policy`` (if
        given) is asked for a speed after each, otherwise the robot keeps its command."""
        while (frame := self.next_frame()) is not None:
            yield frame.scan
            if policy is not None:
                self.command(policy(frame.observation))

    def run(self, policy: SpeedPolicy) -> SimResult:
        """Run to the end, asking ``policy`` for a speed after every scan."""
        while (frame := self.next_frame()) is not None:
            self.command(policy(frame.observation))
        return self.result()

    def result(self) -> SimResult:
        """The run so far (what its :class:`Retention` kept)."""
        if self._sep_rows is None:
            sep = np.array(self._sep_full).reshape(-1, 1 + len(self.world.objects))
        else:
            sep = self._sep_rows.rows()[1]
        return SimResult(
            name=self.name,
            seed=self.seed,
            world=self.world,
            ego_spec=self.ego_spec,
            label_rules=self.rules,
            frames=tuple(self._frames),
            ego_log=self._ego.log(),
            decel_mps2=self.ego_spec.decel_mps2,
            min_separation_m=self._min_sep.copy(),
            min_separation_time_s=self._min_sep_t.copy(),
            contact_time_s=self._contact_t.copy(),
            separation_t_s=sep[:, 0].copy(),
            separation_m=sep[:, 1:].copy(),
        )
