"""Nav2 collision monitor zones against the stopping model (SR-NAV-1 to SR-NAV-4).

Proofs: every obligation ``safecase nav2 check`` decides is decided again here by
:func:`properties.smt.prove` (the two verdicts must agree) and attached with its SMT-LIB text:
the Nav2 tutorial's stop box as a worked example (expected REFUTED, with its proved safe speed),
the approach model, and the export -> check round trip (every band PROVED). Properties: the
check agrees with a brute-force numerical evaluation of the same criterion (GEOS through shapely
for the zone's depth and clearance, a grid over speeds and parameter corners); every exported
band made shallower is refuted; a mutated parameter file is refused with one line or checked,
never a crash. Cross-check: a zone proved never lets the robot reach the obstacle in scipy's
integration of the braking motion, and a refuted zone's counterexample does.
"""

from __future__ import annotations

import itertools
import math
import re
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig, overridden
from properties.oracles.stopping import simulate_stop
from properties.smt import Obligation as SmtObligation
from properties.smt import ProofResult, prove
from safety.model.stopping import ClosingClass, separation_m
from safety.nav2 import Nav2Params, Nav2ParamsError, Verdict, check, load_params
from safety.nav2.export import export_yaml
from safety.nav2.geometry import Footprint, Vertex
from safety.nav2.obligations import (
    Model,
    approach_interval_mps,
    approach_obligation,
    coverage,
    stop_obligation,
)
from safety.nav2.params import parse_params
from safety.nav2.solver import Obligation, decide
from safety.nav2.usage import Use
from safety.nav2.verdicts import Finding, Report, build_model

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "nav2"
CHECK = [
    "safety/nav2/geometry.py",
    "safety/nav2/usage.py",
    "safety/nav2/obligations.py",
    "safety/nav2/verdicts.py",
    "safety/nav2/solver.py",
]
EXPORT = ["safety/nav2/export.py", "safety/nav2/verdicts.py"]
PARAMS = ["safety/nav2/params.py", "safety/nav2/reader.py"]


def _both(obligation: Obligation, *, required: bool) -> ProofResult:
    """Decide ``obligation`` with properties.smt too, attach it, and insist both agree."""
    runtime = decide(obligation)
    result = prove(
        SmtObligation(
            obligation.name,
            obligation.statement,
            obligation.hypotheses,
            obligation.goal,
            obligation.variables,
        )
    )
    result.attach(required=required)
    assert result.verdict.value == runtime.verdict.value, (obligation.name, result.reason)
    return result


def _row(f: Finding) -> list[str]:
    def g(x: Fraction | None) -> str:
        return "-" if x is None else f"{float(x):.6g}"

    verdict = "no claim" if f.verdict is None else f.verdict.value
    band = "-" if f.low_mps is None else f"{g(f.low_mps)} .. {g(f.high_mps)}"
    return [f.label, f.action, f.travel, band, g(f.needed_m), f.gives, verdict, g(f.safe_mps)]


def _table(evidence: Recorder, name: str, report: Report, caption: str) -> None:
    evidence.table(
        name,
        ["zone", "action", "travel", "speeds m/s", "needs m", "zone gives", "verdict", "safe m/s"],
        [_row(f) for f in report.findings],
        caption=caption,
    )


@pytest.fixture(scope="module")
def small(safecase_config: SafecaseConfig) -> SafecaseConfig:
    """The configuration under test with the tutorial robot's 0.3 m square footprint."""
    return overridden(
        safecase_config,
        {
            "geometry": {"footprint_length_m": 0.3, "footprint_width_m": 0.3},
            "sim": {"ego_length_m": 0.3, "ego_width_m": 0.3},
        },
    )


# -- proofs ----------------------------------------------------------------------------------


