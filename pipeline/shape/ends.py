"""The two ends of each cluster as the scanner sees them, and whether they are occluded (SR-CLS-2).

A cluster's *ends* are its first and last point in the counter-clockwise sweep (the points
are sorted by bearing; column 0 is where the sweep enters the cluster, column 1 where it
leaves). An end is *occluded* when the beam next to it, just outside the cluster, returned a
point more than :data:`OCCLUSION_MARGIN_M` nearer to the scanner: something stands in front
there, and the object may go on behind it. A neighbouring beam with no return, or with a
farther one, leaves the end *free*: that is the object's outline.

Why the classifier wants this: a truck seen through a gap between racks, or past a nearer
object, shows only the part between two occluders. Its clipped ends stay at the occluders'
edges while it moves, so its centroid barely moves; a free end moves with the object. The
tracker keeps each track's ends in its history and :mod:`pipeline.features` turns them into
end speeds (docs/findings/classification.md).

Only the adjacent beam counts (its ``beam_index`` differs by one, modulo the scan's beam
count, and it comes from the same scanner), so a dropped beam (no return, out of range)
between the end and the next point leaves the end free. A cluster that straddles the seam of
the sweep (bearing +/- pi, straight behind the scanner) is cut at its largest bearing gap
instead of at the seam.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.types import BoolArray, FloatArray, IntArray, ScanPoints

__all__ = ["OCCLUSION_MARGIN_M", "cluster_ends"]

OCCLUSION_MARGIN_M = 0.3
"""How much nearer than an end its neighbouring beam's return must be to occlude it [m]. Twice
DBSCAN's ``eps_m`` (0.15 m), so a surface that merely continues at a slant does not count. Part
of the feature's definition (the model is trained with it), not configuration."""


def cluster_ends(
    points: ScanPoints, labels: IntArray, n_clusters: int
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """``(end_x_m, end_y_m, end_occluded)``, each (n_clusters, 2), for the clusters that
    ``labels`` (one kept-cluster index or -1 per point of ``points``) defines (module
    docstring). Coordinates are the points' own (robot frame) [m]. Serves SR-CLS-2."""
    n = points.n
    first = np.full(n_clusters, n, dtype=np.int64)
    last = np.full(n_clusters, -1, dtype=np.int64)
    member = np.flatnonzero(labels >= 0)
    np.minimum.at(first, labels[member], member)
    np.maximum.at(last, labels[member], member)
    angle = points.angle_rad
    for k in np.flatnonzero(angle[last] - angle[first] > math.pi):
        # Straddles the seam: its members near -pi follow those near +pi in the sweep.
        idx = np.flatnonzero(labels == k)
        cut = int(np.argmax(np.diff(angle[idx])))
        first[k], last[k] = idx[cut + 1], idx[cut]
    ends = np.stack([first, last], axis=1)
    neighbour = np.stack([first - 1, last + 1], axis=1) % max(n, 1)
    n_beams = max(points.drops.n_beams, 1)
    beam = points.beam_index
    step = np.abs(beam[neighbour] - beam[ends]) % n_beams
    # A second scanner's beams are numbered from n_beams on (pipeline.scanners): a beam of one
    # scanner is never adjacent to a beam of the other.
    same_scanner = (beam[neighbour] >= n_beams) == (beam[ends] >= n_beams)
    adjacent = same_scanner & ((step == 1) | (step == n_beams - 1))
    nearer = points.range_m[neighbour] < points.range_m[ends] - OCCLUSION_MARGIN_M
    occluded: BoolArray = adjacent & nearer
    return points.x_m[ends], points.y_m[ends], occluded
