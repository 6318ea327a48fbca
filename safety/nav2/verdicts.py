"""``nav2 check``: prove or refute every zone of a Nav2 collision monitor (SR-NAV-1, SR-NAV-2).

For each enabled zone and each way it is in use (:mod:`safety.nav2.usage`):

* ``stop``: the obligation of :func:`~safety.nav2.obligations.stop_obligation`, decided by z3;
  a refuted zone gets the counterexample (confirmed with the exact Fraction reading of the same
  formula), the separation it needs at the top of its band and its largest safe speed (proved).
* ``approach``: :func:`~safety.nav2.obligations.approach_obligation`, with the speeds at which
  ``time_before_collision`` does suffice; the zone must hold the robot's footprint (Nav2 measures
  the time to collision from it).
* ``slowdown``, ``limit``, ``none``: make no claim about stopping, and say what they do.

A zone whose shape is only known at run time (``polygon_sub_topic``) is UNKNOWN. The check's
verdict: REFUTED when any obligation is refuted, else UNKNOWN when any is unknown, else PROVED
(and REFUTED when no enabled zone stops the robot at all).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from fractions import Fraction

from pipeline.config import SafecaseConfig
from safety.model.stopping import ClosingClass, StoppingParams, separation_m
from safety.nav2.geometry import Footprint, Vertex, contains_footprint
from safety.nav2.obligations import (
    Coverage,
    Model,
    Reaction,
    approach_interval_mps,
    approach_obligation,
    coverage,
    needed_m,
    safe_speed,
    stop_obligation,
)
from safety.nav2.params import Limit, Nav2Params, Zone
from safety.nav2.solver import Obligation, Outcome, Verdict, decide
from safety.nav2.usage import Overrides, RobotLimits, Use, resolve_limits, zone_uses

__all__ = ["EXIT_CODES", "LATENCIES", "Finding", "Report", "build_model", "check"]

LATENCIES = ("nav2", "project")
EXIT_CODES = {Verdict.PROVED: 0, Verdict.REFUTED: 1, Verdict.UNKNOWN: 3}


def _g(value: Fraction | float) -> str:
    return f"{float(value):.6g}"


@dataclass(frozen=True, slots=True)
class Finding:
    """One claim about one zone (or sub-polygon) and one way it is used, with its verdict.

    ``verdict`` None: the zone makes no claim about stopping (slowdown, limit, none, disabled,
    never in use); ``detail`` says why, or gives the counterexample and the safe speed.
    """

    zone: str
    part: str
    action: str
    travel: str
    low_mps: Fraction | None
    high_mps: Fraction | None
    verdict: Verdict | None
    gives: str = ""
    detail: str = ""
    obligation: Obligation | None = None
    outcome: Outcome | None = None
    needed_m: Fraction | None = None
    safe_mps: Fraction | None = None
    safe_outcome: Outcome | None = None
    why: str = ""

    @property
    def label(self) -> str:
        """``PolygonStop`` or ``VelocityStop/fast``."""
        return f"{self.zone}/{self.part}" if self.part else self.zone


@dataclass(frozen=True, slots=True)
class Report:
    """Every finding of one check, the model it used and the robot limits it assumed."""

    params: Nav2Params
    model: Model
    limits: RobotLimits
    findings: tuple[Finding, ...]

    @property
    def verdict(self) -> Verdict:
        """REFUTED if any claim is refuted, else UNKNOWN if any is unknown, else PROVED."""
        verdicts = {f.verdict for f in self.findings}
        for worst in (Verdict.REFUTED, Verdict.UNKNOWN):
            if worst in verdicts:
                return worst
        return Verdict.PROVED

    @property
    def exit_code(self) -> int:
        """0 every claim proved, 1 some refuted, 3 some unknown (never a pass)."""
        return EXIT_CODES[self.verdict]

    def assumptions(self) -> list[str]:
        """What the verdicts rest on, in words."""
        fp, limits = self.model.footprint, self.limits
        return [
            f"footprint: the robot lies in the {_g(fp.length_m)} x {_g(fp.width_m)} m rectangle "
            f"centred on {self.params.base_frame_id} (geometry.footprint_length_m, "
            "geometry.footprint_width_m)",
            f"reaction time T = {self.model.reaction.describe()}",
            f"obstacle: {self.model.closing.value}, closing head-on at up to "
            f"{_g(self.model.closing_mps)} m/s; it gives at least min_points readings inside a "
            "zone it is in",
            "travel: straight-line translation (the sweep of a turning robot is not covered); "
            "velocity polygons are selected by the commanded velocity, and the robot is taken "
            "to move no faster than that command",
            *(
                f"{name}: {_g(limit.value)} {unit} ({limit.source})"
                for name, limit, unit in (
                    ("forward speed", limits.forward, "m/s"),
                    ("reverse speed", limits.reverse, "m/s"),
                    ("sideways speed", limits.lateral, "m/s"),
                    ("yaw rate", limits.yaw_rate, "rad/s"),
                )
            ),
        ]


def build_model(
    params: Nav2Params,
    config: SafecaseConfig,
    *,
    latency: str = "nav2",
    closing: ClosingClass = ClosingClass.STATIC,
    overrides: Overrides | None = None,
) -> tuple[Model, RobotLimits]:
    """The stopping model of ``config`` with the reaction time of ``latency`` (nav2 | project)."""
    if latency not in LATENCIES:
        raise ValueError(f"latency = {latency!r}: allowed: {' | '.join(LATENCIES)}")
    cli = overrides or Overrides()
    stopping = StoppingParams.from_config(config).exact()
    if latency == "project":
        reaction = Reaction(
            stopping.perception_latency_s,
            f"stopping.perception_latency_s, {stopping.latency_source}",
            stopping.control_cycle_s,
            "stopping.control_cycle_s",
        )
    else:
        period = (
            Limit(cli.control_period_s, "--control-period")
            if cli.control_period_s is not None
            else params.control_period
            or Limit(
                stopping.control_cycle_s,
                "stopping.control_cycle_s: the file gives no controller or smoother frequency",
            )
        )
        reaction = Reaction(
            params.data_age_bound_s(),
            "the largest source_timeout of the enabled observation sources; 0 or no source "
            "leaves it unbounded",
            period.value,
            period.source,
        )
    g = config.geometry
    footprint = Footprint(Fraction(repr(g.footprint_length_m)), Fraction(repr(g.footprint_width_m)))
    return Model(stopping, reaction, closing, footprint), resolve_limits(params, config, cli)


def _counterexample(cov: Coverage, outcome: Outcome) -> str:
    values = outcome.model
    shown = ", ".join(f"{k} = {v} ({float(v):.6g})" for k, v in values.items())
    needed: Fraction = separation_m(
        values["v_mps"],
        values["data_age_s"] + values["control_period_s"],
        values["accel_mps2"],
        values["decel_mps2"],
        values["closing_mps"],
    )
    # The exact reading of the same formula must agree that this is a counterexample.
    confirmed = "" if not cov.covers(needed) else " [NOT confirmed by the exact reading]"
    return f"counterexample {shown}: separation {_g(needed)} m beyond the zone{confirmed}"


Shape = tuple[tuple[Vertex, ...] | None, Fraction | None]


def _stop_finding(model: Model, zone: Zone, part: str, shape: Shape, use: Use) -> Finding:
    vertices, radius = shape
    cov = coverage(vertices, radius, model.footprint, use.travel)
    name = f"SR-NAV-1 {zone.name}{'/' + part if part else ''} {use.travel}"
    obligation = stop_obligation(model, cov, use, name)
    outcome = decide(obligation)
    base = Finding(
        zone.name,
        part,
        zone.action,
        use.travel,
        use.low_mps,
        use.high_mps,
        outcome.verdict,
        cov.short(),
        outcome.reason,
        obligation,
        outcome,
        needed_m(model, use.high_mps),
        why=use.why,
    )
    if outcome.verdict is not Verdict.REFUTED:
        return base
    safe, safe_outcome = safe_speed(model, cov, use.travel, name)
    standstill = model.worst_separation_m(Fraction(0))
    if safe is not None:
        where = f"largest safe speed {_g(safe)} m/s (proved)"
    elif standstill is None:
        where = "no safe speed: the data age is unbounded (a source_timeout of 0, or no source)"
    else:
        where = (
            "no safe speed: even from standstill, acceleration during the reaction time needs "
            f"{_g(standstill)} m"
        )
    detail = f"{_counterexample(cov, outcome)}; {where}"
    return replace(base, detail=detail, safe_mps=safe, safe_outcome=safe_outcome)


def _approach_finding(model: Model, zone: Zone, limits: RobotLimits) -> Finding:
    fp = model.footprint
    # The fastest the robot goes in any direction (forward or reverse, plus sideways when it
    # may translate sideways): Nav2 times the collision along the velocity, whichever it is.
    high = limits.top_speed_mps
    travel = "any" if limits.holonomic else "forward/reverse"
    before = zone.time_before_collision_s
    assert before is not None
    too_small = (zone.vertices is not None and not contains_footprint(zone.vertices, fp)) or (
        zone.radius_m is not None and zone.radius_m**2 < fp.half_diagonal_sq_m2
    )
    if too_small:
        shape = "circle" if zone.radius_m is not None else "polygon"
        return Finding(
            zone.name,
            "",
            zone.action,
            travel,
            Fraction(0),
            high,
            Verdict.REFUTED,
            f"footprint {shape}",
            f"the approach {shape} does not hold the robot's footprint: Nav2 would measure the "
            "time to collision from a smaller robot",
        )
    obligation = approach_obligation(model, before, high, f"SR-NAV-2 {zone.name} approach")
    outcome = decide(obligation)
    interval = approach_interval_mps(model, before)
    holds = (
        f"time_before_collision {_g(before)} s suffices for speeds in [{interval[0]:.4g}, "
        f"{interval[1]:.4g}] m/s"
        if interval is not None
        else f"time_before_collision {_g(before)} s suffices at no speed"
    )
    assumed = (
        f"; footprint from {zone.dynamic_topic}, taken to be the robot's"
        if zone.dynamic_topic
        else ""
    )
    detail = outcome.reason or holds + assumed
    if outcome.verdict is Verdict.REFUTED:
        shown = ", ".join(f"{k} = {v} ({float(v):.6g})" for k, v in outcome.model.items())
        detail = f"counterexample {shown}; {detail}"
    return Finding(
        zone.name,
        "",
        zone.action,
        travel,
        Fraction(0),
        high,
        outcome.verdict,
        f"keeps {_g(before)} s to collision",
        detail,
        obligation,
        outcome,
        needed_m(model, high),
    )


_NO_CLAIM = {
    "slowdown": "scales the commanded velocity by slowdown_ratio {ratio} while >= {n} readings "
    "are inside: it bounds no speed and stops nothing; nothing to prove",
    "limit": "caps the commanded linear speed at {limit} m/s while >= {n} readings are inside: "
    "it stops nothing, and an obstacle may appear inside a stop zone without crossing it first; "
    "nothing to prove",
    "none": "reports only (no action): nothing to prove",
}


def _zone_findings(model: Model, zone: Zone, limits: RobotLimits) -> list[Finding]:
    def note(text: str, verdict: Verdict | None = None, part: str = "") -> Finding:
        return Finding(zone.name, part, zone.action, "-", None, None, verdict, "", text)

    if not zone.enabled:
        return [note("disabled (enabled: false): not checked; check it again if it is switched on")]
    if zone.action in _NO_CLAIM:
        return [
            note(
                _NO_CLAIM[zone.action].format(
                    ratio=_g(zone.slowdown_ratio or 0),
                    limit=_g(zone.linear_limit_mps or 0),
                    n=zone.min_points,
                )
            )
        ]
    if zone.action == "approach":
        return [_approach_finding(model, zone, limits)]
    if zone.dynamic_topic is not None:
        return [
            note(
                f"shape set at run time from {zone.dynamic_topic}: cannot be checked",
                Verdict.UNKNOWN,
            )
        ]
    shapes: dict[str, Shape] = {s.name: (s.vertices, None) for s in zone.subpolygons} or {
        "": (zone.vertices, zone.radius_m)
    }
    findings = []
    for part, uses in zone_uses(zone, limits).items():
        if not uses:
            findings.append(note("never selected for the robot's velocities", part=part))
        findings += [_stop_finding(model, zone, part, shapes[part], use) for use in uses]
    return findings


def check(
    params: Nav2Params,
    config: SafecaseConfig,
    *,
    latency: str = "nav2",
    closing: ClosingClass = ClosingClass.STATIC,
    overrides: Overrides | None = None,
) -> Report:
    """Decide every zone of ``params`` with the stopping model of ``config``."""
    model, limits = build_model(
        params, config, latency=latency, closing=closing, overrides=overrides
    )
    findings = [f for zone in params.zones for f in _zone_findings(model, zone, limits)]
    if not any(f.verdict is not None for f in findings):
        findings.append(
            Finding(
                "(all zones)",
                "",
                "-",
                "-",
                None,
                None,
                Verdict.REFUTED,
                "",
                "no enabled stop or approach zone in use: nothing makes the robot stop",
            )
        )
    findings += [
        Finding(
            name,
            "",
            "-",
            "-",
            None,
            None,
            None,
            "",
            "defined but not listed in polygons: Nav2 ignores it",
        )
        for name in params.unlisted
    ]
    return Report(params, model, limits, tuple(findings))