@pytest.mark.requirement("SR-NAV-1", kind="proof", code=CHECK)
@pytest.mark.parametrize("latency", ["project", "nav2"])
def test_worked_example_the_tutorial_stop_box(
    small: SafecaseConfig, evidence: Recorder, latency: str
) -> None:
    """docs/nav2.md's worked example: the tutorial's 0.4 m stop box on a 0.3 m robot."""
    report = check(load_params(EXAMPLES / "tutorial.yaml"), small, latency=latency)
    _table(
        evidence,
        f"Nav2 tutorial, latency {latency}",
        report,
        "examples/nav2/tutorial.yaml on a 0.3 m x 0.3 m robot: safecase nav2 check "
        f"examples/nav2/tutorial.yaml --config examples/nav2/small-robot.toml --latency {latency}",
    )
    for line in report.assumptions():
        evidence.note(line)
    stop = report.findings[0]
    assert stop.obligation is not None
    assert stop.outcome is not None
    # The finding: refuted (expected: a 0.25 m reach is less than the stop from 1 m/s needs).
    _both(stop.obligation, required=False)
    assert stop.needed_m is not None
    assert stop.verdict is (Verdict.REFUTED if stop.needed_m > Fraction("0.25") else Verdict.PROVED)
    if stop.verdict is Verdict.REFUTED:
        evidence.note(f"{stop.label}: {stop.detail}")
        if stop.safe_outcome is not None:
            # The safe speed the check reports is itself a proof.
            assert stop.safe_mps is not None
            use = Use("forward", Fraction(0), stop.safe_mps, "the largest safe speed")
            cov = coverage(report.params.zones[0].vertices, None, report.model.footprint, "forward")
            safe = _both(
                stop_obligation(report.model, cov, use, "tutorial safe speed"), required=True
            )
            assert safe.proved
            # ...and the largest to 1 mm/s: 1 mm/s more is refuted.
            faster = Use("forward", Fraction(0), stop.safe_mps + Fraction(1, 1000), "faster")
            above = _both(
                stop_obligation(report.model, cov, faster, "tutorial +1 mm/s"), required=False
            )
            assert not above.proved


@pytest.mark.requirement("SR-NAV-2", kind="proof", code=CHECK)
def test_approach_keeps_room_to_stop_exactly_where_v_tb_covers_the_separation(
    small: SafecaseConfig, evidence: Recorder
) -> None:
    text = (
        "collision_monitor:\n  ros__parameters:\n    source_timeout: 0.1\n"
        '    polygons: ["Approach"]\n    observation_sources: ["scan"]\n'
        '    Approach:\n      type: "polygon"\n      action_type: "approach"\n'
        '      footprint_topic: "/local_costmap/published_footprint"\n'
        "      time_before_collision: 2.0\n      simulation_time_step: 0.02\n"
    )
    report = check(parse_params(text), small)
    _table(evidence, "approach zone", report, "time_before_collision 2 s, the footprint by topic")
    (finding,) = report.findings
    assert finding.obligation is not None
    whole = _both(finding.obligation, required=False)
    interval = approach_interval_mps(report.model, Fraction(2))
    assert interval is not None
    low, high = interval
    evidence.note(f"time_before_collision 2 s suffices for speeds in [{low:.6g}, {high:.6g}] m/s")
    top = min(Fraction(math.floor(high * 1000) - 1, 1000), Fraction(1))
    inside = approach_obligation(
        report.model,
        Fraction(2),
        top,
        "approach inside its interval",
        low=Fraction(math.ceil(low * 1000) + 1, 1000),
    )
    assert _both(inside, required=True).proved
    # Below the interval's low end it fails: acceleration during the reaction time.
    s = report.model.stopping
    if s.accel_max_mps2 > 0 or report.model.closing_mps > 0:
        assert not whole.proved
        below = approach_obligation(
            report.model,
            Fraction(2),
            Fraction(math.floor(low * 1000) - 1, 1000) if low > 0.002 else Fraction(1, 1000),
            "approach below its interval",
        )
        assert not _both(below, required=False).proved


@pytest.mark.requirement("SR-NAV-3", kind="proof", code=EXPORT)
@pytest.mark.parametrize("closing", list(ClosingClass), ids=lambda c: c.value)
def test_export_then_check_proves_every_band(
    safecase_config: SafecaseConfig, evidence: Recorder, closing: ClosingClass
) -> None:
    text = export_yaml(safecase_config, closing)
    report = check(parse_params(text, "export"), safecase_config, closing=closing)
    _table(evidence, f"exported zones ({closing.value})", report, "safecase nav2 export | check")
    assert report.verdict is Verdict.PROVED
    for finding in report.findings:
        assert finding.obligation is not None
        assert _both(finding.obligation, required=True).proved


# -- properties ------------------------------------------------------------------------------


@pytest.mark.requirement("SR-NAV-3", kind="property", code=EXPORT)
@settings(max_examples=examples(10), deadline=None)
@given(band=st.integers(0, 9), shrink_mm=st.integers(1, 50))
def test_an_exported_band_made_shallower_is_refuted(
    safecase_config: SafecaseConfig, band: int, shrink_mm: int
) -> None:
    text = export_yaml(safecase_config)
    names = re.findall(r"^      (band_\d+):$", text, flags=re.MULTILINE)
    name = names[band % len(names)]
    block = text.index(f"      {name}:\n")
    line = text.index("points:", block)
    end = text.index("\n", line)
    front = re.search(r"\[\[([0-9.]+),", text[line:end])
    assert front is not None
    shorter = _decimal(Fraction(front.group(1)) - Fraction(shrink_mm, 1000))
    new_line = text[line:end].replace(front.group(1) + ",", shorter + ",")
    report = check(parse_params(text[:line] + new_line + text[end:]), safecase_config)
    verdicts = {f.part: f.verdict for f in report.findings}
    assert verdicts[name] is Verdict.REFUTED, (name, shrink_mm)
    assert all(v is Verdict.PROVED for part, v in verdicts.items() if part != name)
    current().count("exported band 1-50 mm shallower", "refuted")


