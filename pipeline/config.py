"""Validated configuration of the whole pipeline, one section per stage (requirement SR-CFG-*).

The defaults live here, in code; a TOML file given with ``--config FILE`` overrides any subset
of them (a table per section, e.g. ``[cluster] eps_m = 0.2``). Every field carries its unit in
its name. Validation is strict: an unknown key, a wrong type or a value outside its allowed
range raises :class:`~pipeline.errors.ConfigError` whose lines each name the key, the value and
what is allowed. :func:`config_hash` is a stable SHA-256 over the canonical JSON form of the
values, recorded in every evidence bundle and audit log.
"""

from __future__ import annotations

import hashlib
import json
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, Self

from annotated_types import Ge, Gt, Le, Lt
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic.fields import FieldInfo

from pipeline.errors import ConfigError

__all__ = [
    "SafecaseConfig",
    "config_hash",
    "default_config",
    "load_config",
    "overridden",
    "to_toml",
    "validate_config",
]


class _Section(BaseModel):
    """Base of every section: frozen, no unknown keys, no silent coercion of strings."""

    model_config = ConfigDict(frozen=True, extra="forbid", strict=True, validate_default=True)


class DriverSection(_Section):
    """Serial LiDAR transport (requirements SR-DRV-*).

    ``rplidar_mode`` "express" asks for express capsules, whose XOR checksum covers every
    distance; "standard" nodes carry three check bits only (see README "Serial drivers").
    ``incomplete_policy``: a revolution that lost beams to a rejected frame is emitted with
    ``complete=False`` ("mark") or withheld ("drop"); its rejected beams are never emitted.
    ``max_step_deg``: largest plausible angle step between two RPLIDAR nodes.
    """

    protocol: Literal["rplidar", "scip"] = "rplidar"
    port_url: str = Field("", description="pyserial URL or device path; empty: no device")
    baudrate_bps: int = Field(115200, ge=9600, le=4_000_000)
    read_timeout_s: float = Field(0.05, gt=0.0, le=5.0)
    silent_timeout_s: float = Field(0.5, gt=0.0, le=30.0)
    reconnect_backoff_s: float = Field(0.2, ge=0.0, le=30.0)
    max_reconnects: int = Field(10, ge=0, le=10_000)
    rplidar_mode: Literal["standard", "express"] = "express"
    scip_command: Literal["MD", "MS"] = "MD"
    incomplete_policy: Literal["mark", "drop"] = "mark"
    max_beams_per_revolution: int = Field(8192, ge=16, le=65_536)
    max_step_deg: float = Field(10.0, gt=0.0, le=90.0)


class ScanSection(_Section):
    """Scan sanitation before clustering (requirement SR-TRK-*, SR-DRV-*)."""

    min_range_m: float = Field(0.05, ge=0.0, le=10.0)
    max_range_m: float = Field(30.0, gt=0.0, le=200.0)
    max_beams: int = Field(2048, ge=16, le=16384)
    # Pose of the scanner in the robot frame: points are reported in the robot frame.
    mount_x_m: float = Field(0.0, ge=-10.0, le=10.0)
    mount_y_m: float = Field(0.0, ge=-10.0, le=10.0)
    mount_yaw_rad: float = Field(0.0, ge=-6.2832, le=6.2832)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.min_range_m >= self.max_range_m:
            raise ValueError(
                f"scan.min_range_m ({self.min_range_m}) must be below "
                f"scan.max_range_m ({self.max_range_m})"
            )
        return self


