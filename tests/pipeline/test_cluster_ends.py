"""Examples for the clusters' ends and their occlusion flags (SR-CLS-2)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.cluster.dbscan import cluster_scan
from pipeline.config import default_config
from pipeline.shape.ends import OCCLUSION_MARGIN_M
from pipeline.types import Clusters, Scan

N_BEAMS = 1080
ANGLES = np.linspace(-math.pi, math.pi, N_BEAMS, endpoint=False)


def _clusters(returns: dict[int, float]) -> Clusters:
    """Clusters of a scan whose beams ``index: range_m`` returned; every other beam is NaN."""
    ranges = np.full(N_BEAMS, np.nan)
    for index, range_m in returns.items():
        ranges[index % N_BEAMS] = range_m
    _, clusters = cluster_scan(Scan(0.0, ANGLES, ranges), default_config())
    return clusters


def _arc(first: int, last: int, range_m: float = 5.0) -> dict[int, float]:
    return dict.fromkeys(range(first, last + 1), range_m)


def _point(beam: int, range_m: float = 5.0) -> tuple[float, float]:
    a = ANGLES[beam % N_BEAMS]
    return range_m * math.cos(a), range_m * math.sin(a)


def test_an_end_next_to_a_nearer_return_is_occluded() -> None:
    clusters = _clusters({**_arc(500, 539), 499: 3.0, 540: 8.0})
    assert clusters.n == 1
    assert clusters.end_occluded.tolist() == [[True, False]]  # nearer before, farther after
    assert (clusters.end_x_m[0, 0], clusters.end_y_m[0, 0]) == pytest.approx(_point(500))
    assert (clusters.end_x_m[0, 1], clusters.end_y_m[0, 1]) == pytest.approx(_point(539))


@pytest.mark.parametrize(
    ("after", "occluded"),
    [
        ({540: 5.0 - OCCLUSION_MARGIN_M + 0.01}, False),  # nearer, but within the margin
        ({540: 5.0 - OCCLUSION_MARGIN_M - 0.01}, True),
        ({541: 3.0}, False),  # the adjacent beam had no return: open, whatever comes next
        ({}, False),
    ],
)
def test_only_the_adjacent_beam_beyond_the_margin_occludes(
    after: dict[int, float], occluded: bool
) -> None:
    clusters = _clusters({**_arc(500, 539), **after})
    assert clusters.end_occluded[0].tolist() == [False, occluded]


def test_a_cluster_across_the_seam_behind_the_scanner_is_cut_at_its_gap() -> None:
    # Beams 1070..1079 and 0..9 are one wall straight behind; beam 10 sees something nearer.
    clusters = _clusters({**_arc(-10, 9), 10: 3.0})
    assert clusters.n == 1
    assert (clusters.end_x_m[0, 0], clusters.end_y_m[0, 0]) == pytest.approx(_point(1070))
    assert (clusters.end_x_m[0, 1], clusters.end_y_m[0, 1]) == pytest.approx(_point(9))
    assert clusters.end_occluded.tolist() == [[False, True]]


def test_several_clusters_each_get_their_own_ends() -> None:
    clusters = _clusters({**_arc(200, 219), **_arc(220, 239, 7.0), **_arc(600, 629, 4.0)})
    assert clusters.n == 3
    # The far arc (7 m) is bounded by the near one (5 m) at its start, not the other way.
    by_range = np.argsort(np.hypot(clusters.centroid_x_m, clusters.centroid_y_m))
    near, far, other = by_range[1], by_range[2], by_range[0]
    assert clusters.end_occluded[near].tolist() == [False, False]
    assert clusters.end_occluded[far].tolist() == [True, False]
    assert clusters.end_occluded[other].tolist() == [False, False]
    assert clusters.end_x_m.shape == clusters.end_occluded.shape == (3, 2)


def test_a_scan_without_clusters_has_no_ends() -> None:
    clusters = _clusters({})
    assert clusters.end_x_m.shape == clusters.end_occluded.shape == (0, 2)
