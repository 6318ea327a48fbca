"""Configuration section of the built-in simulator."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from pipeline.compat import Self
from pipeline.config.base import Section


class SimSection(Section):
    """Built-in simulator defaults (SR-SIM-*); see pipeline/sources/sim/.

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


class CampaignSection(Section):
    """Targets of closed-loop campaigns (SR-RUN-8; ``safecase campaign``).

    ``max_contact_rate``: the one-sided 95 % Clopper-Pearson upper bound on the per-run rate of
    contacts while moving must stay below this; zero contacts in ``n`` runs bound the rate at
    about ``3 / n``, so the default 0.01 needs at least 299 runs without one.
    """

    max_contact_rate: float = Field(0.01, gt=0.0, lt=1.0)