class ClusterSection(_Section):
    """DBSCAN on scan points (source: eps 0.15 m, min_samples 3, 4..200 points)."""

    eps_m: float = Field(0.15, gt=0.0, le=2.0)
    min_samples: int = Field(3, ge=1, le=100)
    min_points: int = Field(4, ge=1, le=10_000)
    max_points: int = Field(200, ge=1, le=10_000)
    max_clusters: int = Field(64, ge=1, le=1024)
    # Floor of the box area used for point density, so a line-shaped cluster (zero-width box)
    # gets a finite density.
    density_min_area_m2: float = Field(0.01, gt=0.0, le=100.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.min_points > self.max_points:
            raise ValueError(
                f"cluster.min_points ({self.min_points}) must not exceed "
                f"cluster.max_points ({self.max_points})"
            )
        return self


class TrackSection(_Section):
    """Kalman tracking and re-identification (source material numbers; SR-TRK-*)."""

    frame_period_s: float = Field(0.1, gt=0.0, le=1.0)
    history_frames: int = Field(15, ge=2, le=1000)
    decel_window_s: float = Field(0.5, gt=0.0, le=10.0)
    size_variance_frames: int = Field(10, ge=2, le=1000)
    process_accel_std_mps2: float = Field(1.0, gt=0.0, le=50.0)
    measurement_std_m: float = Field(0.05, gt=0.0, le=5.0)
    gate_euclidean_m: float = Field(2.0, gt=0.0, le=50.0)
    gate_mahalanobis_chi2: float = Field(9.21, gt=0.0, le=1000.0)
    confirm_hits: int = Field(3, ge=1, le=100)
    lost_after_misses: int = Field(2, ge=1, le=100)
    dormant_after_misses: int = Field(5, ge=1, le=1000)
    dormant_timeout_frames: int = Field(50, ge=1, le=100_000)
    dormant_gate_factor: float = Field(3.0, ge=1.0, le=100.0)
    dormant_size_tolerance_frac: float = Field(0.3, ge=0.0, le=10.0)
    max_dormant: int = Field(50, ge=0, le=10_000)
    dormant_prediction_cap_s: float = Field(3.0, ge=0.0, le=60.0)
    max_tracks: int = Field(64, ge=1, le=10_000)
    reid_enabled: bool = True
    max_detections: int = Field(64, ge=1, le=10_000)
    init_velocity_std_mps: float = Field(2.0, gt=0.0, le=100.0)
    # Size comparison for re-identification: |a - b| <= tolerance * max(a, b, floor), so
    # leg-sized clusters are not refused over a few centimetres of noise.
    reid_size_floor_m: float = Field(0.1, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.lost_after_misses > self.dormant_after_misses:
            raise ValueError(
                f"track.lost_after_misses ({self.lost_after_misses}) must not exceed "
                f"track.dormant_after_misses ({self.dormant_after_misses})"
            )
        return self


class ClassifySection(_Section):
    """Gradient-boosted tree classifier (source: depth 6, 150 estimators; SR-CLS-*).

    ``model_path``: XGBoost JSON model file (empty: the packaged one) with its card beside it;
    ``model_sha256``: the hash it must have (empty: the one its card records). ``max_depth``,
    ``n_estimators``, ``learning_rate``, ``max_bin`` (histogram bins per feature, so at most
    that many distinct thresholds per feature, which keeps inference tables small) and
    ``train_seed`` are what ``safecase train`` uses.
    Confidence (probability of the chosen class) selects the margin tier: at least
    ``high_confidence_min`` high, at least ``medium_confidence_min`` medium, else the most
    cautious (near-reversal) tier and an any-direction prediction.
    """

    model_path: str = Field("", description="model file; empty: the packaged model")
    model_sha256: str = Field("", pattern=r"^([0-9a-fA-F]{64})?$")
    max_depth: int = Field(6, ge=1, le=16)
    n_estimators: int = Field(150, ge=1, le=5000)
    learning_rate: float = Field(0.3, gt=0.0, le=1.0)
    max_bin: int = Field(64, ge=2, le=1024)
    train_seed: int = Field(0, ge=0, le=2**32 - 1)
    high_confidence_min: float = Field(0.8, gt=0.0, le=1.0)
    medium_confidence_min: float = Field(0.5, gt=0.0, le=1.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.medium_confidence_min > self.high_confidence_min:
            raise ValueError(
                f"classify.medium_confidence_min ({self.medium_confidence_min}) must not "
                f"exceed classify.high_confidence_min ({self.high_confidence_min})"
            )
        return self


class PredictSection(_Section):
    """Motion prediction (source: 1.5 s horizon, +/-15 deg cone, reversal at 0.6 m/s; SR-PRED-*).

    A moving object's speed bound is its filtered speed plus ``velocity_sigmas`` standard
    deviations of the filter's velocity estimate; its cone widens beyond
    ``cone_half_angle_deg`` when that uncertainty makes the heading less certain, and becomes a
    full circle past 90 deg. Bodies are discs of at least ``min_body_radius_m``. Arcs and discs
    are drawn as circumscribed polygons (arc pieces of at most ``arc_step_deg``, discs of
    ``disc_sides`` sides), so the polygons contain the exact regions. A near-reversal track's
    last confirmed heading is the direction of its centroid history when that spans at least
    ``heading_min_travel_m``. ``step_s`` samples the horizon where a finite set of times is
    needed (evaluation).
    """

    horizon_s: float = Field(1.5, gt=0.0, le=10.0)
    step_s: float = Field(0.1, gt=0.0, le=1.0)
    cone_half_angle_deg: float = Field(15.0, ge=0.0, le=90.0)
    reversal_speed_mps: float = Field(0.6, ge=0.0, le=10.0)
    near_reversal_speed_mps: float = Field(0.3, ge=0.0, le=10.0)
    near_reversal_decel_mps2: float = Field(0.4, ge=0.0, le=20.0)
    velocity_sigmas: float = Field(2.0, ge=0.0, le=10.0)
    min_body_radius_m: float = Field(0.1, gt=0.0, le=10.0)
    arc_step_deg: float = Field(15.0, ge=1.0, le=45.0)
    disc_sides: int = Field(12, ge=6, le=64)
    heading_min_travel_m: float = Field(0.3, ge=0.0, le=10.0)


ClosingClassName = Literal["static", "person", "forklift_reversing"]


class StoppingSection(_Section):
    """Stopping-distance model, margin tiers and their speed caps (SR-STOP-*).

    Braking 0.2-0.4 m at 1.0 m/s in the source gives b = v^2 / (2 d) in [1.25, 2.5] m/s^2.
    The reaction latency is ``perception_latency_s + control_cycle_s``; ``latency_source``
    records where the perception bound came from (a measured p99/pWCET later). Each tier's
    margin must absorb the closing speed of its ``closing_class_*`` during the whole stop. The
    default speed caps are the largest speeds each tier's margin covers in the worst case
    (computed and proved by properties/test_stopping.py), rounded down to 1 mm/s.
    """

    perception_latency_s: float = Field(0.08, ge=0.0, le=2.0)
    latency_source: str = Field("config", description="where perception_latency_s came from")
    control_cycle_s: float = Field(0.1, gt=0.0, le=1.0)
    decel_min_mps2: float = Field(1.25, gt=0.0, le=20.0)
    decel_max_mps2: float = Field(2.5, gt=0.0, le=20.0)
    accel_max_mps2: float = Field(0.5, ge=0.0, le=20.0)
    robot_max_speed_mps: float = Field(1.0, gt=0.0, le=10.0)
    margin_high_m: float = Field(0.4, ge=0.0, le=20.0)
    margin_medium_m: float = Field(0.7, ge=0.0, le=20.0)
    margin_near_reversal_m: float = Field(1.0, ge=0.0, le=20.0)
    speed_cap_high_mps: float = Field(0.719, ge=0.0, le=10.0)
    speed_cap_medium_mps: float = Field(1.0, ge=0.0, le=10.0)
    speed_cap_near_reversal_mps: float = Field(0.796, ge=0.0, le=10.0)
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


class GovernorSection(_Section):
    """Speed governor (SR-STOP-2): a speed below ``min_moving_speed_mps`` becomes STOP."""

    min_moving_speed_mps: float = Field(0.05, ge=0.0, le=1.0)


class GeometrySection(_Section):
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
    footprint_length_m: float = Field(0.7, gt=0.0, le=20.0)
    footprint_width_m: float = Field(0.5, gt=0.0, le=20.0)
    max_obstacles: int = Field(64, ge=1, le=10_000)

    @model_validator(mode="after")
    def _grid(self) -> Self:
        if self.n_speeds * self.n_yaw_rates != self.n_trajectories:
            raise ValueError(
                f"geometry.n_speeds ({self.n_speeds}) x geometry.n_yaw_rates "
                f"({self.n_yaw_rates}) must equal geometry.n_trajectories ({self.n_trajectories})"
            )
        return self


class CostmapSection(_Section):
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


class FusionSection(_Section):
    """Thermal / radar fusion into LiDAR tracks with freshness (SR-FUS-1, SR-FUS-3).

    A detection is fused only while its age ``now - stamp`` lies in ``[-clock_skew_s,
    max_age - clock_skew_s]`` (:func:`pipeline.fusion.is_fresh`); ``clock_skew_s`` bounds how
    far a sensor's stamps may differ from the decision clock (0: the sensors stamp with the
    decision clock). Fresh thermal detections are matched one-to-one to live tracks within
    ``gate_m``: a match raises the track's confidence by ``confidence_boost`` (at most 1), an
    unmatched detection becomes a thermal-only pedestrian of confidence at most
    ``thermal_only_confidence``, which must stay below ``classify.medium_confidence_min`` so the
    governor gives it the most cautious tier. Radar Doppler speeds (standard deviation
    ``radar_doppler_std_mps``) update the matched track's velocity. At most ``max_thermal`` /
    ``max_radar`` fresh detections are used per cycle; any beyond are counted and the
    operating-domain monitor stops the robot (never dropped silently).
    """

    thermal_max_age_s: float = Field(0.2, gt=0.0, le=10.0)
    radar_max_age_s: float = Field(0.2, gt=0.0, le=10.0)
    clock_skew_s: float = Field(0.0, ge=0.0, le=1.0)
    gate_m: float = Field(2.0, gt=0.0, le=50.0)
    confidence_boost: float = Field(0.2, ge=0.0, le=1.0)
    thermal_only_confidence: float = Field(0.3, ge=0.0, le=1.0)
    radar_doppler_std_mps: float = Field(0.1, gt=0.0, le=10.0)
    max_thermal: int = Field(64, ge=1, le=10_000)
    max_radar: int = Field(64, ge=1, le=10_000)

    @model_validator(mode="after")
    def _skew_below_ages(self) -> Self:
        for name in ("thermal_max_age_s", "radar_max_age_s"):
            if self.clock_skew_s >= getattr(self, name):
                raise ValueError(
                    f"fusion.clock_skew_s ({self.clock_skew_s}) must be below fusion.{name} "
                    f"({getattr(self, name)}): otherwise no detection is ever fresh"
                )
        return self


class MonitorSection(_Section):
    """Runtime monitors: staleness, clock, deadline, operating domain (SR-FUS-2, SR-TIM-2).

    STOP when the scan's first beam is older than ``scan_max_age_s`` at decision time (or
    stamped more than ``clock_skew_s`` in the future), when the decision clock runs back by
    more than ``max_clock_jump_back_s``, when a cycle takes longer than ``cycle_deadline_s``,
    when more than ``max_blocked_fraction`` of the beams read below the minimum range (a
    covered window) or when any per-cycle cap dropped something. An incomplete scan (frames
    rejected by the driver) limits the speed to ``degraded_speed_mps``.
    """

    scan_max_age_s: float = Field(0.25, gt=0.0, le=10.0)
    cycle_deadline_s: float = Field(0.1, gt=0.0, le=10.0)
    max_clock_jump_back_s: float = Field(0.0, ge=0.0, le=10.0)
    clock_skew_s: float = Field(0.0, ge=0.0, le=1.0)
    max_blocked_fraction: float = Field(0.5, ge=0.0, le=1.0)
    degraded_speed_mps: float = Field(0.3, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _skew_below_age(self) -> Self:
        if self.clock_skew_s >= self.scan_max_age_s:
            raise ValueError(
                f"monitors.clock_skew_s ({self.clock_skew_s}) must be below "
                f"monitors.scan_max_age_s ({self.scan_max_age_s}): otherwise no scan is fresh"
            )
        return self


class SimSection(_Section):
    """Built-in simulator defaults (SR-SIM-*); see pipeline/sim/.

    ``lidar_device`` "generic" uses ``beams`` evenly over ``fov_deg`` at ``scan_rate_hz`` and
    the range limits here; a named device uses its own layout, rate and range limits (the
    sensor-effect keys still apply). Ego braking is drawn per run from
    ``[ego_decel_min_mps2, ego_decel_max_mps2]`` (default: the stopping model's range).
    """

    scenario: str = Field("reversing_forklift_aisle", min_length=1)
    seed: int = Field(0, ge=0, le=2**32 - 1)
    beams: int = Field(1080, ge=16, le=16384)
    duration_s: float = Field(20.0, gt=0.0, le=36_000.0)
    lidar_device: Literal["generic", "hokuyo_urg04lx", "hokuyo_ust10lx", "rplidar_a2"] = "generic"
    fov_deg: float = Field(360.0, gt=0.0, le=360.0)
    scan_rate_hz: float = Field(10.0, gt=0.0, le=100.0)
    min_range_m: float = Field(0.05, ge=0.0, le=10.0)
    max_range_m: float = Field(30.0, gt=0.0, le=200.0)
    range_noise_std_m: float = Field(0.01, ge=0.0, le=1.0)
    noise_clip_sigma: float = Field(3.0, ge=0.0, le=10.0)
    dropout_prob: float = Field(0.002, ge=0.0, le=1.0)
    mixed_pixel_prob: float = Field(0.5, ge=0.0, le=1.0)
    mixed_pixel_min_jump_m: float = Field(0.3, gt=0.0, le=100.0)
    time_skew: bool = True
    mount_x_m: float = Field(0.0, ge=-5.0, le=5.0)
    mount_y_m: float = Field(0.0, ge=-5.0, le=5.0)
    mount_yaw_deg: float = Field(0.0, ge=-180.0, le=180.0)
    step_s: float = Field(0.01, gt=0.0, le=0.1)
    ego_speed_mps: float = Field(1.0, ge=0.0, le=10.0)
    ego_length_m: float = Field(0.9, gt=0.0, le=10.0)
    ego_width_m: float = Field(0.6, gt=0.0, le=10.0)
    ego_accel_mps2: float = Field(0.5, gt=0.0, le=20.0)
    ego_decel_min_mps2: float = Field(1.25, gt=0.0, le=20.0)
    ego_decel_max_mps2: float = Field(2.5, gt=0.0, le=20.0)
    actuation_latency_s: float = Field(0.05, ge=0.0, le=2.0)
    label_stationary_speed_mps: float = Field(0.05, ge=0.0, le=5.0)
    label_near_reversal_speed_mps: float = Field(0.3, ge=0.0, le=5.0)
    label_reversal_window_s: float = Field(1.0, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.min_range_m >= self.max_range_m:
            raise ValueError(
                f"sim.min_range_m ({self.min_range_m}) must be below "
                f"sim.max_range_m ({self.max_range_m})"
            )
        if self.ego_decel_min_mps2 > self.ego_decel_max_mps2:
            raise ValueError(
                f"sim.ego_decel_min_mps2 ({self.ego_decel_min_mps2}) must not exceed "
                f"sim.ego_decel_max_mps2 ({self.ego_decel_max_mps2})"
            )
        if self.label_stationary_speed_mps > self.label_near_reversal_speed_mps:
            raise ValueError(
                f"sim.label_stationary_speed_mps ({self.label_stationary_speed_mps}) must not "
                f"exceed sim.label_near_reversal_speed_mps ({self.label_near_reversal_speed_mps})"
            )
        return self


class AuditSection(_Section):
    """Hash-chained audit log (SR-AUD-*): one JSON line per cycle, see :mod:`safety.audit`.

    The log is fsynced, and its signed head anchor rewritten, every ``fsync_every_records``
    records and at close. ``signing_key`` is the Ed25519 key (PEM) that signs the anchor; empty
    with ``sign_head`` true: the evidence signing key (:mod:`evidence.manifest`).
    """

    log_dir: str = "out/audit"
    fsync_every_records: int = Field(10, ge=1, le=1_000_000)
    sign_head: bool = False
    signing_key: str = Field("", description="Ed25519 PEM key; empty: the evidence key")


class SafecaseConfig(_Section):
    """The whole configuration: one section per stage of the data path."""

    driver: DriverSection = DriverSection()
    scan: ScanSection = ScanSection()
    cluster: ClusterSection = ClusterSection()
    track: TrackSection = TrackSection()
    classify: ClassifySection = ClassifySection()
    predict: PredictSection = PredictSection()
    stopping: StoppingSection = StoppingSection()
    governor: GovernorSection = GovernorSection()
    geometry: GeometrySection = GeometrySection()
    costmap: CostmapSection = CostmapSection()
    fusion: FusionSection = FusionSection()
    monitors: MonitorSection = MonitorSection()
    sim: SimSection = SimSection()
    audit: AuditSection = AuditSection()

    @model_validator(mode="before")
    @classmethod
    def _reject_non_finite(cls, data: Any) -> Any:
        # pydantic accepts nan/inf for plain float fields with no bound; no safety parameter
        # may be non-finite, so reject them here with the key named.
        if isinstance(data, Mapping):
            for section, values in data.items():
                if isinstance(values, Mapping):
                    for key, value in values.items():
                        if isinstance(value, float) and not math.isfinite(value):
                            raise ConfigError(
                                [f"{section}.{key} = {value!r}: allowed: a finite number"]
                            )
        return data


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a JSON string is a valid TOML basic string
    raise TypeError(f"to_toml: cannot write {type(value).__name__} value {value!r}")


def to_toml(data: Mapping[str, Mapping[str, Any]]) -> str:
    """Write section tables of scalars as TOML (what ``load_config`` reads back)."""
    lines: list[str] = []
    for section, values in data.items():
        lines.append(f"[{section}]")
        lines.extend(f"{key} = {_toml_value(value)}" for key, value in values.items())
        lines.append("")
    return "\n".join(lines)


def default_config() -> SafecaseConfig:
    """The built-in configuration (every default from code)."""
    return SafecaseConfig()


def config_hash(config: SafecaseConfig) -> str:
    """Stable SHA-256 (hex) of the configuration's values, independent of key order."""
    canonical = json.dumps(
        config.model_dump(mode="json"), sort_keys=True, separators=(",", ":"), allow_nan=False
    )
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


def _field_info(loc: tuple[int | str, ...]) -> FieldInfo | None:
    model: type[BaseModel] = SafecaseConfig
    info: FieldInfo | None = None
    for part in loc:
        if not isinstance(part, str) or part not in model.model_fields:
            return None
        info = model.model_fields[part]
        annotation = info.annotation
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            model = annotation
    return info


def _allowed(loc: tuple[int | str, ...], err_type: str) -> str:
    """Describe what a key accepts, from the field's own declaration."""
    if err_type == "extra_forbidden":
        parent: type[BaseModel] = SafecaseConfig
        for part in loc[:-1]:
            info = parent.model_fields.get(str(part))
            if info is None or not (
                isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)
            ):
                break
            parent = info.annotation
        return "one of the keys " + ", ".join(sorted(parent.model_fields))
    info = _field_info(loc)
    if info is None:
        return "see `safecase config show` for the keys and defaults"
    bounds: list[str] = []
    for meta in info.metadata:
        if isinstance(meta, Ge):
            bounds.append(f">= {meta.ge}")
        elif isinstance(meta, Gt):
            bounds.append(f"> {meta.gt}")
        elif isinstance(meta, Le):
            bounds.append(f"<= {meta.le}")
        elif isinstance(meta, Lt):
            bounds.append(f"< {meta.lt}")
    annotation = info.annotation
    kind = {"float": "number", "int": "integer", "str": "string", "bool": "boolean"}.get(
        getattr(annotation, "__name__", ""), str(annotation)
    )
    article = "an" if kind[:1] in "aeiou" else "a"
    if getattr(annotation, "__origin__", None) is Literal:
        return "one of " + ", ".join(repr(a) for a in annotation.__args__)  # type: ignore[union-attr]
    if bounds:
        return f"{article} {kind} " + " and ".join(bounds)
    return f"{article} {kind}"


def _format_errors(error: ValidationError, origin: str) -> list[str]:
    lines = []
    for item in error.errors(include_url=False):
        loc = tuple(item["loc"])
        key = ".".join(str(p) for p in loc) or "<top level>"
        value = item.get("input")
        shown = "<missing>" if item["type"] == "missing" else repr(value)
        if item["type"] == "extra_forbidden":
            lines.append(f"{origin}: unknown key {key}; allowed: {_allowed(loc, item['type'])}")
            continue
        message = str(item["msg"])
        if item["type"] == "value_error" and "ctx" in item:
            lines.append(f"{origin}: {message.removeprefix('Value error, ')}")
            continue
        lines.append(
            f"{origin}: {key} = {shown}: {message}; allowed: {_allowed(loc, item['type'])}"
        )
    return lines


def validate_config(data: Mapping[str, Any], origin: str = "config") -> SafecaseConfig:
    """Build a :class:`SafecaseConfig` from nested mappings (sections of keys).

    Raises :class:`ConfigError` naming every bad key, its value and what is allowed.
    """
    try:
        return SafecaseConfig.model_validate(dict(data))
    except ConfigError as exc:
        raise ConfigError([f"{origin}: {line}" for line in exc.lines]) from None
    except ValidationError as exc:
        raise ConfigError(_format_errors(exc, origin)) from None


def load_config(path: Path | str | None = None) -> SafecaseConfig:
    """Load the defaults, overridden by the TOML file at ``path`` when given (SR-CFG-1)."""
    if path is None:
        return default_config()
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError([f"{file}: cannot read the configuration file: {exc.strerror}"]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError([f"{file}: not valid TOML: {exc}"]) from None
    return validate_config(data, origin=str(file))


def overridden(config: SafecaseConfig, updates: Mapping[str, Mapping[str, Any]]) -> SafecaseConfig:
    """A copy of ``config`` with section values replaced, validated like a file would be."""
    data: dict[str, Any] = config.model_dump(mode="python")
    for section, values in updates.items():
        merged = dict(data.get(section, {}))
        merged.update(values)
        data[section] = merged
    return validate_config(data, origin="override")
