"""Configuration sections of the thermal camera, the radar, the microphone array and the
multi-ring LiDAR's marking detector beside the primary LiDAR (SR-FUS-5, SR-FUS-6, SR-FUS-7,
SR-ACU-1..4, SR-MRK-1..4).

Figures from the airside recommendations #22, #23, #24 and #25 (docs/findings/sensors.md,
docs/findings/acoustic.md, docs/findings/markings.md). The runtime reads only the acoustic
section's freshness and caution keys; the simulators and the sensors' front-ends read the rest.
"""

from __future__ import annotations

from pydantic import Field, model_validator

from pipeline.compat import Self
from pipeline.config.base import Section


class ThermalSection(Section):
    """LWIR camera (#22: FLIR Boson+ 640 class) and its detector (SR-FUS-5, SR-FUS-6).

    Pinhole camera of ``width_px`` x ``height_px`` with ``hfov_deg`` across, capturing at
    ``rate_hz`` (the simulated camera on its own clock, :mod:`pipeline.sources.sim.
    sensor_timing`; ``1 / rate_hz`` may not exceed ``fusion.thermal_max_age_s -
    fusion.clock_skew_s``, checked at load: a slower stream would go stale between two frames),
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

    The radar scans at ``rate_hz`` (#24: 20 Hz; the simulated radar on its own clock,
    :mod:`pipeline.sources.sim.sensor_timing`; ``1 / rate_hz`` may not exceed
    ``fusion.radar_max_age_s - fusion.clock_skew_s``, checked at load: a slower stream would go
    stale between two scans), mounted ``mount_z_m`` above the ground (its returns carry the
    mount's position in the robot frame); measurement noise ``range_std_m`` and
    ``azimuth_std_deg`` (the Doppler noise is ``fusion.radar_doppler_std_mps``).
    The front-end drops returns below ``min_rcs_dbsm`` or ``min_snr_db``, returns lower than
    ``min_height_m`` above the ground (clutter, from the elevation) and returns farther than
    ``ghost_margin_m`` behind a mapped reflector along their ray (multipath ghosts); the rest are
    gated against tracks with the tracker's own Mahalanobis gate. When the LiDAR's degradation
    index (its share of returns that are isolated and nearer than ``degraded_within_m``, as a
    fraction of ``degraded_noise_fraction``, capped at 1) reaches ``degraded_from``, radar
    positions also update the matched tracks, with the radar's covariance divided by the index
    (radar weighted more as the LiDAR degrades). With ``write_back`` the radar-refined state and
    covariance of every matched track go back into the tracker's filter, so that the radar's
    information persists into the next prediction instead of serving one cycle only.
    """

    rate_hz: float = Field(20.0, gt=0.0, le=240.0)
    mount_z_m: float = Field(0.5, gt=0.0, le=10.0)
    range_std_m: float = Field(0.15, gt=0.0, le=10.0)
    azimuth_std_deg: float = Field(0.3, gt=0.0, le=20.0)
    min_rcs_dbsm: float = Field(-15.0, ge=-60.0, le=60.0)
    min_snr_db: float = Field(10.0, ge=-20.0, le=100.0)
    min_height_m: float = Field(0.15, ge=-5.0, le=5.0)
    ghost_margin_m: float = Field(0.3, ge=0.0, le=10.0)
    degraded_noise_fraction: float = Field(0.15, gt=0.0, le=1.0)
    degraded_within_m: float = Field(5.0, gt=0.0, le=100.0)
    write_back: bool = True
    degraded_from: float = Field(0.3, gt=0.0, le=1.0)


