"""Availability against the ground-truth oracle and the Nav2-style baseline (SR-AVL-1..4, -6).

One campaign (module fixture) runs every chosen scenario and seed three times in closed loop:
ours, the oracle (the same runtime fed the simulator's truth) and the baseline (a Nav2
collision_monitor on the raw points), with a shadow oracle deciding on our frames to name the
nuisance STOPs (:mod:`safety.availability`). Under ``ci`` it is small (two named scenarios,
seed 0, 10 s); under ``certify`` every named scenario with three seeds and six random
encounters, 15 s each (docs/findings/availability.md says why that many). The targets that are
not reached are strict xfails: reaching them fails the marker and flags the requirement.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import binomtest

from evidence.profiles import active_profile, by_profile, certifying, examples
from evidence.record import Recorder, current
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig, overridden
from pipeline.frames import to_parent
from pipeline.oracle import GroundTruthPerception
from pipeline.perception import Perception
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import Simulation
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.truth import CLASS_NAMES, object_labels
from pipeline.training.data import SIM_TO_MODEL_CLASS
from pipeline.types import FloatArray, PredictionMode, TrackStatus
from safety.availability import Campaign, Comparison, compare_all, run_ours
from safety.availability_plot import NUISANCE_TARGET, PROGRESS_TARGET, campaign_figure
from safety.baseline import Nav2Baseline, points_inside
from safety.bodies import SeenHulls, hull_bodies
from safety.model.freshness import is_fresh
from safety.obstacles import OBJECT_SPEED_WATCH, bodies_now
from safety.runtime import Levers

CODE = ["safety/availability.py", "pipeline/oracle.py", "safety/run.py"]
BASELINE = ["safety/baseline.py", "examples/nav2/baseline.yaml"]
# A share of 0.5 % is judged on at least this many cycles (one cycle is then 0.1 %).
MIN_CYCLES_FOR_SHARE = 1000
NAMED = (
    "reversing_forklift_aisle",
    "crossing_pedestrian",
    "pallet_jack_slow",
    "occlusion_behind_cart",
    "forklift_pass_by",
)


def _runs() -> list[tuple[str, int, float]]:
    if certifying():
        seeds, randoms = by_profile(ci=(0, 0), certify=(2, 4), full=(3, 6))
        return [
            *((n, seed, 15.0) for n in NAMED for seed in range(seeds)),
            *(("random_encounter", seed, 15.0) for seed in range(100, 100 + randoms)),
        ]
    # pallet_jack_slow for 15 s: the run the certify campaign holds below 90 % of the oracle.
    return [("reversing_forklift_aisle", 0, 10.0), ("pallet_jack_slow", 0, 15.0)]


@pytest.fixture(scope="module")
def classifier(safecase_config: SafecaseConfig) -> Classifier:
    """The configured model, loaded once for the module."""
    return Classifier.from_config(safecase_config.classify)


@pytest.fixture(scope="module")
def campaign(safecase_config: SafecaseConfig, classifier: Classifier) -> Campaign:
    """Ours, the oracle and the baseline on every run of :func:`_runs` (under ``certify`` on a
    LocalCluster of two worker processes: the same figures, in half the time)."""
    workers = 2 if certifying() else 1
    return compare_all(safecase_config, _runs(), workers=workers, classifier=classifier)


def _row(c: Comparison) -> list[object]:
    m = c.metrics()

    def contacts(role: str) -> str:
        return " ".join(f"{v:.2f}" for v in m[role].contact_speeds_mps) or "none"

    return [
        c.name,
        c.seed,
        " / ".join(f"{m[r].progress_m:.1f}" for r in ("ours", "oracle", "baseline")),
        f"{c.progress_share():.0%} / {c.progress_share('baseline'):.0%}",
        " / ".join(str(m[r].actions.get("STOP", 0)) for r in ("ours", "oracle", "baseline")),
        f"{c.nuisance_cycles} ({c.nuisance_share:.1%})",
        " / ".join(contacts(r) for r in ("ours", "oracle", "baseline")),
        " / ".join(f"{m[r].closest_m:.2f}" for r in ("ours", "oracle", "baseline")),
    ]


@pytest.mark.requirement("SR-AVL-1", kind="campaign", code=CODE)
@pytest.mark.requirement("SR-AVL-4", kind="campaign", code=BASELINE)
def test_ours_oracle_and_baseline_side_by_side(campaign: Campaign, evidence: Recorder) -> None:
    """The per-run table; the oracle is passively safe as ours is; the metrics are coherent."""
    runs = campaign.comparisons
    evidence.table(
        "ours / oracle / baseline, same scenario and seed (closed loop)",
        [
            "scenario",
            "seed",
            "progress [m]",
            "progress vs oracle (ours / baseline)",
            "STOP cycles",
            "nuisance STOP cycles",
            "robot speed at contact [m/s]",
            "closest [m]",
        ],
        [_row(c) for c in runs],
        caption=f"{len(runs)} runs ({active_profile()} profile). A nuisance STOP: we command STOP "
        "where the oracle, deciding on the same frame, commands PROCEED or SLOW.",
    )
    for role in ("ours", "oracle", "baseline"):
        total, moving = campaign.contacts(role)
        evidence.counts(f"contacts ({role})", {"all": total, "while moving": moving})
    evidence.counts("nuisance STOPs by cause", dict(campaign.nuisance_causes()))
    evidence.counts(
        "speed given up against the shadow oracle, by what set our command [m]",
        {k: round(v, 2) for k, v in campaign.speed_given_up_m().items()},
    )
    evidence.counts(
        "campaign",
        {
            "progress vs oracle (ours)": round(campaign.total_progress_share(), 4),
            "progress vs oracle (baseline)": round(campaign.total_progress_share("baseline"), 4),
            "worst run (ours)": round(campaign.worst_progress_share(), 4),
            "nuisance STOP share": round(campaign.nuisance_share(), 4),
        },
    )
    shares = [c.progress_share() for c in runs]
    if len(shares) > 1:
        # Half-width of the 95 % interval of the mean per-run share: how stable the figure is.
        half = 1.96 * float(np.std(shares, ddof=1)) / math.sqrt(len(shares))
        evidence.note(f"mean per-run progress share {np.mean(shares):.1%} +- {half:.1%} (95 %)")
    evidence.plot("availability campaign", campaign_figure(campaign))
    assert campaign.contacts("oracle")[1] == 0, "the oracle touched something while moving"
    assert campaign.contacts("ours")[1] == 0, "we touched something while moving"
    for c in runs:
        # A nuisance STOP is one of our STOPs, and the shadow decided on every one of our cycles.
        assert c.nuisance_cycles <= c.ours.actions.get("STOP", 0), (c.name, c.seed)
        # What we gave up counts only the cycles where the shadow was faster: at least the net.
        net = sum(row[4] - row[2] for row in c.shadow.rows) * c.period_s
        given = c.speed_given_up_m()
        assert sum(given.values()) >= net - 1e-9, (c.name, c.seed)
        assert set(given) <= {row[5] for row in c.shadow.rows}, (c.name, c.seed)
        assert len(c.shadow.rows) == c.ours.cycles


@pytest.mark.requirement("SR-AVL-2", kind="campaign", code=["safety/availability.py"])
@pytest.mark.xfail(
    reason="progress below 90 % of the oracle's (docs/findings/availability.md); strict: "
    "reaching it fails this marker, and SR-AVL-2 can then be claimed",
    strict=True,
)
def test_progress_reaches_ninety_percent_of_the_oracle(campaign: Campaign) -> None:
    low = {
        f"{c.name} seed {c.seed}": f"{c.progress_share():.0%}"
        for c in campaign.comparisons
        if c.progress_share() < PROGRESS_TARGET
    }
    assert not low, f"below {PROGRESS_TARGET:.0%} of the oracle's progress: {low}"


@pytest.mark.requirement("SR-AVL-3", kind="campaign", code=["safety/availability.py"])
@pytest.mark.xfail(
    reason="nuisance STOP time above 2 % of driving time (docs/findings/availability.md); "
    "strict: reaching it fails this marker, and SR-AVL-3 can then be claimed",
    strict=True,
)
def test_nuisance_stops_within_two_percent(campaign: Campaign) -> None:
    share = campaign.nuisance_share()
    assert share <= NUISANCE_TARGET, f"nuisance STOP time {share:.1%} of driving time"


@pytest.mark.requirement("SR-AVL-1", kind="example", code=["safety/runtime.py", *CODE])
@pytest.mark.requirement("SR-AVL-8", kind="campaign", code=["safety/bodies.py"])
def test_each_lever_measured_before_and_after(
    safecase_config: SafecaseConfig,
    classifier: Classifier,
    campaign: Campaign,
    evidence: Recorder,
) -> None:
    """Our run with each availability lever switched off (``ci``: all at once, on the first
    run; ``certify``: each, and all, on every seed-0 run), beside the campaign's (all on):
    the oracle and the baseline are the campaign's, only ours is rerun."""
    config = safecase_config
    reid = overridden(config, {"track": {"reid_enabled": True}})
    settings_ = {
        "all off": (
            Levers(directed_closing=False, outline_bodies=False, mapped_structure=False),
            config,
        ),
        "re-identification on": (Levers(), reid),
    }
    chosen = campaign.comparisons[:1]
    if certifying():
        named = by_profile(ci=NAMED, certify=NAMED[:3], full=NAMED)
        chosen = [c for c in campaign.comparisons if c.seed == 0 and c.name in named]
        settings_ = {
            "directed closing off": (Levers(directed_closing=False), config),
            "outline bodies off": (Levers(outline_bodies=False), config),
            "mapped structure off": (Levers(mapped_structure=False), config),
            **settings_,
        }
    durations = {(n, s): d for n, s, d in _runs()}
    rows: list[list[object]] = []
    for c in chosen:
        rows.append([c.name, c.seed, "all on", f"{c.progress_share():.0%}", c.nuisance_cycles])
        for label, (levers, cfg) in settings_.items():
            sim = make_simulation(cfg, c.name, c.seed, durations[(c.name, c.seed)])
            summary, shadow = run_ours(cfg, sim, classifier, levers)
            off = replace(c, ours=summary, shadow=shadow)
            assert off.metrics()["ours"].moving_contacts == 0, (c.name, label)
            rows.append([c.name, c.seed, label, f"{off.progress_share():.0%}", off.nuisance_cycles])
    evidence.table(
        "availability levers, before (off) and after (on)",
        ["scenario", "seed", "levers", "progress vs oracle", "nuisance STOP cycles"],
        rows,
        caption=f"{active_profile()} profile; the oracle and baseline runs are the campaign's.",
    )


