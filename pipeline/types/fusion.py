"""Thermal and radar detections and fused tracks (SR-FUS-*)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.types.core import FloatArray, IntArray, freeze_fields
from pipeline.types.tracking import (
    Tracks,
)


@dataclass(frozen=True, slots=True)
class ThermalDetections:
    """Warm-body detections of a thermal camera, robot frame, one entry each (SR-FUS-1, -3).

    ``stamp_s`` is each detection's capture time on the sensor's clock (which may differ from
    the decision clock by at most ``fusion.clock_skew_s``); ``confidence`` the detector's score
    in [0, 1]. Non-finite values are allowed here: fusion drops and counts them.
    """

    stamp_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    confidence: FloatArray

    def __post_init__(self) -> None:
        freeze_fields(self, ("stamp_s", "x_m", "y_m", "confidence"), np.float64)
        n = self.stamp_s.shape
        if len(n) != 1 or any(getattr(self, k).shape != n for k in ("x_m", "y_m", "confidence")):
            raise ValueError(
                "ThermalDetections: stamp_s, x_m, y_m and confidence must be one-dimensional "
                f"and of equal length, got {[getattr(self, k).shape for k in self.__slots__]}"
            )

    @property
    def n(self) -> int:
        """Number of detections."""
        return int(self.stamp_s.shape[0])


@dataclass(frozen=True, slots=True)
class RadarDetections:
    """Radar returns with Doppler, robot frame, one entry each (SR-FUS-1).

    The radar sits at ``(mount_x_m, mount_y_m)``; ``bearing_rad`` is the direction of the return
    from there in the robot frame and ``radial_velocity_mps`` the measured range rate (positive:
    moving away). Non-finite values are allowed here: fusion drops and counts them.

    A 4-D imaging radar also reports each return's ``elevation_rad`` (up from the horizontal),
    radar cross-section ``rcs_dbsm`` and signal-to-noise ratio ``snr_db`` (None: not reported),
    which its front-end filters on (:mod:`pipeline.sensors.radar`, SR-FUS-7). The front-end
    hands fusion the returns it kept, moved into the tracking frame (the mount then in that
    frame too) with their Doppler compensated for the robot's own motion, and each return's
    ``position_weight`` (None or 0: the return's position is not used, only its Doppler).
    """

    stamp_s: FloatArray
    range_m: FloatArray
    bearing_rad: FloatArray
    radial_velocity_mps: FloatArray
    mount_x_m: float = 0.0
    mount_y_m: float = 0.0
    elevation_rad: FloatArray | None = None
    rcs_dbsm: FloatArray | None = None
    snr_db: FloatArray | None = None
    position_weight: FloatArray | None = None

    def __post_init__(self) -> None:
        names = ("stamp_s", "range_m", "bearing_rad", "radial_velocity_mps")
        freeze_fields(self, names, np.float64)
        optional = tuple(
            k
            for k in ("elevation_rad", "rcs_dbsm", "snr_db", "position_weight")
            if getattr(self, k) is not None
        )
        freeze_fields(self, optional, np.float64)
        n = self.stamp_s.shape
        if len(n) != 1 or any(getattr(self, k).shape != n for k in names + optional):
            shapes = [getattr(self, k).shape for k in names + optional]
            raise ValueError(
                "RadarDetections: stamp_s, range_m, bearing_rad and radial_velocity_mps (and "
                f"any of elevation_rad, rcs_dbsm, snr_db, position_weight) must be "
                f"one-dimensional and of equal length, got {shapes}"
            )
        if not (np.isfinite(self.mount_x_m) and np.isfinite(self.mount_y_m)):
            raise ValueError("RadarDetections: the mount position must be finite")

    @property
    def n(self) -> int:
        """Number of returns."""
        return int(self.stamp_s.shape[0])

    @property
    def x_m(self) -> FloatArray:
        """Robot-frame x of each return [m]."""
        return self.mount_x_m + self.range_m * np.cos(self.bearing_rad)

    @property
    def y_m(self) -> FloatArray:
        """Robot-frame y of each return [m]."""
        return self.mount_y_m + self.range_m * np.sin(self.bearing_rad)


@dataclass(frozen=True, slots=True)
class FusionCounts:
    """What one fusion cycle did with each detection (SR-FUS-1); every input lands in one bin.

    Per sensor: ``invalid`` (non-finite stamp or position), ``stale`` (older than the maximum
    age), ``future`` (stamped later than the clock skew allows), ``over_cap`` (fresh but beyond
    the per-cycle cap), ``matched`` (fused into a track); thermal also ``only`` (became a
    thermal-only pedestrian), radar ``unmatched`` (no track in the gate: not used).
    """

    n_thermal: int = 0
    n_thermal_invalid: int = 0
    n_thermal_stale: int = 0
    n_thermal_future: int = 0
    n_thermal_over_cap: int = 0
    n_thermal_matched: int = 0
    n_thermal_only: int = 0
    n_radar: int = 0
    n_radar_invalid: int = 0
    n_radar_stale: int = 0
    n_radar_future: int = 0
    n_radar_over_cap: int = 0
    n_radar_matched: int = 0
    n_radar_unmatched: int = 0

    def __post_init__(self) -> None:
        thermal = (
            self.n_thermal_invalid,
            self.n_thermal_stale,
            self.n_thermal_future,
            self.n_thermal_over_cap,
            self.n_thermal_matched,
            self.n_thermal_only,
        )
        radar = (
            self.n_radar_invalid,
            self.n_radar_stale,
            self.n_radar_future,
            self.n_radar_over_cap,
            self.n_radar_matched,
            self.n_radar_unmatched,
        )
        if min(*thermal, *radar) < 0 or sum(thermal) != self.n_thermal:
            raise ValueError(f"FusionCounts: thermal bins {thermal} must sum to {self.n_thermal}")
        if sum(radar) != self.n_radar:
            raise ValueError(f"FusionCounts: radar bins {radar} must sum to {self.n_radar}")

    @property
    def lidar_only(self) -> bool:
        """True when nothing from thermal or radar was fused this cycle (LiDAR-only fallback)."""
        return self.n_thermal_matched + self.n_thermal_only + self.n_radar_matched == 0


@dataclass(frozen=True, slots=True)
class FusedTracks:
    """LiDAR tracks after fusion, plus thermal-only pedestrians (SR-FUS-1, SR-FUS-3).

    ``tracks`` are the tracker's snapshot with the velocity of radar-matched tracks refined by
    the Doppler update; ``confidence`` (one per track) the classifier's confidence raised for
    thermal-matched tracks; ``thermal_index`` / ``radar_index`` the input detection fused into
    each track or -1. Pedestrians (one per unmatched fresh thermal detection): position as
    detected at ``pedestrian_stamp_s`` [robot frame, m], ``pedestrian_confidence`` below
    ``classify.medium_confidence_min`` (most cautious tier), ``pedestrian_index`` the input
    detection.
    """

    stamp_s: float
    tracks: Tracks
    confidence: FloatArray
    thermal_index: IntArray
    radar_index: IntArray
    pedestrian_x_m: FloatArray
    pedestrian_y_m: FloatArray
    pedestrian_stamp_s: FloatArray
    pedestrian_confidence: FloatArray
    pedestrian_index: IntArray
    counts: FusionCounts

    def __post_init__(self) -> None:
        freeze_fields(self, ("confidence",), np.float64)
        freeze_fields(self, ("thermal_index", "radar_index", "pedestrian_index"), np.int64)
        names = ("pedestrian_x_m", "pedestrian_y_m", "pedestrian_stamp_s", "pedestrian_confidence")
        freeze_fields(self, names, np.float64)
        n = self.tracks.n
        for name in ("confidence", "thermal_index", "radar_index"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"FusedTracks: {name} must have shape ({n},)")
        m = self.pedestrian_index.shape
        if len(m) != 1 or any(getattr(self, k).shape != m for k in names):
            raise ValueError("FusedTracks: pedestrian arrays must have equal length")

    @property
    def n_pedestrians(self) -> int:
        """Number of thermal-only pedestrians."""
        return int(self.pedestrian_index.shape[0])