class AcousticSection(Section):
    """Microphone array (#23: 4-8 MEMS microphones about 15 cm apart), its alert detector and
    the governor's cautious mode (SR-ACU-1..4).

    ``n_mics`` microphones on a circle, neighbours ``mic_spacing_m`` apart, centred at
    ``(mount_x_m, mount_y_m)`` in the robot frame, sampled at ``sample_rate_hz``; sound travels
    at ``speed_of_sound_mps``. The detector takes STFTs of ``stft_len`` samples every
    ``stft_hop`` samples; a band's noise floor is the ``floor_quantile`` of its power over the
    analysis window (adaptive: it follows the apron's level). Reversing beepers are tones of
    ``beeper_low_hz``..``beeper_high_hz`` pulsed with a period of ``pulse_min_period_s``..
    ``pulse_max_period_s``: a band is "on" in a frame when its power exceeds the floor by
    ``on_db``, and a beeper is reported when the band's on/off pattern correlates with itself at
    one period by at least ``pulse_min_corr`` and it is on in ``min_on_fraction``..
    ``max_on_fraction`` of the frames. Horns are harmonic stacks with a fundamental of
    ``horn_low_hz``..``horn_high_hz``, reported when the mean excess over the floor of its first
    ``horn_harmonics`` harmonics reaches ``horn_db`` for at least ``horn_min_s``. GCC-PHAT
    peaks are refined on a grid ``gcc_interp`` times finer than the sample period.

    An alert is fresh for ``max_age_s`` (the freshness guard, with the array's clock off the
    decision clock by at most ``clock_skew_s``); while one is fresh the governor commands at most
    ``caution_speed_mps``. An alert is a bearing: it never creates an obstacle.
    """

    n_mics: int = Field(4, ge=4, le=8)
    mic_spacing_m: float = Field(0.15, gt=0.01, le=1.0)
    mount_x_m: float = Field(0.0, ge=-10.0, le=10.0)
    mount_y_m: float = Field(0.0, ge=-10.0, le=10.0)
    sample_rate_hz: float = Field(16_000.0, ge=8_000.0, le=96_000.0)
    speed_of_sound_mps: float = Field(343.0, ge=300.0, le=360.0)
    stft_len: int = Field(512, ge=64, le=8192)
    stft_hop: int = Field(256, ge=16, le=8192)
    floor_quantile: float = Field(0.2, gt=0.0, lt=0.5)
    beeper_low_hz: float = Field(1_000.0, gt=0.0, le=20_000.0)
    beeper_high_hz: float = Field(2_500.0, gt=0.0, le=20_000.0)
    pulse_min_period_s: float = Field(0.4, gt=0.0, le=10.0)
    pulse_max_period_s: float = Field(1.2, gt=0.0, le=10.0)
    on_db: float = Field(6.0, gt=0.0, le=60.0)
    pulse_min_corr: float = Field(0.6, gt=0.0, le=1.0)
    min_on_fraction: float = Field(0.2, ge=0.0, le=1.0)
    max_on_fraction: float = Field(0.8, ge=0.0, le=1.0)
    horn_low_hz: float = Field(250.0, gt=0.0, le=5_000.0)
    horn_high_hz: float = Field(600.0, gt=0.0, le=5_000.0)
    horn_harmonics: int = Field(4, ge=1, le=16)
    horn_db: float = Field(10.0, gt=0.0, le=60.0)
    horn_min_s: float = Field(0.3, gt=0.0, le=10.0)
    gcc_interp: int = Field(8, ge=1, le=64)
    max_age_s: float = Field(2.0, gt=0.0, le=30.0)
    clock_skew_s: float = Field(0.0, ge=0.0, le=1.0)
    caution_speed_mps: float = Field(0.5, ge=0.0, le=10.0)

    @model_validator(mode="after")
    def _consistent(self) -> Self:
        nyquist = self.sample_rate_hz / 2.0
        for low, high in (
            ("beeper_low_hz", "beeper_high_hz"),
            ("pulse_min_period_s", "pulse_max_period_s"),
            ("min_on_fraction", "max_on_fraction"),
            ("horn_low_hz", "horn_high_hz"),
        ):
            if getattr(self, low) >= getattr(self, high):
                raise ValueError(
                    f"acoustic.{low} ({getattr(self, low)}) must be below acoustic.{high} "
                    f"({getattr(self, high)})"
                )
        top = max(self.beeper_high_hz, self.horn_high_hz * self.horn_harmonics)
        if top >= nyquist:
            raise ValueError(
                f"acoustic: the detector's bands reach {top} Hz, at or above the Nyquist "
                f"frequency of acoustic.sample_rate_hz ({nyquist} Hz)"
            )
        if self.stft_hop > self.stft_len:
            raise ValueError(
                f"acoustic.stft_hop ({self.stft_hop}) must not exceed acoustic.stft_len "
                f"({self.stft_len})"
            )
        if self.clock_skew_s >= self.max_age_s:
            raise ValueError(
                f"acoustic.clock_skew_s ({self.clock_skew_s}) must be below acoustic.max_age_s "
                f"({self.max_age_s}): otherwise no alert is ever fresh"
            )
        return self


