"""The thermal camera's front-end: warm bodies in an LWIR frame, placed on the ground
(SR-FUS-5, SR-FUS-6).

The classical detector of the airside recommendation #22, per frame:

1. **ambient and contrast**: the median and the 1st / 99th percentiles of a 1-in-16 pixel
   sample (every 4th row and column); a frame whose contrast (99th minus 1st percentile) is
   below ``thermal.min_contrast_c`` is *contaminated* (water on the window, a failed shutter):
   it yields nothing, and the stream's last good frame ages until the freshness guard drops it;
2. **threshold** relative to that ambient: pixels warmer than ``ambient + above_ambient_c``
   (adaptive: it follows the scene, not a fixed temperature);
3. **opening** by a 3 x 3 square and **8-connected components**
   (:mod:`pipeline.sensors.components`);
4. **ground contact**: the centre of a component's bottom edge projected to the ground through
   the camera's extrinsic (:class:`pipeline.sensors.camera.PinholeCamera`); a component that
   reaches the image's bottom row, or whose bottom lies above the horizon (a head over a
   vehicle), shows no ground contact and is dropped (counted);
5. **filters**: at least ``min_area_px`` pixels, within ``max_range_m``, area within
   ``area_min_frac``..``area_max_frac`` of the area a ``person_height_m`` x ``person_width_m``
   person would cover standing at that ground point, height / width within
   ``aspect_min``..``aspect_max`` (a sun-loaded vehicle is too wide, a hot strip of asphalt too
   flat), and a peak below ``hot_surface_c`` (exhaust, sun-loaded metal: a body is never that
   hot).

A kept component becomes a detection in the robot frame at the frame's stamp, with its
confidence the ratio of its area to a person's (capped at 1, inverted above 1) and the position
bound its extrinsic's calibration leaves (:meth:`PinholeCamera.ground_error_bound_m`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import ThermalSection
from pipeline.sensors.camera import PinholeCamera
from pipeline.sensors.components import label_runs, opening
from pipeline.types import FloatArray, ThermalDetections
from pipeline.types.sensors import ThermalImage

__all__ = ["ThermalCounts", "ThermalDetector", "ThermalResult"]


@dataclass(frozen=True, slots=True)
class ThermalCounts:
    """What the detector did with one frame's components; every component lands in one bin."""

    n_components: int = 0
    n_small: int = 0
    n_no_ground: int = 0
    n_far: int = 0
    n_hot: int = 0
    n_size: int = 0
    n_aspect: int = 0
    n_kept: int = 0

    def __post_init__(self) -> None:
        bins = (
            self.n_small, self.n_no_ground, self.n_far, self.n_hot, self.n_size, self.n_aspect,
            self.n_kept,
        )  # fmt: skip
        if min(bins) < 0 or sum(bins) != self.n_components:
            raise ValueError(f"ThermalCounts: bins {bins} must sum to {self.n_components}")


@dataclass(frozen=True, slots=True)
class ThermalResult:
    """One frame through the detector: the detections (robot frame), whether the frame was
    contaminated, its ambient and contrast [deg C], each detection's position bound [m], and
    the counts."""

    detections: ThermalDetections
    contaminated: bool
    ambient_c: float
    contrast_c: float
    bound_m: FloatArray
    counts: ThermalCounts


