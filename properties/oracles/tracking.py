"""Reference implementations for clustering and tracking (test-only; SR-TRK-2, -3, -5).

* scikit-learn's ``DBSCAN`` (KD-tree radius queries, distance <= eps, a point counts itself);
* filterpy's ``KalmanFilter`` with ``Q_discrete_white_noise``, one filter per track;
* Stone Soup's ``GOSPAMetric``;
* shapely (GEOS) for convex hulls and minimum rotated rectangles.

:func:`compare_partitions` states what "the same partition" means for SR-TRK-2.
"""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import shapely
from filterpy.common import Q_discrete_white_noise
from filterpy.kalman import KalmanFilter
from sklearn.cluster import DBSCAN

from pipeline.cluster.dbscan import DbscanResult
from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = [
    "PartitionDiff",
    "compare_partitions",
    "filterpy_filters",
    "geos_hull_area",
    "geos_min_rect",
    "sklearn_dbscan",
    "stonesoup_gospa",
]


def sklearn_dbscan(xy_m: FloatArray, eps_m: float, min_samples: int) -> tuple[IntArray, BoolArray]:
    """scikit-learn's labels and core mask for points ``xy_m`` (n, 2)."""
    n = xy_m.shape[0]
    if n == 0:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=bool)
    model = DBSCAN(eps=eps_m, min_samples=min_samples, algorithm="kd_tree").fit(xy_m)
    core = np.zeros(n, dtype=bool)
    core[model.core_sample_indices_] = True
    return model.labels_.astype(np.int64), core


@dataclass(frozen=True, slots=True)
class PartitionDiff:
    """Disagreements between our DBSCAN and the reference on one point set.

    ``core``: points core in one and not the other; ``core_partition``: core pairs grouped
    together by one and apart by the other (counted as clusters whose core points do not map
    one-to-one); ``noise``: points noise in one only; ``border_rule``: border points whose
    cluster is not that of their nearest core point (ties: lower cluster); ``border_vs_ref``:
    border points assigned differently from the reference (allowed: order-dependent there).
    """

    core: int
    core_partition: int
    noise: int
    border_rule: int
    border_vs_ref: int

    @property
    def agrees(self) -> bool:
        """Same core points, same core partition, same noise, our border rule followed."""
        return self.core == self.core_partition == self.noise == self.border_rule == 0


def compare_partitions(
    xy_m: FloatArray, ours: DbscanResult, ref_labels: IntArray, ref_core: BoolArray, eps_m: float
) -> PartitionDiff:
    """Compare our raw DBSCAN result with scikit-learn's on the same points."""
    core_diff = int(np.count_nonzero(ours.is_core != ref_core))
    both = ours.is_core & ref_core
    pairs = {(int(a), int(b)) for a, b in zip(ours.labels[both], ref_labels[both], strict=True)}
    ours_used = {a for a, _ in pairs}
    ref_used = {b for _, b in pairs}
    partition_diff = (len(pairs) - len(ours_used)) + (len(pairs) - len(ref_used))
    noise_diff = int(np.count_nonzero((ours.labels < 0) != (ref_labels < 0)))
    border = np.flatnonzero((ours.labels >= 0) & ~ours.is_core)
    rule_fail = 0
    vs_ref = 0
    core_idx = np.flatnonzero(ours.is_core)
    mapping = dict(pairs)
    for b in border.tolist():
        d2 = (xy_m[core_idx, 0] - xy_m[b, 0]) ** 2 + (xy_m[core_idx, 1] - xy_m[b, 1]) ** 2
        within = d2 <= eps_m * eps_m
        cand_d2, cand_lab = d2[within], ours.labels[core_idx[within]]
        best = cand_lab[cand_d2 == cand_d2.min()].min() if cand_d2.shape[0] else -2
        rule_fail += int(ours.labels[b] != best)
        vs_ref += int(mapping.get(int(ours.labels[b]), -3) != ref_labels[b])
    return PartitionDiff(core_diff, partition_diff, noise_diff, rule_fail, vs_ref)


def filterpy_filters(
    x0: FloatArray, p0: FloatArray, accel_std_mps2: float, measurement_std_m: float
) -> list[KalmanFilter]:
    """One filterpy CV filter per track, state ``[x, y, vx, vy]``, F and Q set per step."""
    filters = []
    for x, p in zip(x0, p0, strict=True):
        kf = KalmanFilter(dim_x=4, dim_z=2)
        kf.x = x.reshape(4, 1).copy()
        kf.P = p.copy()
        kf.H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
        kf.R = np.eye(2) * measurement_std_m**2
        kf.accel_var = accel_std_mps2**2
        filters.append(kf)
    return filters


def filterpy_predict(kf: KalmanFilter, dt_s: float) -> None:
    """Predict one filterpy filter by ``dt_s`` with the matching F and Q."""
    f = np.eye(4)
    f[0, 2] = f[1, 3] = dt_s
    q = Q_discrete_white_noise(dim=2, dt=dt_s, var=kf.accel_var, block_size=2, order_by_dim=False)
    kf.predict(F=f, Q=q)


def stonesoup_gospa(truth_xy_m: FloatArray, hyp_xy_m: FloatArray, c_m: float, p: float) -> float:
    """Stone Soup's GOSPA distance (alpha 2) between two point sets at one instant."""
    from stonesoup.measures import Euclidean
    from stonesoup.metricgenerator.ospametric import GOSPAMetric
    from stonesoup.types.state import State

    stamp = datetime.datetime(2024, 1, 1)
    metric = GOSPAMetric(c=c_m, p=p, measure=Euclidean())
    truth = [State(np.asarray(xy, dtype=float).reshape(2, 1), timestamp=stamp) for xy in truth_xy_m]
    hyps = [State(np.asarray(xy, dtype=float).reshape(2, 1), timestamp=stamp) for xy in hyp_xy_m]
    if not truth and not hyps:
        return 0.0
    result, _ = metric.compute_gospa_metric(hyps, truth)
    return float(result.value["distance"])


def geos_hull_area(xy_m: FloatArray) -> float:
    """Area of the convex hull by GEOS."""
    return float(shapely.convex_hull(shapely.multipoints(xy_m)).area)


def geos_min_rect(xy_m: FloatArray) -> tuple[float, float]:
    """(width, length) of GEOS's minimum rotated rectangle (width <= length)."""
    rect = shapely.minimum_rotated_rectangle(shapely.multipoints(xy_m))
    if rect.geom_type == "Polygon":
        coords = np.asarray(rect.exterior.coords)
        sides = np.hypot(*(coords[1:3] - coords[0:2]).T)
        return float(sides.min()), float(sides.max())
    if rect.geom_type == "LineString":
        return 0.0, float(rect.length)
    return 0.0, 0.0


def sequence_ids(frames: Sequence[IntArray]) -> set[int]:
    """All IDs appearing in a sequence of ID arrays."""
    out: set[int] = set()
    for ids in frames:
        out.update(int(i) for i in ids)
    return out
