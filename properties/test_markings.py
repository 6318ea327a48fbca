"""Retro-reflective markings from a multi-ring LiDAR's intensity (#25; SR-MRK-1..4).

The simulator and the detector are checked against each other only where the physics is
stated (the normalised intensity of a bare surface is the same at every range and incidence);
the line fits against scikit-learn's ``RANSACRegressor`` on the same points; the map's
distances against GEOS (shapely) and dense sampling; map matching against a pose error
injected on purpose. The localisation aid is shown to leave the runtime's decisions identical,
cycle for cycle, with it on and off.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.linear_model import LinearRegression, RANSACRegressor

from evidence.profiles import certifying, examples
from evidence.record import current
from pipeline.config import SafecaseConfig, overridden
from pipeline.errors import ConfigError
from pipeline.sensors.localisation import match_to_map
from pipeline.sensors.marking_fit import circle_lsq, ransac_circle, ransac_line
from pipeline.sensors.marking_map import MarkingMap, MarkingMapError
from pipeline.sensors.markings import RingScan, RingScanError, normalised
from pipeline.sources.sim.apron_markings import apron_markings
from pipeline.sources.sim.markings_source import MarkingsSource
from pipeline.sources.sim.markings_study import BANDS_M, detection_table, drive_errors
from pipeline.sources.sim.rings import GAIN, Cylinders, Surface
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from properties.ahead import ahead
from properties.markings_cases import (
    arc_points,
    bare_map,
    detected,
    line_points,
    small_markings,
    stripe_map,
)
from safety.run import run
from safety.runtime import Runtime

SENSE = ["pipeline/sensors/markings.py", "pipeline/sources/sim/rings.py"]
FIT = ["pipeline/sensors/marking_fit.py", "pipeline/sensors/markings.py"]
MATCH = ["pipeline/sensors/localisation.py", "pipeline/sensors/marking_map.py"]

road_pose = st.tuples(st.floats(0.0, 90.0), st.floats(-2.0, 2.0), st.floats(-0.3, 0.3))


@pytest.mark.requirement("SR-MRK-1", kind="property", code=SENSE)
@settings(max_examples=examples(40), deadline=None)
@given(
    intensity=st.floats(0.0, 1e4),
    range_m=st.floats(0.1, 200.0),
    ref_m=st.floats(1.0, 100.0),
)
def test_normalised_intensity_is_the_stated_formula(
    intensity: float, range_m: float, ref_m: float
) -> None:
    got = normalised(np.array([intensity]), np.array([range_m]), ref_m)[0]
    assert got == pytest.approx(intensity * (range_m / ref_m) ** 2, rel=1e-12, abs=1e-300)


@pytest.mark.requirement("SR-MRK-1", kind="property", code=SENSE)
@settings(max_examples=examples(10), deadline=None)
@given(pose=road_pose, seed=st.integers(0, 2**32 - 1), mount_z=st.floats(0.8, 2.5))
def test_a_bare_surface_normalises_to_one_level_at_every_range(
    safecase_config: SafecaseConfig, pose: tuple[float, float, float], seed: int, mount_z: float
) -> None:
    # Noise-free scanner and uniform asphalt: after range and incidence normalisation every
    # ground return reads GAIN x reflectivity, near or far, steep or grazing.
    cfg = small_markings(safecase_config, 180).model_copy(
        update={"range_std_m": 0.0, "intensity_std": 0.0, "mount_z_m": mount_z}
    )
    surface = Surface(asphalt_spread=0.0)
    scan, _, found = detected(cfg, pose, bare_map(), surface, seed)
    level = found.i_norm[found.is_ground]
    assert level.size > 100
    np.testing.assert_allclose(level, GAIN * surface.asphalt, rtol=1e-6)
    raw = scan.intensity[found.is_ground]
    current().samples("raw ground intensity, max / min of a scan", [raw.max() / raw.min()], "x")


@pytest.mark.requirement("SR-MRK-1", kind="property", code=SENSE)
@settings(max_examples=examples(12), deadline=None)
@given(pose=road_pose, seed=st.integers(0, 2**32 - 1))
def test_no_marking_is_detected_on_bare_asphalt(
    safecase_config: SafecaseConfig, pose: tuple[float, float, float], seed: int
) -> None:
    cfg = small_markings(safecase_config)
    _, _, found = detected(cfg, pose, bare_map(), Surface(), seed)
    n_ground = int(found.is_ground.sum())
    # At 2x the median, a single return over the threshold is a 4.5-sigma event of the
    # asphalt's texture and the intensity noise; no line or arc may come of it.
    assert found.lines == ()
    assert found.arcs == ()
    assert int(found.is_marking.sum()) <= 3
    current().count("bare-asphalt scans", "returns over the threshold", int(found.is_marking.sum()))
    current().count("bare-asphalt scans", "ground returns", n_ground)


@pytest.mark.requirement("SR-MRK-1", kind="property", code=SENSE)
@settings(max_examples=examples(10), deadline=None)
@given(pose=road_pose, seed=st.integers(0, 2**32 - 1))
def test_dry_paint_returns_are_detected_and_vests_are_not_ground(
    safecase_config: SafecaseConfig, pose: tuple[float, float, float], seed: int
) -> None:
    cfg = small_markings(safecase_config)
    # A person in a retro-reflective vest 4 m ahead: bright, but above the ground.
    ahead = (pose[0] + 4.0 * math.cos(pose[2]), pose[1] + 4.0 * math.sin(pose[2]))
    vest = Cylinders(
        np.array([ahead[0]]),
        np.array([ahead[1]]),
        np.array([0.25]),
        np.array([1.8]),
        np.array([0.8]),
    )
    scan, truth, found = detected(cfg, pose, apron_markings(), Surface(), seed, cylinders=vest)
    on_vest = truth.on_ground == 0.0
    assert on_vest.any()
    assert not found.is_marking[on_vest & (scan.z_m > 2 * cfg.ground_tolerance_m)].any()
    horiz = np.hypot(scan.x_m, scan.y_m)
    paint = (truth.paint_fraction >= 0.5) & (horiz <= 15.0) & (truth.on_ground == 1.0)
    recall = float((found.is_marking & paint).sum() / max(int(paint.sum()), 1))
    assert paint.sum() > 20
    assert recall >= 0.9
    current().count("dry paint within 15 m", "returns", int(paint.sum()))
    current().count(
        "dry paint within 15 m", "kept as marking", int((found.is_marking & paint).sum())
    )


@pytest.mark.requirement("SR-MRK-2", kind="cross-check", code=["pipeline/sensors/marking_fit.py"])
@settings(max_examples=examples(40), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    angle=st.floats(-math.pi / 4, math.pi / 4),
    offset=st.floats(-5.0, 5.0),
    n_out=st.integers(0, 40),
)
def test_line_fit_agrees_with_scikit_learn_ransac(
    safecase_config: SafecaseConfig, seed: int, angle: float, offset: float, n_out: int
) -> None:
    tol = safecase_config.markings.line_inlier_m
    rng = np.random.default_rng(seed)
    x, y, on_line = line_points(rng, 60, n_out, angle, offset, 0.02)
    ours = ransac_line(x, y, tol, 200, np.random.default_rng(seed + 1))
    assert ours is not None
    (px, py, ux, uy), inliers = ours
    # scikit-learn regresses y on x (|slope| <= 1 here), with a vertical residual threshold.
    ref = RANSACRegressor(
        LinearRegression(), residual_threshold=tol, random_state=seed % 2**31, max_trials=200
    ).fit(x[:, None], y)
    slope, intercept = float(ref.estimator_.coef_[0]), float(ref.estimator_.intercept_)
    ref_angle = math.atan(slope)
    our_angle = math.atan2(uy, ux)
    d_angle = abs((our_angle - ref_angle + math.pi / 2) % math.pi - math.pi / 2)
    assert d_angle < math.radians(1.0)
    # Both lines at the middle of the true points, measured across the line.
    mx = float(x[on_line].mean())
    our_y = py + (mx - px) * uy / ux
    assert abs(our_y - (slope * mx + intercept)) * math.cos(ref_angle) < 0.02
    both = inliers & ref.inlier_mask_
    jaccard = both.sum() / (inliers | ref.inlier_mask_).sum()
    assert jaccard >= 0.85
    # And both against the truth: every true point within the tolerance is ours.
    assert inliers[on_line].mean() >= 0.99
    current().count("inlier sets (Jaccard)", ">= 0.99" if jaccard >= 0.99 else "0.85-0.99")


@pytest.mark.requirement("SR-MRK-2", kind="property", code=["pipeline/sensors/marking_fit.py"])
@settings(max_examples=examples(40), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    centre=st.tuples(st.floats(-20, 20), st.floats(-20, 20)),
    radius=st.floats(3.0, 30.0),
    start=st.floats(-math.pi, math.pi),
    sweep=st.floats(0.8, 2.0),
)
def test_arc_fit_recovers_the_circle(
    safecase_config: SafecaseConfig,
    seed: int,
    centre: tuple[float, float],
    radius: float,
    start: float,
    sweep: float,
) -> None:
    rng = np.random.default_rng(seed)
    exact = circle_lsq(*arc_points(rng, 12, centre, radius, start, sweep, 0.0))
    assert exact is not None
    assert exact == pytest.approx((*centre, radius), abs=1e-6 * max(radius, 1.0))
    x, y = arc_points(rng, 80, centre, radius, start, sweep, 0.02)
    ox, oy = rng.uniform(-40, 40, 20), rng.uniform(-40, 40, 20)
    found = ransac_circle(
        np.concatenate([x, ox]), np.concatenate([y, oy]), 0.1, (2.0, 40.0), 200, rng
    )
    assert found is not None
    (cx, cy, r), inliers = found
    # A 0.02 m radial noise over a chord c bounds the radius to about noise * (r / sagitta).
    sagitta = radius * (1 - math.cos(sweep / 2))
    bound = 0.02 * 6 * radius / sagitta + 0.02
    assert abs(r - radius) <= bound
    assert math.hypot(cx - centre[0], cy - centre[1]) <= 2 * bound
    assert inliers[:80].mean() >= 0.95


@pytest.mark.requirement("SR-MRK-2", kind="property", code=FIT)
@settings(max_examples=examples(10), deadline=None)
@given(
    pose=st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-math.pi, math.pi)),
    offset=st.floats(3.0, 8.0) | st.floats(-8.0, -3.0),
    angle=st.floats(-math.pi / 2, math.pi / 2),
    seed=st.integers(0, 2**32 - 1),
)
def test_a_stripe_is_recovered_as_a_line_for_any_pose(
    safecase_config: SafecaseConfig,
    pose: tuple[float, float, float],
    offset: float,
    angle: float,
    seed: int,
) -> None:
    cfg = small_markings(safecase_config)
    stripe = stripe_map(pose, offset, angle)
    _, _, found = detected(cfg, pose, stripe, Surface(), seed)
    assert found.lines, "no line fitted to a dry stripe 3-8 m away"
    best = max(found.lines, key=lambda ln: ln.n_inliers)
    from pipeline.frames import to_parent

    ends = to_parent(pose, np.array([best.x0_m, best.x1_m]), np.array([best.y0_m, best.y1_m]))
    # Both ends on the paint (within its width of the centre line: a far end is placed from a
    # return whose footprint is long), so direction and offset are right; and the line is long
    # enough to carry direction.
    assert stripe.distance_m(*ends).max() <= stripe.width_m
    assert best.length_m >= cfg.min_line_length_m
    seg = stripe.segments[0]
    true_dir = math.atan2(seg[3] - seg[1], seg[2] - seg[0])
    fit_dir = math.atan2(ends[1][1] - ends[1][0], ends[0][1] - ends[0][0])
    err = abs((fit_dir - true_dir + math.pi / 2) % math.pi - math.pi / 2)
    assert err <= math.radians(3.0)
    current().count(
        "fitted stripe direction error", "<= 1 deg" if err <= math.radians(1) else "1-3 deg"
    )


@pytest.mark.requirement("SR-MRK-3", kind="cross-check", code=["pipeline/sensors/marking_map.py"])
@settings(max_examples=examples(10), deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_map_distances_agree_with_geos_and_dense_arcs(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mm = apron_markings()
    x, y = rng.uniform(-30, 110, 400), rng.uniform(-10, 45, 400)
    near = mm.nearest(x, y)
    np.testing.assert_allclose(mm.distance_m(x, y), near.distance_m, atol=1e-12)
    segs = shapely.linestrings(mm.segments.reshape(-1, 2, 2))
    d_seg = shapely.distance(segs[None, :], shapely.points(x, y)[:, None]).min(axis=1)
    a = np.linspace(0.0, 1.0, 5001)
    arc_d = np.full(x.shape, np.inf)
    for cx, cy, r, a0, sw in mm.arcs:
        ax, ay = cx + r * np.cos(a0 + sw * a), cy + r * np.sin(a0 + sw * a)
        arc_d = np.minimum(arc_d, np.hypot(x[:, None] - ax, y[:, None] - ay).min(axis=1))
    # Dense sampling is off by at most half a sample's chord (sagitta-free bound).
    chord = float((mm.arcs[:, 2] * np.abs(mm.arcs[:, 4])).max() / 5000)
    ref = np.minimum(d_seg, arc_d)
    assert (near.distance_m <= ref + 1e-9).all()
    assert (near.distance_m >= ref - chord).all()
    # The nearest point is at that distance, and the normal is a unit vector.
    np.testing.assert_allclose(np.hypot(x - near.x_m, y - near.y_m), near.distance_m, atol=1e-9)
    np.testing.assert_allclose(np.hypot(near.nx, near.ny), 1.0, atol=1e-9)


@pytest.mark.requirement("SR-MRK-3", kind="property", code=MATCH)
@settings(max_examples=examples(12), deadline=None)
@given(
    pose=road_pose,
    error=st.tuples(st.floats(-0.3, 0.3), st.floats(-0.3, 0.3), st.floats(-0.03, 0.03)),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_correction_reduces_an_injected_pose_error(
    safecase_config: SafecaseConfig,
    pose: tuple[float, float, float],
    error: tuple[float, float, float],
    seed: int,
) -> None:
    cfg = small_markings(safecase_config)
    mm = apron_markings()
    _, _, found = detected(cfg, pose, mm, Surface(), seed)
    guess = (pose[0] + error[0], pose[1] + error[1], pose[2] + error[2])
    fix = match_to_map(*found.feature_points(), guess, mm, cfg)
    assert fix.accepted, fix.reason
    ex, ey = guess[0] + fix.dx_m - pose[0], guess[1] + fix.dy_m - pose[1]
    before, after = math.hypot(error[0], error[1]), math.hypot(ex, ey)
    yaw_after = abs(guess[2] + fix.dyaw_rad - pose[2])
    # Across the road (its edge lines run along x) and in yaw the markings always constrain
    # the pose: the error is at least halved. Along the road only stop lines, dash ends and the
    # stands do, weakly in places (a single scan's along-road noise exceeds 0.1 m): there
    # the error may not exceed the injected one (by more than 1 cm) or 0.2 m, and what is left
    # is counted.
    assert abs(ey) <= max(0.5 * abs(error[1]), 0.05)
    assert yaw_after <= max(0.5 * abs(error[2]), 0.005)
    assert abs(ex) <= max(abs(error[0]) + 0.01, 0.2)
    assert after <= max(before + 0.01, 0.2)
    left = "<= 5 cm" if abs(ex) <= 0.05 else "5-10 cm" if abs(ex) <= 0.1 else "10-20 cm"
    current().count("along-road error after the correction", left)


@pytest.mark.requirement("SR-MRK-3", kind="property", code=MATCH)
@settings(max_examples=examples(10), deadline=None)
@given(
    along=st.floats(-0.5, 0.5),
    across=st.floats(-0.3, 0.3),
    seed=st.integers(0, 2**32 - 1),
)
def test_along_a_single_stripe_nothing_is_guessed(
    safecase_config: SafecaseConfig, along: float, across: float, seed: int
) -> None:
    cfg = small_markings(safecase_config)
    pose = (0.0, 0.0, 0.0)
    stripe = stripe_map(pose, 3.0, 0.0, length_m=200.0)  # along x, 3 m to the left
    _, _, found = detected(cfg, pose, stripe, Surface(), seed)
    fix = match_to_map(*found.feature_points(), (along, across, 0.0), stripe, cfg)
    assert fix.accepted, fix.reason
    assert fix.n_observable == 2
    assert abs(fix.dx_m) <= 1e-6  # along the stripe: unobservable, left alone
    assert abs(across + fix.dy_m) <= 0.05


@pytest.mark.requirement("SR-MRK-3", kind="property", code=MATCH)
@settings(max_examples=examples(6), deadline=None)
@given(pose=road_pose, seed=st.integers(0, 2**32 - 1))
def test_paint_that_lost_80_percent_gives_no_correction(
    safecase_config: SafecaseConfig, pose: tuple[float, float, float], seed: int
) -> None:
    # The source's worst wet paint is indistinguishable from asphalt at 2x the median: the aid
    # goes quiet (the estimate keeps dead reckoning) instead of correcting from noise.
    cfg = small_markings(safecase_config)
    mm = apron_markings()
    _, _, found = detected(cfg, pose, mm, Surface(paint_loss=0.8), seed)
    fix = match_to_map(*found.feature_points(), pose, mm, cfg)
    assert not fix.accepted
    assert (fix.dx_m, fix.dy_m, fix.dyaw_rad) == (0.0, 0.0, 0.0)


@pytest.mark.requirement("SR-MRK-1", kind="measurement", code=SENSE)
def test_without_the_incidence_cosine_asphalt_is_taken_for_paint(
    safecase_config: SafecaseConfig,
) -> None:
    # The stated normalisation (range only) leaves asphalt near the robot several times brighter
    # than far asphalt, so twice the median is no longer a paint threshold: measured on bare
    # asphalt, five seeds, with and without the incidence cosine.
    rows = []
    for correct in (True, False):
        cfg = small_markings(safecase_config).model_copy(update={"incidence_correction": correct})
        kept = features = ground = 0
        for seed in range(5):
            _, _, found = detected(cfg, (20.0, -1.2, 0.0), bare_map(), Surface(), seed)
            kept += int(found.is_marking.sum())
            features += len(found.lines) + len(found.arcs)
            ground += int(found.is_ground.sum())
        rows.append([str(correct), ground // 5, kept / 5, features / 5])
        if correct:
            assert features == 0
        else:
            assert kept / 5 > 100
            assert features > 0
    current().table(
        "bare asphalt, per scan",
        ["incidence cosine", "ground returns", "returns over 2x median", "lines and arcs"],
        rows,
        "range normalisation alone against range and incidence (docs/findings/markings.md)",
    )


@pytest.mark.requirement("SR-MRK-1", kind="measurement", code=SENSE)
def test_detection_by_range_band_dry_and_wet(safecase_config: SafecaseConfig) -> None:
    cfg = small_markings(safecase_config)
    n_scans = 40 if certifying() else 4
    rows = []
    for loss in (0.0, 0.5, 0.8):
        tab = detection_table(cfg, loss, n_scans, 0)
        for b in range(len(BANDS_M) - 1):
            rows.append(
                [
                    f"{loss:.0%}",
                    f"{BANDS_M[b]:.0f}-{BANDS_M[b + 1]:.0f}",
                    f"{tab.return_recall[b]:.3f}",
                    f"{tab.return_false_rate[b]:.1e}",
                    f"{tab.feature_recall[b]:.2f}",
                    f"{tab.false_cells_per_scan[b]:.2f}",
                ]
            )
        if loss == 0.0:
            # Dry paint within 15 m: every band keeps at least 90 % of its paint returns.
            assert (tab.return_recall[:3] >= 0.9).all()
        if loss == 0.8:
            assert (tab.feature_recall == 0.0).all()
    current().table(
        "detection by range band",
        ["paint loss", "band [m]", "paint kept", "asphalt kept", "marking recall", "false cells"],
        rows,
        f"{n_scans} poses along the service road, 720 columns (docs/findings/markings.md)",
    )


@pytest.mark.requirement("SR-MRK-3", kind="measurement", code=MATCH)
@ahead
def test_the_correction_bounds_the_drift_along_a_drive(safecase_config: SafecaseConfig) -> None:
    cfg = small_markings(safecase_config)
    certify = certifying()
    distance = 90.0 if certify else 9.0
    rows = []
    for loss in (0.0, 0.5) if certify else (0.0,):
        d = drive_errors(cfg, loss, 0, distance_m=distance)
        rows.append(
            [
                f"{loss:.0%}",
                f"{d.accepted:.2f}",
                f"{d.odometry_m[-1]:.3f}",
                f"{d.corrected_m.max():.3f}",
            ]
        )
        assert d.accepted >= 0.9
        assert d.corrected_m[-1] < d.odometry_m[-1]
        assert d.corrected_m.max() <= 0.25
    current().table(
        "localisation error along the drive",
        ["paint loss", "accepted", "odometry-only error at the end [m]", "corrected max [m]"],
        rows,
        f"{distance:.0f} m along the service road, odometry drifting 2 % and 0.002 rad/s",
    )


def test_bad_inputs_are_refused(safecase_config: SafecaseConfig) -> None:
    one = np.ones(1)
    with pytest.raises(RingScanError, match="finite"):
        RingScan(0.0, one * np.nan, one, one, one, one, np.zeros(1, int), (0.0, 0.0, 1.0))
    with pytest.raises(RingScanError, match="shape"):
        RingScan(0.0, np.ones(2), one, one, one, one, np.zeros(1, int), (0.0, 0.0, 1.0))
    with pytest.raises(MarkingMapError, match="zero length"):
        MarkingMap(np.array([[1.0, 1.0, 1.0, 1.0]]), np.zeros((0, 5)))
    with pytest.raises(ConfigError, match="arc_min_radius_m"):
        overridden(safecase_config, {"markings": {"arc_min_radius_m": 50.0}})
    with pytest.raises(ConfigError, match=r"markings\.threshold_factor"):
        overridden(safecase_config, {"markings": {"threshold_factor": 0.5}})


@pytest.mark.requirement(
    "SR-MRK-4", kind="example", code=["pipeline/sources/sim/markings_source.py"]
)
def test_decisions_are_identical_with_the_markings_aid_on_and_off(
    safecase_config: SafecaseConfig,
) -> None:
    config = safecase_config
    cfg = small_markings(config)

    def cycles(with_markings: bool) -> tuple[list[dict[str, object]], MarkingsSource | None]:
        sim = make_simulation(config, "crossing_pedestrian", 0, 3.0)
        plain = SimSource(sim)
        source: SimSource | MarkingsSource = plain
        aid = None
        if with_markings:
            aid = MarkingsSource(plain, cfg, apron_markings(), np.random.default_rng(7))
            source = aid
        rows = []
        for out in run(config, source, Runtime(config)):
            body = out.record.body()
            body.pop("timings_s")
            rows.append(body | {"action": out.command.action.name, "speed": out.command.speed_mps})
        return rows, aid

    off, _ = cycles(False)
    on, aid = cycles(True)
    assert aid is not None
    accepted = sum(r.correction.accepted for r in aid.reports)
    # The aid really ran: it localised on most scans of the run.
    assert len(aid.reports) == len(on)
    assert accepted >= len(on) // 2
    assert len(on) == len(off) > 20
    for k, (a, b) in enumerate(zip(off, on, strict=True)):
        assert a == b, f"cycle {k}: the decision changed with the markings aid on"
    current().count("cycles", "identical decisions", len(on))
    current().count("cycles", "corrections accepted", accepted)
    current().note(aid.summary())
