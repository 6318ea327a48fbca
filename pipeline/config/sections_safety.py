"""Configuration sections of the safety stages (stopping model to audit log)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from pipeline.compat import Self
from pipeline.config.base import Section

ClosingClassName = Literal["static", "person", "forklift_reversing"]


class StoppingSection(Section):
    """Stopping-distance model, margin tiers and their speed caps (SR-STOP-*).

    Braking 0.2-0.4 m at 1.0 m/s in the source gives b = v^2 / (2 d) in [1.25, 2.5] m/s^2.
    The reaction latency is ``perception_latency_s + control_cycle_s``; ``latency_source``
    records where the perception bound came from (a measured p99/pWCET later). Each tier's
    margin must absorb the closing speed of its ``closing_class_*`` during the whole stop. The
    default speed caps are the largest speeds each tier's margin covers in the worst case
    (computed and proved by properties/test_stopping.py), rounded down to 1 mm/s.
    """

    # The largest age of the scan's first beam at decision time (SR-STOP-5): one revolution
    # (0.1 s at 10 Hz: the first beam is that old when the scan completes) plus the source's
    # 80 ms p99 processing latency. The scan-freshness monitor enforces it.
    perception_latency_s: float = Field(0.18, ge=0.0, le=2.0)
    latency_source: str = Field("config", description="where perception_latency_s came from")
    control_cycle_s: float = Field(0.1, gt=0.0, le=1.0)
    decel_min_mps2: float = Field(1.25, gt=0.0, le=20.0)
    decel_max_mps2: float = Field(2.5, gt=0.0, le=20.0)
    accel_max_mps2: float = Field(0.5, ge=0.0, le=20.0)
    robot_max_speed_mps: float = Field(1.0, gt=0.0, le=10.0)
    margin_high_m: float = Field(0.4, ge=0.0, le=20.0)
    margin_medium_m: float = Field(0.7, ge=0.0, le=20.0)
    margin_near_reversal_m: float = Field(1.0, ge=0.0, le=20.0)
    speed_cap_high_mps: float = Field(0.592, ge=0.0, le=10.0)
    speed_cap_medium_mps: float = Field(0.896, ge=0.0, le=10.0)
    speed_cap_near_reversal_mps: float = Field(0.651, ge=0.0, le=10.0)
    closing_class_high: ClosingClassName = "static"
    closing_class_medium: ClosingClassName = "static"
    closing_class_near_reversal: ClosingClassName = "forklift_reversing"
    person_speed_mps: float = Field(1.6, ge=0.0, le=10.0)
    forklift_reversing_speed_mps: float = Field(0.6, ge=0.0, le=10.0)
    static_speed_mps: float = Field(0.0, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.decel_min_mps2 > self.decel_max_mps2:
            raise ValueError(
                f"stopping.decel_min_mps2 ({self.decel_min_mps2}) must not exceed "
                f"stopping.decel_max_mps2 ({self.decel_max_mps2})"
            )
        return self


class GovernorSection(Section):
    """Speed governor (SR-STOP-2): a speed below ``min_moving_speed_mps`` becomes STOP."""

    min_moving_speed_mps: float = Field(0.05, ge=0.0, le=1.0)


class GeometrySection(Section):
    """Swept-path collision checking (SR-SAT-*).

    ``contact_tolerance_m``: pairs separated by at most this along every edge normal count as
    colliding (the tolerance band). ``pregate_m``: envelopes farther than this from the robot
    (and than any swept hull reaches) are not checked. Candidate trajectories: a grid of
    ``n_speeds`` x ``n_yaw_rates`` = ``n_trajectories`` constant arcs over ``horizon_s``,
    sampled every ``sample_dt_s``; the footprint is a ``footprint_length_m`` x
    ``footprint_width_m`` rectangle.
    """

    pregate_m: float = Field(20.0, gt=0.0, le=1000.0)
    sample_dt_s: float = Field(0.1, gt=0.0, le=1.0)
    n_trajectories: int = Field(175, ge=1, le=10_000)
    max_vertices: int = Field(32, ge=3, le=1024)
    contact_tolerance_m: float = Field(1e-9, ge=0.0, le=1e-3)
    horizon_s: float = Field(1.5, gt=0.0, le=10.0)
    n_speeds: int = Field(7, ge=1, le=100)
    n_yaw_rates: int = Field(25, ge=1, le=1000)
    max_yaw_rate_radps: float = Field(1.0, ge=0.0, le=10.0)
    footprint_length_m: float = Field(0.9, gt=0.0, le=20.0)
    footprint_width_m: float = Field(0.6, gt=0.0, le=20.0)
    max_obstacles: int = Field(64, ge=1, le=10_000)

    @model_validator(mode="after")
    def _grid(self) -> Self:
        if self.n_speeds * self.n_yaw_rates != self.n_trajectories:
            raise ValueError(
                f"geometry.n_speeds ({self.n_speeds}) x geometry.n_yaw_rates "
                f"({self.n_yaw_rates}) must equal geometry.n_trajectories ({self.n_trajectories})"
            )
        return self


# The largest costmap grid [cells]: 2000 x 2000 (100 m x 100 m at 5 cm).
MAX_COSTMAP_CELLS = 4_000_000
# The most samples of the path ahead per cycle: 100 m at 2.5 cm.
MAX_PATH_SAMPLES = 4_000


class CostmapSection(Section):
    """Grid costmap of envelopes (SR-PRED-2).

    A ``width_m`` x ``height_m`` grid of square cells of ``resolution_m``, centred on
    (``centre_x_m``, ``centre_y_m``) in the envelopes' frame. A cell is marked when it touches an
    envelope; ``contact_tolerance_m`` widens "touches" to absorb rounding (conservative).
    """

    resolution_m: float = Field(0.05, gt=0.0, le=1.0)
    width_m: float = Field(20.0, gt=0.0, le=500.0)
    height_m: float = Field(20.0, gt=0.0, le=500.0)
    centre_x_m: float = Field(0.0, ge=-1000.0, le=1000.0)
    centre_y_m: float = Field(0.0, ge=-1000.0, le=1000.0)
    contact_tolerance_m: float = Field(1e-9, ge=0.0, le=1e-3)

    @model_validator(mode="after")
    def _bounded_grid(self) -> Self:
        # SR-TIM-3: the grid is rasterized every cycle, so its size is bounded work.
        cells = (self.width_m / self.resolution_m) * (self.height_m / self.resolution_m)
        if not cells <= MAX_COSTMAP_CELLS:
            raise ValueError(
                f"costmap.width_m x costmap.height_m at costmap.resolution_m ({self.width_m} x "
                f"{self.height_m} m at {self.resolution_m} m) makes {cells:.4g} cells; allowed: "
                f"at most {MAX_COSTMAP_CELLS}"
            )
        return self


class MonitorSection(Section):
    """Runtime monitors: staleness, clock, deadline, operating domain (SR-FUS-2, SR-TIM-2).

    STOP when the scan's first beam is older than ``scan_max_age_s`` at decision time (or
    stamped more than ``clock_skew_s`` in the future), when the decision clock runs back by
    more than ``max_clock_jump_back_s``, when a cycle takes longer than ``cycle_deadline_s``,
    when more than ``max_blocked_fraction`` of the beams read below the minimum range (a
    covered window) or when any per-cycle cap dropped something. An incomplete scan (frames
    rejected by the driver) limits the speed to ``degraded_speed_mps``. Under a STOP, a robot
    that decelerates at less than ``braking_tolerance`` times ``stopping.decel_min_mps2``
    (measured from odometry: the stopping proof's braking assumption) is recorded as a STOP of
    the ``braking`` monitor.
    """

    scan_max_age_s: float = Field(0.18, gt=0.0, le=10.0)
    cycle_deadline_s: float = Field(0.1, gt=0.0, le=10.0)
    max_clock_jump_back_s: float = Field(0.0, ge=0.0, le=10.0)
    clock_skew_s: float = Field(0.0, ge=0.0, le=1.0)
    max_blocked_fraction: float = Field(0.5, ge=0.0, le=1.0)
    degraded_speed_mps: float = Field(0.3, ge=0.0, le=10.0)
    braking_tolerance: float = Field(0.8, gt=0.0, le=1.0)

    @model_validator(mode="after")
    def _skew_below_age(self) -> Self:
        if self.clock_skew_s >= self.scan_max_age_s:
            raise ValueError(
                f"monitors.clock_skew_s ({self.clock_skew_s}) must be below "
                f"monitors.scan_max_age_s ({self.scan_max_age_s}): otherwise no scan is fresh"
            )
        return self


class AuditSection(Section):
    """Hash-chained audit log (SR-AUD-*): one JSON line per cycle, see :mod:`safety.audit.log`.

    The log is fsynced, and its head anchor rewritten, every ``fsync_every_records`` records and
    at close. ``sign_head`` true: ``safecase run`` signs the anchor with Ed25519. The key is
    ``signing_key``, a PEM file that must exist (never created: a mistyped path is an error
    naming it when the run starts, before any cycle); empty, the default key that also signs
    evidence bundles (``$SAFECASE_SIGNING_KEY`` or ``~/.config/safecase/signing-key.pem``),
    created on first use. ``signing_key`` is read only when ``sign_head`` is true.
    """

    log_dir: str = "out/audit"
    fsync_every_records: int = Field(10, ge=1, le=1_000_000)
    sign_head: bool = False
    signing_key: str = Field(
        "",
        description="Ed25519 PEM key that signs the head when sign_head is true; it must "
        "exist. Empty: the default evidence key, created on first use",
    )


class RuntimeSection(Section):
    """The cycle loop (SR-RUN-*): path clearance, optional planner and costmap stages.

    The governor's free distances are measured along the robot's path ahead, sampled every
    ``path_step_m`` up to ``path_lookahead_m`` (:mod:`safety.geometry.path`); the lookahead should
    cover the stopping distance at the robot's maximum speed against the fastest closing class, or
    the governor holds the robot below that speed. Thermal-only pedestrians are discs of
    ``person_radius_m``. Scan points on the path outside every kept cluster close in at the fastest
    class's speed (``loose_points = "worst"``, the default): they may be a moving object that
    clustering merged with structure into a cluster too large to keep (a forklift beside racking
    did exactly that in a campaign, SR-RUN-8). ``"static"`` (closing speed
    ``stopping.static_speed_mps``) is sound only where every such point is fixed structure.
    ``planner_check`` and ``costmap`` run the swept-path check of the
    candidate grid and the costmap every cycle (recorded, for a planner; the candidate grid costs
    10-30 ms here, so it is off by default). In closed-loop simulation every cycle takes
    ``sim_cycle_s`` on the simulated clock, and ``sim_sensors`` names the simulated sensors run
    beside the LiDAR (``"thermal"``: the LWIR camera and its detector, ``"radar"``: the radar;
    :mod:`pipeline.sources.sim.sensors_source`, SR-FUS-9); none by default.
    """

    path_lookahead_m: float = Field(6.0, gt=0.0, le=100.0)
    path_step_m: float = Field(0.05, gt=0.0, le=1.0)
    person_radius_m: float = Field(0.3, gt=0.0, le=2.0)
    loose_points: Literal["static", "worst"] = "worst"
    planner_check: bool = False
    costmap: bool = True
    sim_cycle_s: float = Field(0.05, ge=0.0, le=1.0)
    # Lax for this field alone: TOML gives a list, the section keeps a tuple (frozen, hashable).
    sim_sensors: tuple[Literal["thermal", "radar"], ...] = Field((), strict=False)

    @model_validator(mode="after")
    def _bounded_path(self) -> Self:
        # SR-TIM-3: the path ahead is sampled every cycle, so its length is bounded work.
        samples = self.path_lookahead_m / self.path_step_m
        if not samples <= MAX_PATH_SAMPLES:
            raise ValueError(
                f"runtime.path_lookahead_m / runtime.path_step_m ({self.path_lookahead_m} / "
                f"{self.path_step_m}) makes {samples:.4g} path samples; allowed: at most "
                f"{MAX_PATH_SAMPLES}"
            )
        return self
