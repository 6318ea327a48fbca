"""The thermal camera's geometry: a pinhole on the robot, and its ground projection with the
error bound its extrinsic calibration leaves (SR-FUS-6).

Robot frame: x forward, y left, z up, origin on the ground. The camera sits at
``(mount_x_m, mount_y_m, mount_z_m)``, turned ``yaw_rad`` counter-clockwise and pitched
``pitch_rad`` down. Camera axes: X right, Y down, Z along the optical axis; with ``(f, l, u)``
a point's forward, leftward and upward offsets from the camera in its yaw-aligned frame and
``c, s`` the cosine and sine of the pitch::

    X = -l,   Y = -f s - u c,   Z = f c - u s,   pixel (cx + fx X / Z, cy + fy Y / Z).

Pixel ``(u, v)`` is continuous, 0 at the left (top) edge of the first column (row), so the centre
of pixel ``(i, j)`` is ``(j + 0.5, i + 0.5)``. :meth:`PinholeCamera.ground_point` inverts the
projection for points on the ground: the ray ``(x, y, 1) = ((u - cx) / fx, (v - cy) / fy, 1)``
meets the ground at ``t = h / (c y + s)`` (looking down: ``c y + s > 0``), at forward
``h (c - s y) / (c y + s)`` and leftward ``-h x / (c y + s)``.

Error bound (:meth:`PinholeCamera.ground_error_bound_m`). The extrinsic is known to within
``dt`` per translation axis and ``da`` in pitch and yaw (roll is not modelled). For a fixed
pixel, the forward offset is strictly decreasing in the pitch (its derivative is
``-h (D^2 + N^2) / D^2`` with ``D = c y + s``, ``N = c - s y``), the leftward offset is
monotone in the pitch while the ray points ahead, ``N > 0`` (derivative ``h x N / D^2``), and
both are linear in the height, so over the box ``pitch +- da, height +- dt`` each offset's
largest change is reached at one of its four corners. The yaw error turns the offset vector
``p`` about the camera, moving it by at most ``|p| da``; the horizontal translation moves
everything by at most ``sqrt(2) dt``. By the triangle inequality the true ground point lies within

    ``B = sqrt(2) dt + sqrt(max |d forward|^2 + max |d left|^2) + (|p| + max |dp|) da``

of the projected one (``inf`` when at a corner of the box the pixel does not look at the
ground ahead: at or above the horizon, or behind the camera).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from pipeline.config import ThermalSection
from pipeline.types import BoolArray, FloatArray

__all__ = ["PinholeCamera"]


@dataclass(frozen=True, slots=True)
class PinholeCamera:
    """A pinhole camera mounted on the robot (module docstring); lengths in metres, angles in
    radians, sizes in pixels."""

    width_px: int
    height_px: int
    hfov_rad: float
    mount_x_m: float
    mount_y_m: float
    mount_z_m: float
    yaw_rad: float
    pitch_rad: float

    def __post_init__(self) -> None:
        if not (0.0 < self.hfov_rad < math.pi and self.mount_z_m > 0.0):
            raise ValueError(f"PinholeCamera: need 0 < hfov < pi and height > 0, got {self}")

    @staticmethod
    def from_config(section: ThermalSection) -> PinholeCamera:
        """The camera the ``thermal`` section describes."""
        return PinholeCamera(
            width_px=section.width_px,
            height_px=section.height_px,
            hfov_rad=math.radians(section.hfov_deg),
            mount_x_m=section.mount_x_m,
            mount_y_m=section.mount_y_m,
            mount_z_m=section.mount_z_m,
            yaw_rad=math.radians(section.mount_yaw_deg),
            pitch_rad=math.radians(section.mount_pitch_deg),
        )

    @property
    def fx(self) -> float:
        """Focal length [px] (square pixels: also the vertical one)."""
        return 0.5 * self.width_px / math.tan(0.5 * self.hfov_rad)

    @property
    def cx(self) -> float:
        """Principal point, horizontal [px]."""
        return 0.5 * self.width_px

    @property
    def cy(self) -> float:
        """Principal point, vertical [px]."""
        return 0.5 * self.height_px

    def perturbed(
        self, dx_m: float, dy_m: float, dz_m: float, dyaw_rad: float, dpitch_rad: float
    ) -> PinholeCamera:
        """The same camera with its extrinsic moved (a calibration error)."""
        return replace(
            self,
            mount_x_m=self.mount_x_m + dx_m,
            mount_y_m=self.mount_y_m + dy_m,
            mount_z_m=self.mount_z_m + dz_m,
            yaw_rad=self.yaw_rad + dyaw_rad,
            pitch_rad=self.pitch_rad + dpitch_rad,
        )

    def camera_offsets(
        self, x_m: FloatArray, y_m: FloatArray, z_m: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Robot-frame points as forward, leftward, upward offsets in the yaw-aligned frame."""
        dx, dy = x_m - self.mount_x_m, y_m - self.mount_y_m
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return c * dx + s * dy, -s * dx + c * dy, z_m - self.mount_z_m

    def project(
        self, x_m: FloatArray, y_m: FloatArray, z_m: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Pixel coordinates ``(u, v)`` and depth ``Z`` [m] of robot-frame points (a point
        behind the camera has ``Z <= 0`` and meaningless pixel coordinates)."""
        f, lft, up = self.camera_offsets(x_m, y_m, z_m)
        c, s = math.cos(self.pitch_rad), math.sin(self.pitch_rad)
        depth = f * c - up * s
        safe = np.where(depth > 0.0, depth, 1.0)
        u = self.cx + self.fx * (-lft) / safe
        v = self.cy + self.fx * (-f * s - up * c) / safe
        return u, v, depth

    def _ground_offsets(
        self, u: FloatArray, v: FloatArray, pitch_rad: float, height_m: float
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Forward and leftward offsets of the ground point seen at pixel ``(u, v)``."""
        x = (u - self.cx) / self.fx
        y = (v - self.cy) / self.fx
        c, s = math.cos(pitch_rad), math.sin(pitch_rad)
        down = c * y + s
        ahead = c - s * y
        ok = (down > 0.0) & (ahead > 0.0)
        t = np.where(ok, height_m / np.where(ok, down, 1.0), np.nan)
        return t * ahead, -t * x, ok

    def ground_point(
        self, u: FloatArray, v: FloatArray
    ) -> tuple[FloatArray, FloatArray, BoolArray]:
        """Robot-frame ``(x_m, y_m)`` of the ground point seen at pixel ``(u, v)``, and whether
        the pixel looks at the ground ahead of the camera (below the horizon, forward)."""
        f, lft, ok = self._ground_offsets(u, v, self.pitch_rad, self.mount_z_m)
        c, s = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return self.mount_x_m + c * f - s * lft, self.mount_y_m + s * f + c * lft, ok

    def ground_error_bound_m(
        self, u: FloatArray, v: FloatArray, translation_m: float, angle_rad: float
    ) -> FloatArray:
        """Largest distance [m] between the ground point :meth:`ground_point` gives for pixel
        ``(u, v)`` and the true one, when the true extrinsic differs from this one by at most
        ``translation_m`` per axis and ``angle_rad`` in pitch and yaw (module docstring)."""
        f0, l0, ok = self._ground_offsets(u, v, self.pitch_rad, self.mount_z_m)
        worst_f = np.zeros_like(f0)
        worst_l = np.zeros_like(f0)
        for dp in (-angle_rad, angle_rad):
            for dh in (-translation_m, translation_m):
                f1, l1, ok1 = self._ground_offsets(u, v, self.pitch_rad + dp, self.mount_z_m + dh)
                ok = ok & ok1
                worst_f = np.maximum(worst_f, np.abs(f1 - f0))
                worst_l = np.maximum(worst_l, np.abs(l1 - l0))
        shift = np.hypot(worst_f, worst_l)
        bound = math.sqrt(2.0) * translation_m + shift + (np.hypot(f0, l0) + shift) * angle_rad
        return np.where(ok, bound, np.inf)