@pytest.mark.requirement("SR-AVL-7", kind="campaign", code=["pipeline/track/tracker.py"])
def test_the_domain_speed_monitor_rarely_stops_the_robot_for_nothing(campaign: Campaign) -> None:
    """With re-identification off by default, the object-speed domain monitor sets at most
    0.5 % of our cycles as nuisance STOPs (a STOP where the oracle sees nothing that fast): the
    speed jumps left come from a new track confirmed on detections of different sizes (a
    cluster that split and merged while it was tentative). On fewer than
    ``MIN_CYCLES_FOR_SHARE`` cycles (the ci campaign) the count must only not refute that share
    (one-sided binomial test at 5 %)."""
    causes = dict(campaign.nuisance_causes())
    cycles = sum(c.ours.cycles for c in campaign.comparisons)
    count = causes.get(OBJECT_SPEED_WATCH, 0)
    if cycles < MIN_CYCLES_FOR_SHARE:
        # Too few cycles for a share of 0.5 % (one cycle is more): the count must only not
        # refute it, at the 5 % level (binomial, one-sided).
        p_value = float(binomtest(count, cycles, 0.005, alternative="greater").pvalue)
        current().note(
            f"{count} of {cycles} cycles set by the monitor: too few cycles to judge a 0.5 % "
            f"share, and they do not refute it (one-sided binomial p = {p_value:.2f})"
        )
        assert p_value >= 0.05, (count, cycles, causes)
        return
    share = count / cycles
    assert share <= 0.005, (f"{share:.2%} of {cycles} cycles", causes)


