"""Separating-axis collision checks between batches of convex polygons (SR-SAT-1, SR-SAT-6).

The verdict for a pair (A, B) is *clear* exactly when one of these axis tests separates them
by more than the pair's threshold ``thr = tolerance + RHO * M + slack_A + slack_B`` (metres;
``M`` the largest coordinate magnitude of the pair, ``slack`` from the normalisation):

* the x or y axis (bounding boxes, compared exactly),
* the line through the two bounding-box centres,
* any edge normal of A or of B (the separating axis theorem: two convex polygons are disjoint
  if and only if one of these separates them).

Each projection gap is computed in floating point within ``8u |n| M`` of its exact value, and
``RHO`` is 64u, so "clear" is a proof in exact arithmetic that the polygons share no point:
zero false negatives. A pair reported as colliding is either overlapping or touching, or
separated by no more than ``thr`` along every edge normal (the tolerance band).

The other steps only decide pairs sooner, never differently: a bounding-circle reject
(used by the planner's distance pre-gate) implies the centre-line test, and a point certified
inside both polygons (with a margin above rounding) proves an overlap that no axis test can
contradict. So the all-pairs and the matched-pairs entry points return identical verdicts, in
either argument order.

Hot-path layout: the candidate pairs' vertices are gathered into one (side, xy, K, pairs)
buffer and every step is a whole-array numpy call over all pairs; scratch arrays come from a
:class:`~safety.geometry.Workspace` so no large temporary is mapped afresh per call.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.types import BoolArray, ConvexPolygons, FloatArray, IntArray
from safety.geometry import GeometryError, PolygonBounds, U, Workspace

__all__ = ["CERT_KAPPA", "RHO", "SatChecker", "SatStats"]

RHO = 64.0 * U
CERT_KAPPA = 16.0 * U


@dataclass
class SatStats:
    """How the last call decided its pairs (for the evidence; cheap to keep)."""

    pairs: int = 0
    box: int = 0
    centre_line: int = 0
    certificate: int = 0
    full_sat: int = 0

    def as_dict(self) -> dict[str, int]:
        """Counts by deciding stage."""
        return {
            "pairs": self.pairs,
            "box": self.box,
            "centre_line": self.centre_line,
            "certificate": self.certificate,
            "full_sat": self.full_sat,
        }


class SatChecker:
    """Batched SAT overlap tests with reusable scratch buffers (not thread-safe).

    ``tolerance_m`` is the contact tolerance: pairs separated by at most this much along every
    edge normal are reported as colliding.
    """

    def __init__(self, tolerance_m: float = 1e-9) -> None:
        if not (np.isfinite(tolerance_m) and 0.0 <= tolerance_m <= 1e-3):
            raise GeometryError(
                f"SatChecker: tolerance_m = {tolerance_m!r}; expected a number in [0, 1e-3]"
            )
        self.tolerance_m = float(tolerance_m)
        self.stats = SatStats()
        self._ws = Workspace()

    # -- entry points ---------------------------------------------------------------------
    def overlap_pairs(self, a: ConvexPolygons, b: ConvexPolygons) -> BoolArray:
        """Collision verdict of each matched pair (a[i], b[i]); shape (N,)."""
        _check(a, "a")
        _check(b, "b")
        if a.n != b.n:
            raise GeometryError(f"overlap_pairs: {a.n} polygons in a but {b.n} in b")
        ba, bb = PolygonBounds(a), PolygonBounds(b)
        tol = self.tolerance_m
        clear = (
            (ba.min_x_m > bb.max_x_m + tol)
            | (bb.min_x_m > ba.max_x_m + tol)
            | (ba.min_y_m > bb.max_y_m + tol)
            | (bb.min_y_m > ba.max_y_m + tol)
        )
        idx = np.flatnonzero(~clear)
        self.stats = SatStats(pairs=a.n, box=a.n - idx.size)
        out = np.zeros(a.n, dtype=bool)
        if idx.size:
            out[idx] = self._decide(a, b, ba, bb, idx, idx)
        return out

    def overlap_all(self, a: ConvexPolygons, b: ConvexPolygons) -> BoolArray:
        """Collision verdict of every pair (a[i], b[j]); shape (Na, Nb)."""
        _check(a, "a")
        _check(b, "b")
        ba, bb = PolygonBounds(a), PolygonBounds(b)
        tol = self.tolerance_m
        # The boxes only: the bounding-circle test is implied by the kernel's centre-line
        # test, which is cheaper than computing radii for the few pairs it would remove.
        clear = (ba.min_x_m[:, None] > bb.max_x_m[None, :] + tol) | (
            bb.min_x_m[None, :] > ba.max_x_m[:, None] + tol
        )
        clear |= ba.min_y_m[:, None] > bb.max_y_m[None, :] + tol
        clear |= bb.min_y_m[None, :] > ba.max_y_m[:, None] + tol
        flat = np.flatnonzero(~clear)
        ia, ib = np.divmod(flat, b.n)
        self.stats = SatStats(pairs=a.n * b.n, box=a.n * b.n - ia.size)
        out = np.zeros((a.n, b.n), dtype=bool)
        if ia.size:
            out[ia, ib] = self._decide(a, b, ba, bb, ia, ib)
        return out

    # -- the kernel -----------------------------------------------------------------------
    def _decide(
        self,
        a: ConvexPolygons,
        b: ConvexPolygons,
        ba: PolygonBounds,
        bb: PolygonBounds,
        ia: IntArray,
        ib: IntArray,
    ) -> BoolArray:
        """Collision verdicts of the pairs (a[ia], b[ib]) that no box separates.

        Vertices are gathered into v[xy, side, K, pair] (side 0: A, 1: B, both padded to one
        K), so each step below is one numpy call for both polygons of every pair; the call
        count, not the arithmetic, is what costs for the few pairs of a typical cycle.
        """
        ws = self._ws
        n = ia.size
        k = max(a.k, b.k)
        v = ws.get("v", (2, 2, k, n))
        np.take(a.vertices_m, ia, axis=2, out=v[:, 0, : a.k])
        np.take(b.vertices_m, ib, axis=2, out=v[:, 1, : b.k])
        if a.k < k:
            v[:, 0, a.k :] = v[:, 0, :1]
        if b.k < k:
            v[:, 1, b.k :] = v[:, 1, :1]
        sa, sb = ba.pack[:, ia], bb.pack[:, ib]  # centre x, centre y, magnitude, slack
        magnitude = np.maximum(sa[2], sb[2])
        thr = sa[3] + sb[3] + (self.tolerance_m + RHO * magnitude)
        d = sb[:2] - sa[:2]
        e = _edges(ws, v)
        ex, ey, c, length = e

        # Centre line: project both polygons on d = cB - cA.
        proj = ws.get("p", (2, k, n))
        tmp = ws.get("tmp", (2, k, n))
        np.multiply(v[0], d[0], out=proj)
        np.multiply(v[1], d[1], out=tmp)
        np.add(proj, tmp, out=proj)
        top_a = proj[0].argmax(axis=0)
        low_b = proj[1].argmin(axis=0)
        cols = np.arange(n)
        gap = proj[1, low_b, cols] - proj[0, top_a, cols]
        sep = gap > np.hypot(d[0], d[1]) * thr
        by_line = int(np.count_nonzero(sep))

        # Certificates: B's vertex farthest back along d strictly inside A, or A's vertex
        # farthest along d strictly inside B (with a margin above rounding): an overlap.
        flat = np.stack([low_b * n + (k * n), top_a * n]) + cols
        pts = v.reshape(2, -1)[:, flat]  # [xy, polygon tested (A, B), pair]
        val = ws.get("val", (2, k, n))
        np.multiply(ey, pts[0][:, None, :], out=val)
        np.multiply(ex, pts[1][:, None, :], out=tmp)
        np.subtract(val, tmp, out=val)
        np.subtract(val, c, out=val)
        np.multiply(length, CERT_KAPPA * magnitude, out=tmp)
        np.add(val, tmp, out=val)
        cert = np.logical_and.reduce(val < 0, axis=1).any(axis=0)
        cert &= ~sep
        undecided = ~(sep | cert)

        rest = np.flatnonzero(undecided)
        if rest.size:
            er = e[..., rest]
            vr = v[:, ::-1][..., rest]
            sep[rest] = _separated_full(ws, er[0], er[1], er[2], er[3], vr[0], vr[1], thr[rest])
        stats = self.stats
        stats.centre_line = by_line
        stats.certificate = int(np.count_nonzero(cert))
        stats.full_sat = int(rest.size)
        collide: BoolArray = ~sep
        return collide


def _check(polygons: ConvexPolygons, name: str) -> None:
    if not isinstance(polygons, ConvexPolygons):
        raise GeometryError(
            f"{name}: expected ConvexPolygons (see safety.geometry.convex_polygons), "
            f"got {type(polygons).__name__}"
        )


def _edges(ws: Workspace, v: FloatArray) -> FloatArray:
    """Edge data e[0..3] = ex, ey, c, |e| of shape (side, K, n) for vertices v[xy, side, K, n].

    Edge i runs from vertex i to i+1 (cyclically); its outward normal is n = (ey, -ex) and
    c = n . v_i. Padding edges (zero length) get c = 1: they then never separate (their
    projections are all 0, so the gap is -1) and never veto a certificate (n.p - c = -1).
    """
    _, sides, k, n = v.shape
    e = ws.get("e", (4, sides, k, n))
    sq = ws.get("esq", (2, sides, k, n))
    np.subtract(v[:, :, 1:], v[:, :, :-1], out=e[:2, :, :-1])
    np.subtract(v[:, :, 0], v[:, :, -1], out=e[:2, :, -1])
    np.multiply(e[1], v[0], out=e[2])
    np.multiply(e[0], v[1], out=sq[0])
    np.subtract(e[2], sq[0], out=e[2])
    np.multiply(e[:2], e[:2], out=sq)
    np.add(sq[0], sq[1], out=e[3])
    np.sqrt(e[3], out=e[3])
    np.putmask(e[2], e[3] == 0, 1.0)
    result: FloatArray = e
    return result


def _separated_full(
    ws: Workspace,
    ex: FloatArray,
    ey: FloatArray,
    c: FloatArray,
    length: FloatArray,
    ox: FloatArray,
    oy: FloatArray,
    thr: FloatArray,
) -> BoolArray:
    """Does any edge normal of either side separate it from the other side's vertices?"""
    sides, k, n = ex.shape
    ko = ox.shape[1]
    proj = ws.get("fp", (sides, k, ko, n))
    tmp = ws.get("ft", (sides, k, ko, n))
    np.multiply(ey[:, :, None, :], ox[:, None, :, :], out=proj)
    np.multiply(ex[:, :, None, :], oy[:, None, :, :], out=tmp)
    np.subtract(proj, tmp, out=proj)
    low = np.minimum.reduce(proj, axis=2)
    np.subtract(low, c, out=low)
    separated: BoolArray = (low > length * thr).any(axis=(0, 1))
    return separated
