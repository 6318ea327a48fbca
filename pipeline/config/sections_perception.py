"""Configuration sections of the perception stages (drivers to prediction, fusion)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from pipeline.compat import Self
from pipeline.config.base import Section


class DriverSection(Section):
    """Serial LiDAR transport (requirements SR-DRV-*).

    ``rplidar_mode`` "express" asks for express capsules, whose XOR checksum covers every
    distance; "standard" nodes carry three check bits only (docs/findings/drivers.md).
    ``incomplete_policy``: a revolution that lost beams to a rejected frame is emitted with
    ``complete=False`` ("mark") or withheld ("drop"); its rejected beams are never emitted.
    ``max_step_deg``: largest plausible angle step between two RPLIDAR nodes. A device that
    never answers is given up after ``max_reconnects`` attempts ``reconnect_backoff_s`` apart;
    one that answered and went away is retried until the run ends, the wait doubling up to
    ``reconnect_backoff_max_s``.
    """

    protocol: Literal["rplidar", "scip"] = "rplidar"
    port_url: str = Field("", description="pyserial URL or device path; empty: no device")
    baudrate_bps: int = Field(115200, ge=9600, le=4_000_000)
    read_timeout_s: float = Field(0.05, gt=0.0, le=5.0)
    silent_timeout_s: float = Field(0.5, gt=0.0, le=30.0)
    reconnect_backoff_s: float = Field(0.2, ge=0.0, le=30.0)
    reconnect_backoff_max_s: float = Field(2.0, ge=0.0, le=300.0)
    max_reconnects: int = Field(10, ge=0, le=10_000)
    rplidar_mode: Literal["standard", "express"] = "express"
    scip_command: Literal["MD", "MS"] = "MD"
    incomplete_policy: Literal["mark", "drop"] = "mark"
    max_beams_per_revolution: int = Field(8192, ge=16, le=65_536)
    max_step_deg: float = Field(10.0, gt=0.0, le=90.0)

    @model_validator(mode="after")
    def _backoff_ordered(self) -> Self:
        if self.reconnect_backoff_max_s < self.reconnect_backoff_s:
            raise ValueError(
                f"driver.reconnect_backoff_max_s ({self.reconnect_backoff_max_s}) must not be "
                f"below driver.reconnect_backoff_s ({self.reconnect_backoff_s})"
            )
        return self


class ScanSection(Section):
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


class SecondScanSection(Section):
    """A second scanner (rear, or a corner) merged with the first per cycle (SR-LID-1..4).

    Its points are moved into the robot frame by its ``mount_*`` pose, range-filtered with the
    ``scan`` section's limits, and merged with the first scanner's only while its scan is
    fresh by the first scanner's bound (``monitors.scan_max_age_s``, ``monitors.clock_skew_s``:
    the stopping proof's latency); a stale or missing second scan is left out, recorded in the
    audit log, and ``on_stale`` says what the robot does meanwhile: ``report`` (nothing more),
    ``slow`` (``monitors.degraded_speed_mps``) or ``stop``.
    """

    enabled: bool = False
    mount_x_m: float = Field(-0.45, ge=-10.0, le=10.0)
    mount_y_m: float = Field(0.0, ge=-10.0, le=10.0)
    mount_yaw_rad: float = Field(3.141592653589793, ge=-6.2832, le=6.2832)
    on_stale: Literal["report", "slow", "stop"] = "slow"


class ClusterSection(Section):
    """DBSCAN on scan points (source: eps 0.15 m, min_samples 3, 4..200 points)."""

    eps_m: float = Field(0.15, gt=0.0, le=2.0)
    min_samples: int = Field(3, ge=1, le=100)
    min_points: int = Field(4, ge=1, le=10_000)
    max_points: int = Field(200, ge=1, le=10_000)
    max_clusters: int = Field(64, ge=1, le=1024)
    # Floor of the box area used for point density, so a line-shaped cluster (zero-width box)
    # gets a finite density.
    density_min_area_m2: float = Field(0.01, gt=0.0, le=100.0)
    # Shape estimator (SR-TRK-7): "box" the minimum-area box, "lshape" the search-based
    # L-shape fit (Zhang et al. 2017) with the box as fallback (pipeline/shape/lshape.py).
    shape_estimator: Literal["box", "lshape"] = "box"
    lshape_criterion: Literal["closeness", "area", "variance"] = "closeness"
    lshape_angle_step_deg: float = Field(1.0, ge=0.05, le=10.0)
    lshape_perpendicular_tol_deg: float = Field(15.0, ge=0.0, le=45.0)
    lshape_min_edge_inliers: int = Field(6, ge=2, le=1000)
    lshape_inlier_m: float = Field(0.1, gt=0.0, le=2.0)
    lshape_closeness_floor_m: float = Field(0.01, gt=0.0, le=1.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.min_points > self.max_points:
            raise ValueError(
                f"cluster.min_points ({self.min_points}) must not exceed "
                f"cluster.max_points ({self.max_points})"
            )
        return self


class TrackSection(Section):
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
    # Off by default (SR-AVL-7, SR-TRK-9): on ray-cast runs a dormant track is often given to
    # another object (a walker's other leg, the next walker), and the velocity it then reports
    # set most of the robot's needless stops; docs/findings/availability.md has the figures.
    reid_enabled: bool = False
    max_detections: int = Field(64, ge=1, le=10_000)
    init_velocity_std_mps: float = Field(2.0, gt=0.0, le=100.0)
    # Size comparison for re-identification: |a - b| <= tolerance * max(a, b, floor), so
    # leg-sized clusters are not refused over a few centimetres of noise.
    reid_size_floor_m: float = Field(0.1, ge=0.0, le=10.0)
    # Re-identification within the domain (SR-AVL-7): after a gap of h seconds a dormant track
    # takes only a detection within 0.5 * reid_max_accel * h^2 + half its largest size +
    # reid_slack_m of its constant-velocity prediction (every place an object of the operating
    # domain, accelerating at most reid_max_accel_mps2, can have reached, seen from any side),
    # keeps its velocity estimate and widens that estimate's standard deviation by
    # reid_max_accel * h (every velocity it can have reached).
    reid_max_accel_mps2: float = Field(2.5, gt=0.0, le=50.0)
    reid_slack_m: float = Field(0.15, ge=0.0, le=10.0)
    # Association (SR-TRK-8): "hungarian" the gated cascade everywhere; "jpda" joint
    # probabilistic data association where confirmed tracks share gated detections, the
    # cascade elsewhere (pipeline/track/jpda.py). A cluster of tracks whose joint hypotheses
    # could exceed jpda_max_hypotheses falls back to the cascade (counted).
    association: Literal["hungarian", "jpda"] = "hungarian"
    jpda_detection_prob: float = Field(0.9, gt=0.0, le=1.0)
    jpda_max_hypotheses: int = Field(2048, ge=1, le=1_000_000)
    jpda_surveillance_area_m2: float = Field(2827.0, gt=0.0, le=1e6)
    jpda_clutter_density_min_per_m2: float = Field(1e-4, gt=0.0, le=100.0)
    jpda_clutter_smoothing: float = Field(0.1, gt=0.0, le=1.0)
    # Track heading (SR-TRK-7): the detections' box axes smoothed with this gain; the 180 deg
    # flip resolved by the velocity above heading_flip_speed_mps, else by the heading history.
    # Below about 1 m/s a creeping vehicle's centroid slides faster than it drives as its
    # visible faces change, and resolves the flip the wrong way (docs/findings/tracking-airside.md).
    heading_smoothing: float = Field(0.3, gt=0.0, le=1.0)
    heading_flip_speed_mps: float = Field(1.0, ge=0.0, le=20.0)
    # A certain velocity above this speed (but below the flip speed) still chooses which side
    # of the box is the heading's, without resolving the flip.
    heading_side_speed_mps: float = Field(0.3, ge=0.0, le=20.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.lost_after_misses > self.dormant_after_misses:
            raise ValueError(
                f"track.lost_after_misses ({self.lost_after_misses}) must not exceed "
                f"track.dormant_after_misses ({self.dormant_after_misses})"
            )
        return self


class ClassifySection(Section):
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


class PredictSection(Section):
    """Motion prediction (source: 1.5 s horizon, +/-15 deg cone, reversal at 0.6 m/s; SR-PRED-*).

    A moving object's speed bound is its filtered speed plus ``velocity_sigmas`` standard
    deviations of the filter's velocity estimate; its cone widens beyond
    ``cone_half_angle_deg`` when that uncertainty makes the heading less certain, and becomes a
    full circle past 90 deg. Bodies are discs of at least ``min_body_radius_m``. Arcs and discs
    are drawn as circumscribed polygons (arc pieces of at most ``arc_step_deg``, discs of
    ``disc_sides`` sides), so the polygons contain the exact regions. A near-reversal track's
    last confirmed heading is the direction of its centroid history when that spans at least
    ``heading_min_travel_m``. A forklift-class track slower than ``near_reversal_speed_mps``
    whose history was moving within ``near_reversal_memory_s`` is predicted as near reversal
    whatever state the classifier gave it (the simulator labels such a truck near reversal).
    No object of the operating domain moves faster than
    ``max_object_speed_mps``: it caps every speed bound (an assumption; the runtime stops when a
    confirmed track is seen faster). ``step_s`` samples the horizon where a finite set of times is
    needed (evaluation). A track whose cluster's box is at most ``person_max_extent_m`` long and
    wide may be a person whatever its class (:func:`pipeline.predict.person_compatible`, SR-CLS-8).
    ``heading_source`` says what orients a vehicle whose motion gives no direction (a slow cone
    whose spread reaches 90 deg, a near-reversal track without a confirmed heading): "motion"
    leaves it a disc; "track" predicts it along its track heading's body axis, both ways, when
    the track has a heading and cannot be a person (:mod:`pipeline.predict_axis`, SR-PRED-4).
    """

    horizon_s: float = Field(1.5, gt=0.0, le=10.0)
    step_s: float = Field(0.1, gt=0.0, le=1.0)
    cone_half_angle_deg: float = Field(15.0, ge=0.0, le=90.0)
    reversal_speed_mps: float = Field(0.6, ge=0.0, le=10.0)
    max_object_speed_mps: float = Field(3.5, gt=0.0, le=20.0)
    near_reversal_speed_mps: float = Field(0.3, ge=0.0, le=10.0)
    near_reversal_decel_mps2: float = Field(0.4, ge=0.0, le=20.0)
    near_reversal_memory_s: float = Field(1.0, ge=0.0, le=10.0)
    velocity_sigmas: float = Field(2.0, ge=0.0, le=10.0)
    min_body_radius_m: float = Field(0.1, gt=0.0, le=10.0)
    arc_step_deg: float = Field(15.0, ge=1.0, le=45.0)
    disc_sides: int = Field(12, ge=6, le=64)
    heading_min_travel_m: float = Field(0.3, ge=0.0, le=10.0)
    person_max_extent_m: float = Field(1.0, gt=0.0, le=5.0)
    heading_source: Literal["motion", "track"] = "motion"


class FusionSection(Section):
    """Thermal / radar fusion into LiDAR tracks with freshness (SR-FUS-1, SR-FUS-3).

    A detection is fused only while its age ``now - stamp`` lies in ``[-clock_skew_s,
    max_age - clock_skew_s]`` (:func:`safety.model.freshness.is_fresh`); ``clock_skew_s`` bounds how
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
