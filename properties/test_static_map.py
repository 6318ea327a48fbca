"""The site's static map (SR-AVL-8): what it covers, against GEOS (shapely), and that a cluster
judged to be the mapped structure holds no return of anything that moves."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import certifying, examples
from evidence.record import current
from pipeline.classify.model import Classifier
from pipeline.config import SafecaseConfig
from pipeline.errors import ConfigError
from pipeline.frames import to_parent
from pipeline.perception import Perception
from pipeline.sources.sim.lidar import STRUCTURE_ID
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from pipeline.static_map import StaticMap, clusters_on_map
from pipeline.types import PredictionMode
from safety.bodies import mapped_rows, tracks_on_map
from safety.model.freshness import is_fresh
from safety.run import site_map

CODE = ["pipeline/static_map.py", "safety/bodies.py"]


@st.composite
def _parts(draw: Any) -> list[np.ndarray]:
    """One to four rectangles, some of them thinner than a cell, at random angles."""
    parts = []
    for _ in range(draw(st.integers(1, 4))):
        cx, cy = draw(st.floats(-3.0, 3.0)), draw(st.floats(-3.0, 3.0))
        length, width = draw(st.floats(0.05, 3.0)), draw(st.floats(0.01, 1.0))
        a = draw(st.floats(0.0, math.pi))
        c, s = math.cos(a), math.sin(a)
        half = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * [0.5 * length, 0.5 * width]
        parts.append(half @ np.array([[c, s], [-s, c]]) + [cx, cy])
    return parts


@pytest.mark.requirement("SR-AVL-8", kind="cross-check", code=["pipeline/static_map.py"])
@settings(max_examples=examples(60), deadline=None)
@given(
    parts=_parts(),
    resolution=st.floats(0.02, 0.2),
    tolerance=st.floats(0.0, 0.25),
    seed=st.integers(0, 2**31 - 1),
)
def test_covered_points_lie_near_the_structure_and_the_structure_is_covered(
    parts: list[np.ndarray], resolution: float, tolerance: float, seed: int
) -> None:
    """Against GEOS: every covered point lies within ``reach_m`` (tolerance + sqrt(2) x
    resolution) of a part, and every point of a part (its vertices, points inside it, points
    on its edges) is covered."""
    smap = StaticMap.from_parts(parts, resolution, tolerance)
    union = shapely.unary_union([shapely.Polygon(p) for p in parts])
    rng = np.random.default_rng(seed)
    x_lo, y_lo, x_hi, y_hi = union.bounds
    pad = smap.reach_m() + 0.3
    x = rng.uniform(x_lo - pad, x_hi + pad, 4000)
    y = rng.uniform(y_lo - pad, y_hi + pad, 4000)
    hit = smap.covers(x, y)
    far = shapely.distance(union, shapely.points(x[hit], y[hit]))
    assert (far <= smap.reach_m() + 1e-9).all(), float(far.max(initial=0.0))
    inner = []
    for p in parts:
        w = rng.dirichlet(np.ones(4), 200)
        edge = p + rng.uniform(0.0, 1.0, (4, 1)) * (np.roll(p, -1, axis=0) - p)
        inner.extend([w @ p, p, edge])
    pts = np.concatenate(inner)
    assert smap.covers(pts[:, 0], pts[:, 1]).all()


@pytest.mark.requirement("SR-AVL-8", kind="property", code=["pipeline/static_map.py"])
def test_a_nav2_map_file_round_trips_and_bad_files_are_refused(tmp_path: Path) -> None:
    """``write_nav2`` then ``from_nav2`` gives the same grid, origin and resolution; a missing
    file, a missing key, a rotated origin and an unknown mode are refused, each naming it."""
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.2], [0.0, 0.2]])
    smap = StaticMap.from_parts([square, square + np.array([2.0, 1.0])], 0.05, 0.1)
    yaml_path = smap.write_nav2(tmp_path / "site.yaml")
    back = StaticMap.from_nav2(yaml_path, 0.1)
    assert np.array_equal(back.occupied, smap.occupied)
    assert np.array_equal(back.covered, smap.covered)
    assert (back.origin_x_m, back.origin_y_m) == (smap.origin_x_m, smap.origin_y_m)
    assert back.resolution_m == smap.resolution_m
    with pytest.raises(ConfigError, match="no such map file"):
        StaticMap.from_nav2(tmp_path / "none.yaml", 0.1)
    text = yaml_path.read_text()
    for bad, match in (
        (text.replace("resolution:", "res:"), "needs the keys"),
        (
            text.replace(", 0.0]", ", 0.5]"),
            r"yaw 0.5 is not supported; allowed: 0 \(as most of Nav2 assumes\)",
        ),
        (text.replace("trinary", "raw"), "mode 'raw'"),
        (text.replace("site.pgm", "gone.pgm"), "gone.pgm"),
    ):
        broken = tmp_path / "broken.yaml"
        broken.write_text(bad)
        with pytest.raises(ConfigError, match=match):
            StaticMap.from_nav2(broken, 0.1)


@pytest.mark.requirement("SR-AVL-8", kind="property", code=["pipeline/static_map.py"])
def test_a_cluster_is_on_the_map_only_when_every_return_is_covered() -> None:
    """One uncovered return takes a cluster off the map; noise is ignored; a cluster with no
    return is not on the map."""
    smap = StaticMap.from_parts(
        [np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 0.1], [0.0, 0.1]])], 0.05, 0.1
    )
    x = np.array([0.5, 1.0, 1.5, 0.5, 1.0, 1.0, 5.0])
    y = np.array([0.05, 0.05, 0.05, 0.05, 0.6, 0.05, 5.0])
    labels = np.array([0, 0, 0, 1, 1, 2, -1])
    assert clusters_on_map(smap, labels, x, y, 4).tolist() == [True, False, True, False]


@pytest.fixture(scope="module")
def classifier(safecase_config: SafecaseConfig) -> Classifier:
    """The configured model, loaded once for the module."""
    return Classifier.from_config(safecase_config.classify)


@pytest.mark.requirement("SR-AVL-8", kind="property", code=CODE)
def test_no_return_of_a_moving_object_is_taken_for_the_map(
    safecase_config: SafecaseConfig, classifier: Classifier
) -> None:
    """On simulated scans of the named scenarios (the simulator's per-beam truth beside them):
    every return of every cluster the runtime reads as mapped structure (the unknown rows it
    reads along the path, the tracks it does not hold to the speed domain) hit the structure,
    except mixed pixels (a beam grazing an object's edge returns a range between it and the
    structure behind, on the structure); an object with such a return has a return of its own
    that very cycle in a cluster not read as structure or among the loose points, so it is not
    lost."""
    config = safecase_config
    seconds = 15.0 if certifying() else 5.0
    names = (
        "crossing_pedestrian",
        "occlusion_behind_cart",
        "pallet_jack_slow",
        "forklift_pass_by",
        "reversing_forklift_aisle",
    )
    chain = Perception.from_config(config, classifier=classifier, guard=is_fresh)
    mapped_seen = returns = mixed_seen = unknown_rows = 0
    for name in names if certifying() else names[:2]:
        chain.reset()
        sim = make_simulation(config, name, 0, seconds)
        smap = site_map(config, sim)
        assert smap is not None
        beams: dict[float, Any] = {}
        step = sim.next_frame

        def recorded(step: Any = step, beams: dict[float, Any] = beams) -> Any:
            got = step()
            if got is not None:
                beams[got.scan.stamp_s] = got.truth.beams
            return got

        sim.next_frame = recorded  # type: ignore[method-assign]
        for frame in SimSource(sim).frames():
            seen = chain.perceive(frame)
            pred, tracks, clusters = seen.predictions, seen.fused.tracks, seen.clusters
            unknown = pred.mode == int(PredictionMode.UNKNOWN)
            on_map = tracks_on_map(tracks, clusters, seen.points, seen.pose, smap)
            rows = mapped_rows(unknown, pred, tracks, on_map)
            truth = beams[seen.points.stamp_s]
            owner = truth.owner_id[seen.points.beam_index]
            mixed = truth.mixed[seen.points.beam_index]
            labels = clusters.point_labels
            on = clusters_on_map(
                smap, labels, *to_parent(seen.pose, seen.points.x_m, seen.points.y_m), clusters.n
            )
            unknown_rows += int(np.count_nonzero(rows))
            for det in tracks.detection_index[on_map]:
                mine = labels == det
                moving = mine & (owner != STRUCTURE_ID)
                where = (name, seen.points.stamp_s)
                assert mixed[moving].all(), (*where, set(owner[moving & ~mixed].tolist()))
                for obj in set(owner[moving].tolist()):
                    # Its other returns: in a cluster off the map, or loose points (noise and
                    # clusters over the size filter), which the governor reads as they are.
                    lab = labels[owner == obj]
                    elsewhere = (lab < 0) | ~on[np.maximum(lab, 0)]
                    assert elsewhere.any(), (*where, obj, "lost to the map")
                mixed_seen += int(moving.sum())
                mapped_seen += 1
                returns += int(mine.sum())
    assert unknown_rows >= 20, f"only {unknown_rows} mapped rows: the check checks nothing"
    current().counts(
        "mapped structure",
        {
            "tracks updated by a cluster on the map": mapped_seen,
            "of which unknown rows read as structure": unknown_rows,
            "their returns": returns,
            "of which mixed pixels of a moving object": mixed_seen,
        },
    )