def _true_centre(sim: Simulation, i: int, t_s: float) -> FloatArray:
    """Centre of object ``i``'s box aligned with its heading at ``t_s`` (world frame) [m]."""
    at = np.array([t_s])
    heading = float(sim.world.objects[i].trajectory.at(at)["heading_rad"][0])
    lo, hi = sim.world.vertex_slices[i]
    verts = sim.world.object_vertices(at)[0][lo:hi]
    c, s = math.cos(heading), math.sin(heading)
    along, across = verts @ np.array([c, s]), verts @ np.array([-s, c])
    mid_a, mid_c = 0.5 * (along.min() + along.max()), 0.5 * (across.min() + across.max())
    return np.array([c * mid_a - s * mid_c, s * mid_a + c * mid_c])


@pytest.mark.requirement("SR-AVL-1", kind="example", code=["pipeline/oracle.py"])
def test_the_oracle_perceives_the_simulators_truth(safecase_config: SafecaseConfig) -> None:
    """Every object is a confirmed track at its true box centre, moving at that centre's true
    velocity (a central difference over 2 ms, one-sided at 0), with the simulator's class
    label; no point is left loose."""
    config = safecase_config
    sim = make_simulation(config, "forklift_pass_by", 0, 3.0)
    truth = GroundTruthPerception.for_simulation(config, sim)
    n_obj = len(sim.world.objects)
    checked = 0
    for frame in SimSource(sim).frames():
        assert frame.scan is not None
        seen = truth.perceive(frame)
        t = float(frame.scan.stamp_s)
        tracks, klass = seen.fused.tracks, seen.classification
        labels = object_labels(sim.world, t, sim.rules)
        assert tracks.n >= n_obj
        assert np.all(tracks.status == int(TrackStatus.CONFIRMED))
        assert seen.points.n == 0
        for i in range(n_obj):
            assert np.allclose(tracks.state[i, :2], _true_centre(sim, i, t), atol=1e-9)
            lo, hi = max(t - 1e-3, 0.0), t + 1e-3  # the world starts at 0
            velocity = (_true_centre(sim, i, hi) - _true_centre(sim, i, lo)) / (hi - lo)
            assert np.allclose(tracks.state[i, 2:], velocity, atol=1e-2), (i, t)
            name = klass.class_names[int(klass.class_index[i])]
            assert name == SIM_TO_MODEL_CLASS[CLASS_NAMES[int(labels[i])]]
            checked += 1
    assert checked >= n_obj * 20
    current().note(f"{checked} object-frames equal to the simulator's truth")


