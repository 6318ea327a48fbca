"""Weather and light in the simulator: fog, rain, night and sun, and what they do to the
sensors (SR-SIM-6).

A :class:`Weather` describes the conditions of a run; the sensor models read what they need
from it. The physics is textbook and each constant is named where it is defined:

* **Fog** (meteorological visibility ``visibility_m``): the extinction coefficient at 550 nm
  is Koschmieder's ``3.912 / V`` (the 2 % contrast threshold). Kim, McArthur and Korevaar
  (SPIE 4214, 2001) give its wavelength dependence ``(lambda / 550 nm)^-q`` with ``q = 0``
  below 500 m visibility, so a 905 nm LiDAR sees the same extinction in fog.
* **Rain** (``rain_mmph``): Carbonneau's empirical near-infrared attenuation
  ``1.076 R^0.67 dB/km`` (a few dB/km: rain matters to a LiDAR through wet surfaces and drops
  on its window far more than through the air), plus a per-beam loss of
  :data:`RAIN_DROPOUT_PER_MMPH` for those (a model parameter, not a measured figure).
* **LiDAR**: a target at the clear-air maximum range ``R0`` is at the detection threshold;
  two-way extinction over ``R`` scales the returned power by ``exp(-2 alpha R)``, so the
  farthest detectable range ``R`` solves ``R^2 exp(2 alpha R) = R0^2``
  (:func:`attenuated_range_m`). Droplets in the first metres of the beam scatter light back
  into the receiver: with probability ``1 - exp(-alpha * BACKSCATTER_PATH_M)`` a beam returns a
  spurious near range (uniform up to :data:`BACKSCATTER_MAX_RANGE_M`, only when nearer than
  the surface it would have hit).
* **Thermal** (LWIR, 8-14 um): the apparent temperature difference of a surface against the
  air fades as ``exp(-beta r)`` with ``beta`` a fraction :data:`LWIR_FOG_RATIO` of the visible
  fog extinction (fog droplets of a few um scatter 10 um light far less than visible light;
  a model parameter) plus the rain term; ``lens_contamination`` (water on the window) removes
  that fraction of every contrast in the frame. At night the sky is far colder than the air
  and nothing is sun-loaded; by day ``sun_load_c`` heats sunlit metal and asphalt.

:data:`WEATHER_PRESETS` names the conditions the scenarios and the configuration use; ``clear``
changes nothing (the LiDAR model then makes no extra draws: runs stay bit-identical).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from pipeline.sources.sim.lidar import LidarSpec, attenuated_range_m

__all__ = [
    "BACKSCATTER_MAX_RANGE_M",
    "BACKSCATTER_PATH_M",
    "CLEAR",
    "KOSCHMIEDER",
    "LWIR_FOG_RATIO",
    "RAIN_DROPOUT_PER_MMPH",
    "WEATHER_PRESETS",
    "Weather",
    "attenuated_range_m",
    "weather_lidar",
]

KOSCHMIEDER = 3.912
"""``-ln(0.02)``: extinction [1/m] times visibility [m] at the 2 % contrast threshold."""

BACKSCATTER_PATH_M = 1.5
"""Path length in front of the window [m] whose droplets can return a spurious echo."""

BACKSCATTER_MAX_RANGE_M = 2.5
"""Spurious (backscatter) echoes appear up to this range [m]."""

RAIN_DROPOUT_PER_MMPH = 0.004
"""Beams lost per mm/h of rain (wet dark surfaces, drops on the window); model parameter."""

MAX_RAIN_DROPOUT = 0.5
"""Upper bound of the rain dropout probability."""

LWIR_FOG_RATIO = 0.4
"""LWIR fog extinction as a fraction of the visible one (model parameter)."""


def _carbonneau_per_m(rain_mmph: float) -> float:
    """Near-infrared rain extinction [1/m] from Carbonneau's 1.076 R^0.67 dB/km."""
    if rain_mmph <= 0.0:
        return 0.0
    db_per_km = 1.076 * math.pow(rain_mmph, 0.67)
    return db_per_km * math.log(10.0) / 10.0 / 1000.0


