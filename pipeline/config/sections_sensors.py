"""Configuration sections of the thermal camera and the radar beside the primary LiDAR
(SR-FUS-5, SR-FUS-6, SR-FUS-7).

Figures from the airside recommendations #22 and #24 (docs/findings/sensors.md). Nothing in
the runtime reads these sections yet: the camera's simulator and the sensors' front-ends do.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pipeline.compat import Self
from pipeline.config.base import Section


class ThermalSection(Section):
    """LWIR camera (#22: FLIR Boson+ 640 class) and its detector (SR-FUS-5, SR-FUS-6).

    Pinhole camera of ``width_px`` x ``height_px`` with ``hfov_deg`` across, at ``rate_hz``,
    mounted at ``(mount_x_m, mount_y_m, mount_z_m)`` in the robot frame, turned
    ``mount_yaw_deg`` (counter-clockwise) and pitched ``mount_pitch_deg`` down; ``netd_c`` is
    the simulated pixel noise. The detector keeps pixels warmer than the frame's ambient (its
    median) by ``above_ambient_c``, opens the mask with a 3 x 3 square, labels 8-connected
    components, and keeps a component whose area is ``area_min_frac``..``area_max_frac`` of a
    ``person_height_m`` x ``person_width_m`` person at the range its ground contact gives, whose
    height / width is ``aspect_min``..``aspect_max``, at least ``min_area_px`` pixels, within
    ``max_range_m``, and whose peak is below ``hot_surface_c`` (exhaust, sun-loaded metal). A frame
    whose contrast (1st to 99th percentile) is below ``min_contrast_c`` is contaminated: it
    yields nothing and the stream goes stale. The extrinsic is known to within
    ``calibration_translation_m`` per axis and ``calibration_angle_deg`` in pitch and yaw.
    """

    width_px: int = Field(640, ge=32, le=4096)
    height_px: int = Field(512, ge=32, le=4096)
    hfov_deg: float = Field(32.0, gt=1.0, le=150.0)
    rate_hz: float = Field(30.0, gt=0.0, le=240.0)
    mount_x_m: float = Field(0.4, ge=-10.0, le=10.0)
    mount_y_m: float = Field(0.0, ge=-10.0, le=10.0)
    mount_z_m: float = Field(1.2, gt=0.1, le=10.0)
    mount_yaw_deg: float = Field(0.0, ge=-180.0, le=180.0)
    mount_pitch_deg: float = Field(3.0, ge=-30.0, le=60.0)
    netd_c: float = Field(0.05, ge=0.0, le=5.0)
    above_ambient_c: float = Field(10.0, gt=0.0, le=100.0)
    hot_surface_c: float = Field(45.0, gt=0.0, le=1000.0)
    min_contrast_c: float = Field(1.5, ge=0.0, le=100.0)
    person_height_m: float = Field(1.75, gt=0.2, le=3.0)
    person_width_m: float = Field(0.5, gt=0.05, le=2.0)
    area_min_frac: float = Field(0.25, gt=0.0, le=10.0)
    area_max_frac: float = Field(2.5, gt=0.0, le=100.0)
    aspect_min: float = Field(1.3, gt=0.0, le=20.0)
    aspect_max: float = Field(6.0, gt=0.0, le=50.0)
    min_area_px: int = Field(6, ge=1, le=100_000)
    max_range_m: float = Field(40.0, gt=0.5, le=500.0)
    calibration_translation_m: float = Field(0.03, ge=0.0, le=1.0)
    calibration_angle_deg: float = Field(0.5, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        for low, high in (("area_min_frac", "area_max_frac"), ("aspect_min", "aspect_max")):
            if getattr(self, low) >= getattr(self, high):
                raise ValueError(
                    f"thermal.{low} ({getattr(self, low)}) must be below thermal.{high} "
                    f"({getattr(self, high)})"
                )
        if self.mount_pitch_deg + self.calibration_angle_deg >= 90.0:
            raise ValueError(
                f"thermal.mount_pitch_deg ({self.mount_pitch_deg}) plus "
                f"thermal.calibration_angle_deg ({self.calibration_angle_deg}) must stay below 90"
            )
        return self


class RadarSection(Section):
    """4-D imaging radar (#24: Continental ARS548 class) and its front-end (SR-FUS-7).

    The radar is mounted ``mount_z_m`` above the ground (its returns carry the mount's position
    in the robot frame); measurement noise ``range_std_m`` and ``azimuth_std_deg`` (the Doppler
    noise is ``fusion.radar_doppler_std_mps``).
    The front-end drops returns below ``min_rcs_dbsm`` or ``min_snr_db``, returns lower than
    ``min_height_m`` above the ground (clutter, from the elevation) and returns farther than
    ``ghost_margin_m`` behind a mapped reflector along their ray (multipath ghosts); the rest are
    gated against tracks with the tracker's own Mahalanobis gate. When the LiDAR's degradation
    index (its share of isolated returns, as a fraction of ``degraded_noise_fraction``, capped at
    1) reaches ``degraded_from``, radar positions also update the matched tracks, with the
    radar's covariance divided by the index (radar weighted more as the LiDAR degrades).
    """

    mount_z_m: float = Field(0.5, gt=0.0, le=10.0)
    range_std_m: float = Field(0.15, gt=0.0, le=10.0)
    azimuth_std_deg: float = Field(0.3, gt=0.0, le=20.0)
    min_rcs_dbsm: float = Field(-15.0, ge=-60.0, le=60.0)
    min_snr_db: float = Field(10.0, ge=-20.0, le=100.0)
    min_height_m: float = Field(0.15, ge=-5.0, le=5.0)
    ghost_margin_m: float = Field(0.3, ge=0.0, le=10.0)
    degraded_noise_fraction: float = Field(0.15, gt=0.0, le=1.0)
    degraded_from: float = Field(0.3, gt=0.0, le=1.0)
