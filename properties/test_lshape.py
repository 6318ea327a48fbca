"""L-shape fitting and track headings (SR-TRK-7): the fast fit against a brute-force scalar
evaluation of the same criterion, against the minimum-area box on fully visible boxes, and the
heading error on ray-cast apron scans by view and range."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import certifying, examples
from evidence.record import Recorder, current
from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.shape.box import cluster_shapes
from pipeline.shape.lshape import CRITERIA, angle_grid, lshape_fit
from pipeline.types import FloatArray, IntArray
from properties.ahead import ahead
from properties.airside_runs import airside_frames
from properties.heading_cases import RANGE_BINS_M, VIEWS, HeadingSamples, heading_samples
from properties.oracles.lshape import brute_force_lshape

CODE = ["pipeline/shape/lshape.py"]
CODE_TRACK = ["pipeline/shape/lshape.py", "pipeline/track/heading.py", "pipeline/track/tracker.py"]
MEDIAN_TARGET_DEG = 2.0  # published for the method (Zhang et al. 2017), median
SOURCE_TARGET_DEG = 5.0  # the source's target for two visible faces


def _segment(a: FloatArray, b: FloatArray, spacing_m: float) -> FloatArray:
    n = max(int(np.hypot(*(b - a)) / spacing_m), 1)
    t = np.arange(n) / n
    return a[None, :] + t[:, None] * (b - a)[None, :]


def _shape(kind: str, rng: np.random.Generator, noisy: bool = True) -> FloatArray:
    """Points of one cluster: an L, a single face, a full box outline or a blob (with range
    noise of 0, 5 or 20 mm when ``noisy``)."""
    length, width = float(rng.uniform(0.4, 4.0)), float(rng.uniform(0.3, 2.0))
    spacing = float(rng.uniform(0.015, 0.1))
    corner, right, up = np.zeros(2), np.array([length, 0.0]), np.array([0.0, width])
    if kind == "L":
        pts = np.concatenate([_segment(corner, right, spacing), _segment(corner, up, spacing)])
    elif kind == "I":
        pts = _segment(corner, right, spacing)
    elif kind == "box":
        far = right + up
        pts = np.concatenate(
            [
                _segment(a, b, spacing)
                for a, b in ((corner, right), (right, far), (far, up), (up, corner))
            ]
        )
    else:
        pts = rng.normal(0.0, [length / 3, width / 3], (int(rng.integers(5, 80)), 2))
    h = float(rng.uniform(-math.pi, math.pi))
    rot = np.array([[math.cos(h), -math.sin(h)], [math.sin(h), math.cos(h)]])
    noise = float(rng.choice([0.0, 0.005, 0.02])) if noisy else 0.0
    out: FloatArray = pts @ rot.T + rng.uniform(-20.0, 20.0, 2) + rng.normal(0.0, noise, pts.shape)
    return out


def _scan(shapes: list[FloatArray]) -> tuple[FloatArray, FloatArray, IntArray]:
    xy = np.concatenate(shapes)
    labels = np.repeat(np.arange(len(shapes)), [s.shape[0] for s in shapes])
    return xy[:, 0].copy(), xy[:, 1].copy(), labels.astype(np.int64)


@pytest.mark.requirement("SR-TRK-7", kind="cross-check", code=CODE)
@settings(max_examples=examples(40), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    kinds=st.lists(st.sampled_from(["L", "I", "box", "blob"]), min_size=1, max_size=3),
    criterion=st.sampled_from(CRITERIA),
    step=st.sampled_from([1.0, 2.0, 5.0]),
)
def test_fast_fit_equals_the_brute_force_criterion(
    seed: int, kinds: list[str], criterion: str, step: float
) -> None:
    """Every cluster's reported score is the point-by-point evaluation of the paper's criterion
    at its chosen angle (within 1e-9), and no angle of the grid scores higher. Where a cluster's
    two edges tie by norm within rounding (symmetric shapes), the paper's choice of edge is
    decided by rounding; each choice then counts as a legitimate evaluation."""
    rng = np.random.default_rng(seed)
    cfg = overridden(
        default_config(),
        {"cluster": {"lshape_criterion": criterion, "lshape_angle_step_deg": step}},
    ).cluster
    x, y, labels = _scan([_shape(k, rng) for k in kinds])
    fit = lshape_fit(x, y, labels, len(kinds), cfg)
    grid = angle_grid(step).tolist()
    for k in range(len(kinds)):
        mine = labels == k
        if np.count_nonzero(mine) < 2 * cfg.lshape_min_edge_inliers:
            assert not fit.accepted[k]
            assert np.isnan(fit.orientation_rad[k])
            current().count("clusters", "too small to search")
            continue
        values = brute_force_lshape(
            x[mine].tolist(), y[mine].tolist(), grid, criterion, cfg.lshape_closeness_floor_m
        )
        chosen = int(np.argmin(np.abs(np.asarray(grid) - fit.orientation_rad[k])))
        floor = max(min(v) for v in values)
        scale = max(abs(floor), 1e-12)
        # The fit's score is one legitimate evaluation at its angle, and no angle beats it.
        assert any(fit.score[k] == pytest.approx(v, rel=1e-9, abs=1e-12) for v in values[chosen]), (
            kinds[k],
            fit.score[k],
            values[chosen],
        )
        assert fit.score[k] >= floor - 1e-9 * scale, (kinds[k], chosen)
        best = max(range(len(grid)), key=lambda a: (max(values[a]), -a))
        tie = any(len(v) > 1 for v in values)
        current().count("clusters", "edge tie within rounding" if tie else "no tie")
        current().count("clusters", "same angle" if chosen == best else "another angle, same score")


@pytest.mark.requirement("SR-TRK-7", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    criterion=st.sampled_from(["closeness", "area"]),
    step=st.sampled_from([0.5, 1.0, 2.0]),
)
def test_on_fully_visible_boxes_the_fit_equals_the_minimum_area_box(
    seed: int, criterion: str, step: float
) -> None:
    """With all four faces seen (exact points), the fit's rectangle is the minimum-area box up to
    the grid: orientation within one step, sides within ``(length + width) sin(step)``."""
    rng = np.random.default_rng(seed)
    cfg = overridden(
        default_config(),
        {"cluster": {"lshape_criterion": criterion, "lshape_angle_step_deg": step}},
    ).cluster
    x, y, labels = _scan([_shape("box", rng, noisy=False)])
    if labels.shape[0] < 2 * cfg.lshape_min_edge_inliers:
        current().count("boxes", "too few points")
        return
    fit = lshape_fit(x, y, labels, 1, cfg)
    box = cluster_shapes(x, y, labels, 1)
    d = (fit.heading_rad[0] - box.heading_rad[0] + math.pi / 4) % (math.pi / 2) - math.pi / 4
    assert abs(d) <= math.radians(step) + 1e-9
    slack = (box.length_m[0] + box.width_m[0]) * math.sin(math.radians(step)) + 1e-9
    assert abs(fit.length_m[0] - box.length_m[0]) <= slack
    assert abs(fit.width_m[0] - box.width_m[0]) <= slack
    current().count("boxes", "accepted" if fit.accepted[0] else "compared, not accepted")


def _stats(values: np.ndarray) -> tuple[int, float, float]:
    v = values[~np.isnan(values)]
    if v.size == 0:
        return 0, math.nan, math.nan
    return int(v.size), float(np.median(v)), float(np.percentile(v, 95))


def _cell(values: np.ndarray) -> str:
    n, med, p95 = _stats(values)
    return "-" if n == 0 else f"{med:.2f} / {p95:.2f}"


@pytest.mark.requirement("SR-TRK-7", kind="campaign", code=CODE_TRACK)
@ahead
def test_heading_error_by_view_and_range_on_ray_cast_scans(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    """Ray-cast ``vehicle_headings`` runs (tugs, covered carts, platform carts, robots and
    containers parked at random headings at 3-25 m, others driving, turning and creeping): the
    box and the L-shape fit per cluster, by view and range; the track headings. Targets: the
    L-shape's median orientation error on two faces below the 2 deg published for the method,
    its 95th percentile below the source's 5 deg."""
    seeds = range(40) if certifying() else range(3)
    duration = 10.0 if certifying() else 6.0
    samples = HeadingSamples()
    for seed in seeds:
        heading_samples(
            safecase_config,
            airside_frames(safecase_config, "vehicle_headings", seed, duration),
            samples,
        )
    a = samples.arrays()
    rows = []
    for view in VIEWS:
        for b in range(len(RANGE_BINS_M) - 1):
            m = (a["view"] == view) & (a["range_bin"] == b)
            if not m.any():
                continue
            rows.append(
                [
                    view,
                    f"{RANGE_BINS_M[b]:.0f}-{RANGE_BINS_M[b + 1]:.0f}",
                    int(m.sum()),
                    f"{100 * a['accepted'][m].mean():.0f}",
                    _cell(a["box_orientation_deg"][m]),
                    _cell(a["lshape_orientation_deg"][m]),
                    _cell(a["box_axis_deg"][m]),
                    _cell(a["lshape_axis_deg"][m]),
                ]
            )
    evidence.table(
        "heading error by view and range (median / 95th percentile, deg)",
        [
            "view",
            "range m",
            "clusters",
            "L-shape accepted %",
            "box orientation (mod 90)",
            "L-shape orientation (mod 90)",
            "box axis (mod 180)",
            "L-shape axis (mod 180)",
        ],
        rows,
        caption=f"{len(seeds)} seeded vehicle_headings runs of {duration:.0f} s, 1080-beam "
        "scanner with the configured noise; containers (nearly square) are left out of the "
        "axis columns",
    )
    speed, resolved = a["track_speed_mps"], a["track_resolved"]
    track_rows = []
    for label, m in (
        ("moving (>= 0.3 m/s), flip resolved", (speed >= 0.3) & resolved),
        ("slow (< 0.3 m/s), flip resolved", (speed < 0.3) & resolved),
        ("slow (< 0.3 m/s), flip unresolved (error mod 180)", (speed < 0.3) & ~resolved),
        ("moving, flip unresolved (error mod 180)", (speed >= 0.3) & ~resolved),
    ):
        n, med, p95 = _stats(a["track_error_deg"][m])
        cone = a["cone_error_deg"][m]
        known = int(np.count_nonzero(~np.isnan(cone)))
        flipped = f"{100 * np.mean(a['track_error_deg'][m] > 90.0):.1f}" if n else "-"
        cone_flipped = f"{100 * np.mean(cone[~np.isnan(cone)] > 90.0):.1f}" if known else "-"
        track_rows.append(
            [
                label,
                n,
                "-" if n == 0 else f"{med:.2f} / {p95:.2f}",
                flipped,
                known,
                _cell(cone),
                cone_flipped,
            ]
        )
    slow = speed < 0.3
    evidence.table(
        "track heading against the prediction's heading (median / 95th percentile, deg)",
        [
            "tracks (confirmed, box-like vehicles)",
            "samples",
            "L-shape track heading",
            "flipped (> 90 deg) %",
            "prediction heading known",
            "prediction heading (history or velocity)",
            "flipped %",
        ],
        track_rows,
        caption="the prediction's heading (pipeline.predict.confirmed_heading_rad) orients a "
        "near-reversal vehicle's cones; unknown makes them discs",
    )
    two = a["view"] == "two faces"
    n_two, med_two, p95_two = _stats(a["lshape_orientation_deg"][two])
    _, box_med, _ = _stats(a["box_orientation_deg"][two])
    evidence.counts(
        "two visible faces",
        {
            "clusters": n_two,
            "L-shape median deg": round(med_two, 3),
            "L-shape p95 deg": round(p95_two, 3),
            "box median deg": round(box_med, 3),
        },
    )
    evidence.counts(
        "slow vehicles: heading known",
        {
            "L-shape track": int(np.count_nonzero(slow)),
            "prediction": int(np.count_nonzero(slow & ~np.isnan(a["cone_error_deg"]))),
        },
    )
    assert n_two >= 50, "too few two-face views to judge"
    assert med_two < MEDIAN_TARGET_DEG
    assert p95_two < SOURCE_TARGET_DEG