@dataclass(frozen=True, slots=True)
class Weather:
    """Conditions of one run (module docstring). Temperatures in deg C.

    ``visibility_m`` is the meteorological visibility (``inf``: no fog); ``rain_mmph`` the rain
    rate; ``night`` removes the sun; ``ambient_c`` is the air temperature; ``sun_load_c`` how
    far sunlit metal and asphalt rise above the air by day (ignored at night);
    ``lens_contamination`` the fraction of thermal contrast lost on the camera window.
    """

    name: str = "clear"
    visibility_m: float = math.inf
    rain_mmph: float = 0.0
    night: bool = False
    ambient_c: float = 15.0
    sun_load_c: float = 0.0
    lens_contamination: float = 0.0

    def __post_init__(self) -> None:
        problems = []
        if not self.visibility_m > 0.0:
            problems.append(f"visibility_m {self.visibility_m} must be > 0")
        if not (math.isfinite(self.rain_mmph) and self.rain_mmph >= 0.0):
            problems.append(f"rain_mmph {self.rain_mmph} must be >= 0")
        if not (math.isfinite(self.ambient_c) and -60.0 <= self.ambient_c <= 60.0):
            problems.append(f"ambient_c {self.ambient_c} must be in [-60, 60]")
        if not (math.isfinite(self.sun_load_c) and self.sun_load_c >= 0.0):
            problems.append(f"sun_load_c {self.sun_load_c} must be >= 0")
        if not 0.0 <= self.lens_contamination <= 1.0:
            problems.append(f"lens_contamination {self.lens_contamination} must be in [0, 1]")
        if problems:
            raise ValueError(f"Weather {self.name}: " + "; ".join(problems))

    @property
    def fog_extinction_per_m(self) -> float:
        """Koschmieder's visible (and, below 500 m visibility, near-infrared) extinction."""
        return 0.0 if math.isinf(self.visibility_m) else KOSCHMIEDER / self.visibility_m

    @property
    def lidar_extinction_per_m(self) -> float:
        """Near-infrared extinction [1/m]: fog plus rain."""
        return self.fog_extinction_per_m + _carbonneau_per_m(self.rain_mmph)

    @property
    def lwir_extinction_per_m(self) -> float:
        """Long-wave infrared extinction [1/m]: the fog share plus rain."""
        return LWIR_FOG_RATIO * self.fog_extinction_per_m + _carbonneau_per_m(self.rain_mmph)

    @property
    def sun_c(self) -> float:
        """Sun load in force [deg C above the air]: none at night."""
        return 0.0 if self.night else self.sun_load_c

    @property
    def sky_c(self) -> float:
        """Apparent sky temperature [deg C]: a clear night sky is some 20 C below the air;
        fog or rain close the sky off near the air temperature."""
        overcast = self.fog_extinction_per_m > 0.0 or self.rain_mmph > 0.0
        return self.ambient_c - (2.0 if overcast else (20.0 if self.night else 12.0))

    @property
    def ground_c(self) -> float:
        """Asphalt [deg C]: a little above the air at night (it gives back the day's heat),
        sun-loaded by day, at the air's temperature when wet."""
        if self.rain_mmph > 0.0:
            return self.ambient_c
        return self.ambient_c + (1.5 if self.night else 0.6 * self.sun_c)

    @property
    def active(self) -> bool:
        """Whether anything differs from clear air for the LiDAR."""
        return self.lidar_extinction_per_m > 0.0 or self.rain_mmph > 0.0

    def with_changes(self, **changes: object) -> Weather:
        """A copy with some fields changed (validated again)."""
        return replace(self, **changes)  # type: ignore[arg-type]


def weather_lidar(spec: LidarSpec, weather: Weather) -> LidarSpec:
    """``spec`` with the weather's LiDAR effects (module docstring); ``spec`` itself when the
    weather changes nothing for a LiDAR (clear air, night or day alike)."""
    if not weather.active:
        return spec
    alpha = weather.lidar_extinction_per_m
    return spec.with_changes(
        extinction_per_m=alpha,
        weather_dropout_prob=min(RAIN_DROPOUT_PER_MMPH * weather.rain_mmph, MAX_RAIN_DROPOUT),
        backscatter_prob=1.0 - math.exp(-alpha * BACKSCATTER_PATH_M),
        backscatter_max_range_m=BACKSCATTER_MAX_RANGE_M,
    )


CLEAR = Weather()

WEATHER_PRESETS: dict[str, Weather] = {
    w.name: w
    for w in (
        CLEAR,
        Weather("day_sun", ambient_c=28.0, sun_load_c=30.0),
        Weather("night", night=True, ambient_c=8.0),
        Weather("fog", visibility_m=60.0, ambient_c=8.0),
        Weather("night_fog", visibility_m=40.0, night=True, ambient_c=5.0),
        Weather("rain", rain_mmph=8.0, ambient_c=12.0, lens_contamination=0.3),
        Weather("heavy_rain", rain_mmph=30.0, ambient_c=12.0, lens_contamination=0.9),
    )
}
"""Named conditions: ``clear`` (default), ``day_sun``, ``night``, ``fog`` (60 m visibility),
``night_fog`` (40 m), ``rain`` (8 mm/h, some water on the camera window), ``heavy_rain``
(30 mm/h, the window nearly blinded)."""
