"""Which directions and speeds each zone is in use for (SR-NAV-1).

The robot's limits (:class:`RobotLimits`) come from the command line, else the Nav2 file
(:class:`~safety.nav2.params.Nav2Params`), else the project's configuration (forward speed
``stopping.robot_max_speed_mps``, yaw rate ``geometry.max_yaw_rate_radps``; no reversing and no
sideways travel unless given), each with where it came from.

* A static polygon or circle is in use at every speed: forward up to the forward limit, reverse
  up to the reverse limit; a robot with a lateral limit may translate in any direction, up to
  ``max(forward, reverse) + lateral`` (a rational bound on the speed's magnitude).
* A velocity polygon's sub-polygon is in use where Nav2 selects it: the first sub-polygon whose
  ``linear_min..linear_max`` and ``theta_min..theta_max`` hold the commanded velocity
  (``VelocityPolygon::isInRange``). The velocity box of the robot is cut at every band edge; in
  each cell the first match is found. A velocity that no sub-polygon holds keeps whichever one
  was in use before (Nav2 only warns), so its speed is charged to every sub-polygon. Holonomic
  sub-polygons are charged their own magnitude band (first-match precedence ignored: more
  usage, never less), and a velocity counts as held only when the direction sectors of the
  sub-polygons holding it cover every direction.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from fractions import Fraction
from itertools import pairwise

from pipeline.config import SafecaseConfig
from safety.nav2.params import PI, Limit, Nav2Params, SubPolygon, Zone

__all__ = ["Overrides", "RobotLimits", "Use", "resolve_limits", "zone_uses"]

ZERO = Fraction(0)
# (cell low end, cell high end, sample point) of commanded x [m/s]
Cell = tuple[Fraction, Fraction, Fraction]


@dataclass(frozen=True, slots=True)
class Overrides:
    """Limits given on the command line (None: take them from the file or the configuration)."""

    max_speed_mps: Fraction | None = None
    max_reverse_speed_mps: Fraction | None = None
    max_lateral_speed_mps: Fraction | None = None
    max_yaw_rate_radps: Fraction | None = None
    control_period_s: Fraction | None = None


@dataclass(frozen=True, slots=True)
class RobotLimits:
    """The robot's speed limits [m/s, rad/s], each with its source."""

    forward: Limit
    reverse: Limit
    lateral: Limit
    yaw_rate: Limit

    @property
    def holonomic(self) -> bool:
        """True when the robot may translate sideways."""
        return self.lateral.value > 0

    @property
    def top_speed_mps(self) -> Fraction:
        """An upper bound on the speed's magnitude in any direction [m/s]."""
        return max(self.forward.value, self.reverse.value) + self.lateral.value


@dataclass(frozen=True, slots=True)
class Use:
    """A zone (or sub-polygon) in use while travelling ``travel`` at speeds ``[low, high]``."""

    travel: str  # forward | reverse | any
    low_mps: Fraction
    high_mps: Fraction
    why: str


def _pick(cli: Fraction | None, option: str, found: Limit | None, fallback: Limit) -> Limit:
    if cli is not None:
        return Limit(cli, f"--{option}")
    return found if found is not None else fallback


def resolve_limits(params: Nav2Params, config: SafecaseConfig, cli: Overrides) -> RobotLimits:
    """The robot's limits: command line, else the Nav2 file, else the configuration."""
    return RobotLimits(
        forward=_pick(
            cli.max_speed_mps,
            "max-speed",
            params.forward,
            Limit(
                Fraction(repr(config.stopping.robot_max_speed_mps)),
                "stopping.robot_max_speed_mps; the file gives none",
            ),
        ),
        reverse=_pick(
            cli.max_reverse_speed_mps,
            "max-reverse-speed",
            params.reverse,
            Limit(ZERO, "the file gives none: no reversing; check it with --max-reverse-speed"),
        ),
        lateral=_pick(
            cli.max_lateral_speed_mps,
            "max-lateral-speed",
            params.lateral,
            Limit(ZERO, "the file gives none: no sideways travel"),
        ),
        yaw_rate=_pick(
            cli.max_yaw_rate_radps,
            "max-yaw-rate",
            params.yaw_rate,
            Limit(
                Fraction(repr(config.geometry.max_yaw_rate_radps)),
                "geometry.max_yaw_rate_radps; the file gives none",
            ),
        ),
    )


def _static_uses(limits: RobotLimits) -> list[Use]:
    if limits.holonomic:
        return [Use("any", ZERO, limits.top_speed_mps, "every velocity of the robot")]
    uses = []
    if limits.forward.value > 0:
        uses.append(Use("forward", ZERO, limits.forward.value, "every forward speed"))
    if limits.reverse.value > 0:
        uses.append(Use("reverse", ZERO, limits.reverse.value, "every reverse speed"))
    return uses


def _cells(
    edges: Iterable[Fraction], low: Fraction, high: Fraction
) -> list[tuple[Fraction, Fraction]]:
    """Sample points of the cells of ``[low, high]`` cut at ``edges``: (point, cell high end).

    Each breakpoint is its own cell; each open interval between two is sampled at its middle.
    """
    cuts = sorted({low, high, *(e for e in edges if low < e < high)})
    cells = [(c, c) for c in cuts]
    cells += [((a + b) / 2, b) for a, b in pairwise(cuts)]
    return cells