@pytest.mark.requirement("SR-AVL-4", kind="cross-check", code=BASELINE)
@settings(max_examples=examples(100), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_vertices=st.integers(3, 9),
    n_points=st.integers(1, 200),
)
def test_the_baselines_point_in_polygon_agrees_with_geos(
    seed: int, n_vertices: int, n_points: int
) -> None:
    """Nav2's even-odd test against shapely (GEOS) on random simple polygons (star-shaped about
    their centre, any orientation), points off the boundary."""
    rng = np.random.default_rng(seed)
    angles = np.sort(rng.uniform(0.0, 2.0 * math.pi, n_vertices))
    radii = rng.uniform(0.2, 2.0, n_vertices)
    verts = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)
    if rng.random() < 0.5:
        verts = verts[::-1]
    polygon = shapely.Polygon(verts)
    if not polygon.is_valid or polygon.area < 1e-3:
        return
    x, y = rng.uniform(-2.5, 2.5, (2, n_points))
    far = shapely.distance(polygon.exterior, shapely.points(x, y)) > 1e-9
    ours = points_inside(verts, x, y)
    geos = shapely.contains_xy(polygon, x, y)
    assert np.array_equal(ours[far], geos[far])
    current().count("points", "inside" if geos[far].any() else "all outside", int(far.sum()))