class MarkingsSection(Section):
    """Retro-reflective ground markings from a multi-ring LiDAR's intensity (#25; SR-MRK-1..3).

    A localisation aid, never a safety input (SR-MRK-4): nothing in the runtime reads this
    section. The scanner (RS32 class: 32 rings from ``elevation_min_deg`` to
    ``elevation_max_deg``, dense near the horizon; ``n_columns`` firings a revolution at
    ``rate_hz``) is mounted ``mount_z_m`` above the ground at ``mount_x_m`` ahead of the robot's
    centre; a ring's beam diverges by ``divergence_mrad``; ranges have ``range_std_m`` noise
    and intensities a relative ``intensity_std`` noise. The detector keeps returns within
    ``ground_tolerance_m`` of the ground plane fitted to the returns near the expected ground
    and within ``max_ground_range_m``; normalises intensity as I_norm = I_raw (range /
    ``ref_range_m``)^2, divided by the incidence cosine when ``incidence_correction``; and keeps
    a return brighter than ``threshold_factor`` x the scan's median ground I_norm. Kept returns
    are binned into a bird's-eye grid of ``bev_cell_m`` cells, clustered (DBSCAN, ``cluster_eps_m``,
    ``cluster_min_samples``; clusters of at least ``min_cluster_cells``), and in each cluster
    straight lines (RANSAC, ``ransac_iterations`` trials seeded by ``ransac_seed``, inliers within
    ``line_inlier_m``, at least ``min_line_inliers`` and ``min_line_length_m`` long) and then arcs
    (radius ``arc_min_radius_m``..``arc_max_radius_m``, inliers within ``arc_inlier_m``, at least
    ``min_arc_inliers``) are fitted, at most ``max_features`` a scan. Map matching aligns the
    fitted features' inliers within ``match_max_range_m`` of the robot (farther, a beam's
    footprint is long along the ray and smears a stripe across it) to the stored map (point to
    centre line, ``match_iterations`` Gauss-Newton steps, pairs farther than ``match_gate_m``
    left out, directions whose
    information per point is below ``min_information`` left uncorrected) and accepts a
    correction with at least ``min_match_points`` pairs, an RMS residual of at most
    ``max_match_rms_m`` and a size of at most ``max_correction_m``.
    """

    elevation_min_deg: float = Field(-25.0, ge=-60.0, lt=0.0)
    elevation_max_deg: float = Field(15.0, gt=0.0, le=60.0)
    n_columns: int = Field(900, ge=16, le=7200)
    rate_hz: float = Field(10.0, gt=0.0, le=40.0)
    mount_x_m: float = Field(0.3, ge=-10.0, le=10.0)
    mount_z_m: float = Field(1.5, gt=0.2, le=5.0)
    divergence_mrad: float = Field(3.0, ge=0.0, le=20.0)
    range_std_m: float = Field(0.02, ge=0.0, le=1.0)
    intensity_std: float = Field(0.1, ge=0.0, le=1.0)
    ground_tolerance_m: float = Field(0.1, gt=0.0, le=1.0)
    max_ground_range_m: float = Field(30.0, gt=1.0, le=200.0)
    ref_range_m: float = Field(10.0, gt=0.0, le=200.0)
    incidence_correction: bool = True
    threshold_factor: float = Field(2.0, gt=1.0, le=20.0)
    bev_cell_m: float = Field(0.1, gt=0.0, le=1.0)
    cluster_eps_m: float = Field(3.0, gt=0.0, le=10.0)
    cluster_min_samples: int = Field(2, ge=1, le=50)
    min_cluster_cells: int = Field(4, ge=1, le=1000)
    ransac_iterations: int = Field(64, ge=1, le=10_000)
    ransac_seed: int = Field(0, ge=0)
    line_inlier_m: float = Field(0.1, gt=0.0, le=1.0)
    min_line_inliers: int = Field(6, ge=2, le=10_000)
    min_line_length_m: float = Field(1.0, gt=0.0, le=100.0)
    arc_inlier_m: float = Field(0.1, gt=0.0, le=1.0)
    arc_min_radius_m: float = Field(2.0, gt=0.0, le=1000.0)
    arc_max_radius_m: float = Field(40.0, gt=0.0, le=1000.0)
    min_arc_inliers: int = Field(8, ge=3, le=10_000)
    max_features: int = Field(24, ge=1, le=1000)
    match_iterations: int = Field(8, ge=1, le=100)
    match_gate_m: float = Field(0.5, gt=0.0, le=10.0)
    match_max_range_m: float = Field(15.0, gt=0.0, le=200.0)
    min_information: float = Field(0.05, gt=0.0, le=1.0)
    min_match_points: int = Field(12, ge=3, le=100_000)
    max_match_rms_m: float = Field(0.1, gt=0.0, le=10.0)
    max_correction_m: float = Field(1.0, gt=0.0, le=100.0)

    @model_validator(mode="after")
    def _ordered(self) -> Self:
        if self.arc_min_radius_m >= self.arc_max_radius_m:
            raise ValueError(
                f"markings.arc_min_radius_m ({self.arc_min_radius_m}) must be below "
                f"markings.arc_max_radius_m ({self.arc_max_radius_m})"
            )
        return self


class MapSection(Section):
    """The site's static map (:mod:`pipeline.static_map`, SR-AVL-8).

    ``file``: a Nav2 ``map_server`` YAML file (empty: no map). In a simulated run with
    ``simulated_world`` (the default) and no file, the simulated world's fixed structure is the
    map, rasterised at ``resolution_m``. A cluster whose every return lies within
    ``tolerance_m`` (cell centre to occupied cell centre) of the map's structure is that
    structure: the governor reads it where it stands, along the path, instead of as an object of
    unknown motion. The map frame is taken to be the tracking frame (assumption A-11: the
    localisation keeps them within ``tolerance_m``). ``tolerance_m + 1.5 resolution_m`` must
    stay below ``runtime.person_radius_m``, so a person's returns cannot all be covered while
    they stand clear of the structure.
    """

    file: str = ""
    simulated_world: bool = True
    resolution_m: float = Field(0.05, gt=0.005, le=0.5)
    tolerance_m: float = Field(0.1, ge=0.0, le=0.5)