def _decimal(value: Fraction) -> str:
    return f"{float(value):.10f}".rstrip("0")


FOOTPRINT = Footprint(Fraction("0.3"), Fraction("0.3"))


@st.composite
def star_polygons(draw: st.DrawFn) -> list[Vertex]:
    """Simple polygons around a centre near the robot: one vertex in each of n equal sectors."""
    n = draw(st.integers(4, 8))
    cx = draw(st.sampled_from([Fraction(k, 20) for k in range(-4, 9)]))
    radii = draw(st.lists(st.integers(6, 30), min_size=n, max_size=n))
    sector = 360 // n
    offsets = draw(st.lists(st.integers(0, sector - 1), min_size=n, max_size=n))
    return [
        (
            cx + Fraction(round(r * 50 * math.cos(math.radians(k * sector + o)))) / 1000,
            Fraction(round(r * 50 * math.sin(math.radians(k * sector + o)))) / 1000,
        )
        for k, (r, o) in enumerate(zip(radii, offsets, strict=True))
    ]


def _brute_depth(vertices: list[Vertex], travel: str) -> float:
    """GEOS: least stretch inside the zone ahead of the front, over a grid across the robot."""
    sign = 1.0 if travel == "forward" else -1.0
    zone = shapely.Polygon([(float(x), float(y)) for x, y in vertices])
    front, half = 0.15, 0.15
    # A grid across the robot, and both sides of every place the picture changes: a vertex's
    # offset, an edge crossing the robot's front.
    ys = set(np.linspace(-half + 1e-9, half - 1e-9, 101).tolist())
    corners = [(sign * float(x), float(y)) for x, y in vertices]
    for (x0, y0), (x1, y1) in zip(corners, corners[1:] + corners[:1], strict=True):
        changes = [y0]
        if x0 != x1 and min(x0, x1) <= front <= max(x0, x1):
            changes.append(y0 + (front - x0) * (y1 - y0) / (x1 - x0))
        ys |= {y + d for y in changes for d in (-1e-7, 1e-7) if abs(y + d) < half}
    least = math.inf
    for y in ys:
        line = shapely.LineString([(sign * front, y), (sign * (front + 100.0), y)])
        reach = 0.0
        for piece in shapely.get_parts(zone.intersection(line)):
            if piece.is_empty or piece.length == 0:
                continue
            xs = [sign * x for x, _ in piece.coords]
            if min(xs) <= front + 1e-9:
                reach = max(xs) - front
        least = min(least, reach)
    return least


def _brute_clearance(vertices: list[Vertex]) -> float:
    zone = shapely.Polygon([(float(x), float(y)) for x, y in vertices])
    robot = shapely.box(-0.15, -0.15, 0.15, 0.15)
    return float(zone.exterior.distance(robot)) if zone.contains(robot) else 0.0


def _brute_needed(model: Model, low: float, high: float) -> float:
    """Largest separation over a speed grid and every corner of the parameter ranges."""
    s, r = model.stopping, model.reaction
    assert r.worst_s is not None
    speeds = np.linspace(low, high, 201)
    corners = itertools.product(
        (0.0, float(r.worst_s)),
        (0.0, float(s.accel_max_mps2)),
        (float(s.decel_min_mps2), float(s.decel_max_mps2)),
        (0.0, float(model.closing_mps)),
    )
    return max(float(np.max(separation_m(speeds, t, a, b, c))) for t, a, b, c in corners)


@pytest.mark.requirement("SR-NAV-1", kind="property", code=CHECK)
@settings(max_examples=examples(30), deadline=None)
@given(
    vertices=star_polygons(),
    travel=st.sampled_from(["forward", "reverse", "any"]),
    low=st.integers(0, 60),
    width=st.integers(1, 60),
)
def test_the_check_agrees_with_a_brute_force_evaluation(
    small: SafecaseConfig, vertices: list[Vertex], travel: str, low: int, width: int
) -> None:
    assume(shapely.Polygon([(float(x), float(y)) for x, y in vertices]).is_valid)
    model, _ = build_model(_NO_FILE, small, latency="project")
    use = Use(travel, Fraction(low, 100), Fraction(low + width, 100), "a random band")
    cov = coverage(tuple(vertices), None, model.footprint, travel)
    verdict = decide(stop_obligation(model, cov, use, "random zone")).verdict
    gives = _brute_clearance(vertices) if travel == "any" else _brute_depth(vertices, travel)
    needs = _brute_needed(model, low / 100, (low + width) / 100)
    rec = current()
    # The exact geometry is the infimum the samples approach from above.
    assert cov.effective_m() <= gives + 1e-9
    assert gives - cov.effective_m() <= 1e-3, (gives, cov)
    if abs(gives - needs) < 2e-3:
        rec.count("brute force", "too close to call")
        return
    assert verdict is (Verdict.PROVED if needs <= gives else Verdict.REFUTED), (gives, needs)
    rec.count("brute force", f"agrees ({verdict.value})")