@pytest.mark.requirement("SR-AVL-4", kind="example", code=BASELINE)
def test_the_baseline_zones_act_as_nav2s(safecase_config: SafecaseConfig) -> None:
    """Tutorial zones: a wall 0.2 m ahead of the front stops the robot; 0.5 m ahead the
    slowdown zone (30 %) and the approach model (the command scaled by the start time of the
    first colliding step over 2 s) both act and the stricter wins; 1 m ahead the approach model
    alone; 3 m ahead it drives on."""
    base = Nav2Baseline.from_file(safecase_config)
    v = base.command_mps
    front = 0.5 * safecase_config.geometry.footprint_length_m
    wall_y = np.linspace(-0.2, 0.2, 9)

    def speed(ahead_m: float) -> float:
        return base.speed_mps(np.full(9, front + ahead_m), wall_y)[0]

    def approach(ahead_m: float) -> float:
        # The footprint's front reaches the wall in the first step k with v (k + 1) 0.1 >= ahead.
        k = math.ceil(ahead_m / (v * 0.1) - 1 - 1e-9)
        return v * k * 0.1 / 2.0

    assert speed(0.2) == 0.0
    assert speed(0.5) == pytest.approx(min(0.3 * v, approach(0.5)))  # the stricter zone wins
    assert speed(1.0) == pytest.approx(approach(1.0))
    assert speed(3.0) == v


@pytest.mark.requirement("SR-AVL-6", kind="property", code=["safety/bodies.py"])
def test_every_return_lies_in_its_outline_body(
    safecase_config: SafecaseConfig, classifier: Classifier
) -> None:
    """Rows of unknown motion seen this cycle (new clusters, unconfirmed tracks): every scan
    point of the cluster that updated the track lies in the body the governor reads."""
    config = safecase_config
    seconds = 12.0 if certifying() else 4.0
    chain = Perception.from_config(config, classifier=classifier, guard=is_fresh)
    checked = 0
    for name in ("occlusion_behind_cart", "reversing_forklift_aisle"):
        chain.reset()
        sim = make_simulation(config, name, 0, seconds)
        for frame in SimSource(sim).frames():
            seen = chain.perceive(frame)
            pred, tracks = seen.predictions, seen.fused.tracks
            clusters, points, pose = seen.clusters, seen.points, seen.pose
            unknown = pred.mode == int(PredictionMode.UNKNOWN)
            discs = bodies_now(pred, tracks, unknown, config.predict.disc_sides)
            seen_hulls = SeenHulls.of(unknown, pred, tracks, clusters, pose, config.predict)
            bodies = hull_bodies(unknown, discs, seen_hulls)
            rows = np.flatnonzero(unknown)
            for k, r in enumerate(rows):
                det = int(
                    tracks.detection_index[np.searchsorted(tracks.track_id, pred.track_id[r])]
                )
                if det < 0 or det >= clusters.n:
                    continue
                mine = clusters.point_labels == det
                px, py = to_parent(pose, points.x_m[mine], points.y_m[mine])
                n = int(bodies.counts[k])
                body = shapely.Polygon(bodies.vertices_m[:, :n, k].T)
                grown = body.buffer(float(bodies.slack_m[k]) + 1e-9)
                assert shapely.contains_xy(grown, px, py).all(), (name, int(pred.track_id[r]))
                checked += 1
    assert checked >= 10, f"only {checked} unknown rows seen: the check checks nothing"
    current().count("rows", "unknown rows seen, every return inside", checked)