def _yaw_samples(subs: tuple[SubPolygon, ...], yaw: Fraction) -> list[Fraction]:
    edges = [e for s in subs for e in (s.theta_min_radps, s.theta_max_radps)]
    return [point for point, _ in _cells(edges, -yaw, yaw)]


def _matches(sub: SubPolygon, x: Fraction, yaw: Fraction) -> bool:
    in_theta = sub.theta_min_radps <= yaw <= sub.theta_max_radps
    return in_theta and sub.linear_min_mps <= x <= sub.linear_max_mps


def _sectors_cover(subs: list[SubPolygon]) -> bool:
    """True when the direction sectors of ``subs`` cover every direction in [-pi, pi]."""
    spans: list[tuple[Fraction, Fraction]] = []
    for s in subs:
        start, end = s.direction_start_rad, s.direction_end_rad
        spans += [(start, end)] if start <= end else [(start, PI), (-PI, end)]
    reach = -PI
    for start, end in sorted(spans):
        if start > reach:
            return False
        reach = max(reach, end)
    return reach >= PI


def _x_usage(zone: Zone, limits: RobotLimits) -> tuple[dict[str, list[Cell]], bool]:
    """Per sub-polygon, the cells of commanded x where Nav2 may use it; and whether gaps exist."""
    subs = zone.subpolygons
    yaws = _yaw_samples(subs, limits.yaw_rate.value)
    edges = [e for s in subs for e in (s.linear_min_mps, s.linear_max_mps)]
    first: dict[str, list[Cell]] = {s.name: [] for s in subs}
    uncovered: list[Cell] = []
    # Zero is a cut: each cell lies on one side of standstill.
    for x, cell_high in _cells([*edges, ZERO], -limits.reverse.value, limits.forward.value):
        cell = (x if x == cell_high else 2 * x - cell_high, cell_high, x)
        for w in yaws:
            chosen = next((s for s in subs if _matches(s, x, w)), None)
            (first[chosen.name] if chosen is not None else uncovered).append(cell)
    return {name: cells + uncovered for name, cells in first.items()}, bool(uncovered)


def _directional_uses(cells: list[Cell], limits: RobotLimits, gaps: bool) -> list[Use]:
    note = " (with the velocities no sub-polygon holds)" if gaps else ""
    if limits.holonomic:
        # Nav2 selects by x alone: any sideways speed may be added to the x it selected by.
        reach = max(max(abs(low), abs(high)) for low, high, _ in cells)
        high = min(reach + limits.lateral.value, limits.top_speed_mps)
        return [Use("any", ZERO, high, f"commanded |x| up to {float(reach):g} m/s{note}")]
    uses = []
    ahead = [(lo, hi) for lo, hi, x in cells if x > 0 or (x == 0 and limits.forward.value > 0)]
    behind = [(-hi, -lo) for lo, hi, x in cells if x < 0 or (x == 0 and limits.reverse.value > 0)]
    for travel, spans in (("forward", ahead), ("reverse", behind)):
        if spans:
            low = max(min(lo for lo, _ in spans), ZERO)
            high = max(hi for _, hi in spans)
            axis = "x" if travel == "forward" else "-x"
            uses.append(Use(travel, low, high, f"commanded {axis} in {_span(low, high)}{note}"))
    return uses


def _holonomic_uses(zone: Zone, limits: RobotLimits) -> dict[str, list[Use]]:
    subs = zone.subpolygons
    top = limits.top_speed_mps
    yaws = _yaw_samples(subs, limits.yaw_rate.value)
    edges = [e for s in subs for e in (s.linear_min_mps, s.linear_max_mps)]
    gaps = [
        (m if m == high else 2 * m - high, high)
        for m, high in _cells(edges, ZERO, top)
        if any(not _sectors_cover([s for s in subs if _matches(s, m, w)]) for w in yaws)
    ]
    note = " (with the velocities no sub-polygon holds)" if gaps else ""
    result: dict[str, list[Use]] = {}
    for s in subs:
        spans = list(gaps)
        low, high = max(s.linear_min_mps, ZERO), min(s.linear_max_mps, top)
        if low <= high:
            spans.append((low, high))
        result[s.name] = []
        if spans:
            low, high = min(lo for lo, _ in spans), max(hi for _, hi in spans)
            why = f"speed magnitudes {_span(low, high)}{note}"
            result[s.name].append(Use("any", low, high, why))
    return result


def _velocity_uses(zone: Zone, limits: RobotLimits) -> dict[str, list[Use]]:
    if zone.holonomic:
        return _holonomic_uses(zone, limits)
    usage, gaps = _x_usage(zone, limits)
    return {
        name: _directional_uses(cells, limits, gaps) if cells else []
        for name, cells in usage.items()
    }


def _span(low: Fraction, high: Fraction) -> str:
    return f"[{float(low):g}, {float(high):g}] m/s"


def zone_uses(zone: Zone, limits: RobotLimits) -> dict[str, list[Use]]:
    """Uses of the zone, keyed by sub-polygon name ("" for a zone of one shape)."""
    if zone.shape == "velocity_polygon":
        return _velocity_uses(zone, limits)
    return {"": _static_uses(limits)}