class ThermalDetector:
    """The detector of the module docstring for the camera the ``thermal`` section describes."""

    def __init__(self, section: ThermalSection, camera: PinholeCamera | None = None) -> None:
        self.section = section
        self.camera = camera if camera is not None else PinholeCamera.from_config(section)

    def detect(self, image: ThermalImage) -> ThermalResult:
        """Warm bodies in ``image`` (module docstring)."""
        t = self.section
        pixels = image.pixels_c
        if pixels.shape != (t.height_px, t.width_px):
            raise ValueError(
                f"ThermalDetector: image is {pixels.shape[1]} x {pixels.shape[0]} px; expected "
                f"thermal.width_px x thermal.height_px = {t.width_px} x {t.height_px}"
            )
        sample = pixels[2::4, 2::4].reshape(-1)
        sample = sample[np.isfinite(sample)]
        if sample.shape[0] == 0:
            return self._empty(image.stamp_s, math.nan, 0.0, contaminated=True)
        low, ambient, high = (float(q) for q in np.percentile(sample, (1.0, 50.0, 99.0)))
        contrast = high - low
        if not contrast >= t.min_contrast_c:
            return self._empty(image.stamp_s, ambient, contrast, contaminated=True)
        # NaN pixels compare False: a dead pixel is never foreground.
        mask = opening(pixels > np.float32(ambient + t.above_ambient_c))
        comps = label_runs(mask)
        if comps.n == 0:
            return self._empty(image.stamp_s, ambient, contrast, contaminated=False)
        area = comps.area_px()
        row_min, row_max, col_min, col_max = comps.boxes()
        peak = comps.maximum(pixels)
        height = (row_max - row_min + 1).astype(np.float64)
        width = (col_max - col_min + 1).astype(np.float64)
        u = 0.5 * (col_min + col_max + 1).astype(np.float64)
        v = (row_max + 1).astype(np.float64)
        cam = self.camera
        x_m, y_m, ground = cam.ground_point(u, v)
        f, lft, _ = cam.camera_offsets(x_m, y_m, np.zeros_like(x_m))
        distance = np.where(ground, np.hypot(f, lft), np.inf)  # from the camera, on the ground
        # The pixel area a person standing at the ground point would cover.
        _, v_top, depth = cam.project(x_m, y_m, np.full_like(x_m, t.person_height_m))
        _, _, mid = cam.project(x_m, y_m, np.full_like(x_m, 0.5 * t.person_height_m))
        seen = ground & (depth > 0.0) & (mid > 0.0)
        expected_h = np.where(seen, v - v_top, np.nan)
        expected_w = np.where(seen, cam.fx * t.person_width_m / np.where(seen, mid, 1.0), np.nan)
        ratio = area / (expected_h * expected_w)
        aspect = height / width
        small = area < t.min_area_px
        # A component cut by the image's bottom edge hides its ground contact: no position.
        no_ground = ~small & ~(seen & (expected_h > 0.0) & (row_max < t.height_px - 1))
        far = ~small & ~no_ground & (distance > t.max_range_m)
        rest = ~(small | no_ground | far)
        hot = rest & ~(peak < t.hot_surface_c)
        rest &= ~hot
        size = rest & ~((ratio >= t.area_min_frac) & (ratio <= t.area_max_frac))
        rest &= ~size
        shape = rest & ~((aspect >= t.aspect_min) & (aspect <= t.aspect_max))
        keep = rest & ~shape
        counts = ThermalCounts(
            n_components=comps.n,
            n_small=int(np.count_nonzero(small)),
            n_no_ground=int(np.count_nonzero(no_ground)),
            n_far=int(np.count_nonzero(far)),
            n_hot=int(np.count_nonzero(hot)),
            n_size=int(np.count_nonzero(size)),
            n_aspect=int(np.count_nonzero(shape)),
            n_kept=int(np.count_nonzero(keep)),
        )
        k = np.flatnonzero(keep)
        bound = cam.ground_error_bound_m(
            u[k], v[k], t.calibration_translation_m, math.radians(t.calibration_angle_deg)
        )
        detections = ThermalDetections(
            stamp_s=np.full(k.shape[0], image.stamp_s),
            x_m=x_m[k],
            y_m=y_m[k],
            confidence=np.minimum(ratio[k], 1.0 / ratio[k]),
        )
        return ThermalResult(detections, False, ambient, contrast, bound, counts)

    def _empty(
        self, stamp_s: float, ambient_c: float, contrast_c: float, *, contaminated: bool
    ) -> ThermalResult:
        none = np.empty(0)
        return ThermalResult(
            ThermalDetections(none, none, none, none),
            contaminated,
            ambient_c,
            contrast_c,
            none,
            ThermalCounts(),
        )