_NO_FILE = parse_params(
    'collision_monitor:\n  ros__parameters:\n    polygons: ["Z"]\n'
    '    observation_sources: ["scan"]\n    Z:\n      type: "circle"\n      radius: 1.0\n'
    '      action_type: "stop"\n'
)


@pytest.mark.requirement("SR-NAV-1", kind="cross-check", code=CHECK)
@settings(max_examples=examples(30), deadline=None)
@given(
    vertices=star_polygons(),
    travel=st.sampled_from(["forward", "reverse"]),
    top=st.integers(5, 120),
    u=st.tuples(*(st.floats(0.0, 1.0),) * 5),
)
def test_a_proved_zone_never_meets_the_obstacle_in_a_simulated_stop(
    small: SafecaseConfig, vertices: list[Vertex], travel: str, top: int, u: tuple[float, ...]
) -> None:
    model, _ = build_model(_NO_FILE, small, latency="project")
    use = Use(travel, Fraction(0), Fraction(top, 100), "a random band")
    cov = coverage(tuple(vertices), None, model.footprint, travel)
    outcome = decide(stop_obligation(model, cov, use, "random zone"))
    depth = cov.effective_m()
    s, worst = model.stopping, model.reaction.worst_s
    assert worst is not None
    rec = current()
    if outcome.verdict is Verdict.PROVED:
        # Any speed of the band, any parameters in range: scipy's integration of the stop.
        v = u[0] * top / 100
        t = u[1] * float(worst)
        a = u[2] * float(s.accel_max_mps2)
        b = float(s.decel_min_mps2) + u[3] * float(s.decel_max_mps2 - s.decel_min_mps2)
        c = u[4] * float(model.closing_mps)
        stop = simulate_stop(v, t, a, b, c)
        assert stop.separation_m <= depth + 1e-9, (stop, depth)
        rec.count("simulated stops", "proved zone: no contact")
        return
    assert outcome.verdict is Verdict.REFUTED
    m = outcome.model
    stop = simulate_stop(
        float(m["v_mps"]),
        float(m["data_age_s"] + m["control_period_s"]),
        float(m["accel_mps2"]),
        float(m["decel_mps2"]),
        float(m["closing_mps"]),
    )
    assert stop.separation_m > depth - 1e-9, (stop, depth, m)
    rec.count("simulated stops", "counterexample: contact")


def _read(text: str) -> tuple[Nav2Params | None, str]:
    """The parameters, or None and the one error line; any other exception propagates."""
    try:
        return parse_params(text, "mutant"), ""
    except Nav2ParamsError as exc:
        return None, str(exc)


_MUTANTS = st.sampled_from(
    ["", "0", "-1", "1e99", ".nan", "true", '"x"', "[]", "[1, 2]", "{}", '"[[0, 0]]"', "null"]
)


@pytest.mark.requirement("SR-NAV-4", kind="property", code=PARAMS)
@settings(max_examples=examples(100), deadline=None)
@given(data=st.data())
def test_a_mutated_file_is_refused_with_one_line_or_checked(
    small: SafecaseConfig, data: st.DataObject
) -> None:
    lines = (EXAMPLES / "tutorial.yaml").read_text().splitlines()
    index = data.draw(st.integers(0, len(lines) - 1))
    how = data.draw(st.sampled_from(["value", "drop", "repeat", "cut"]))
    line = lines[index]
    if how == "value" and ":" in line:
        key = line[: line.index(":") + 1]
        lines[index] = f"{key} {data.draw(_MUTANTS)}"
    elif how == "drop":
        del lines[index]
    elif how == "repeat":
        lines.insert(index, line)
    else:
        lines[index] = line[: data.draw(st.integers(0, len(line)))]
    rec = current()
    params, problem = _read("\n".join(lines) + "\n")
    if params is None:
        assert "\n" not in problem
        rec.count("mutated files", "refused with one line")
        return
    report = check(params, small, latency="project")
    assert report.exit_code in (0, 1, 3)
    rec.count("mutated files", "read and checked")
