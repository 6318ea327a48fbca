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

The other steps only decide pairs sooner, never differently: the bounding circle and the
distance pre-gate imply the centre-line test, and a point certified inside both polygons
(with a margin above rounding) proves an overlap that no axis test can contradict. So the
all-pairs and the matched-pairs entry points return identical verdicts, in either argument
order.
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
    box_or_circle: int = 0
    centre_line: int = 0
    certificate: int = 0
    full_sat: int = 0

    def as_dict(self) -> dict[str, int]:
        """Counts by deciding stage."""
        return {
            "pairs": self.pairs,
            "box_or_circle": self.box_or_circle,
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
        self.stats = SatStats(pairs=a.n, box_or_circle=a.n - idx.size)
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
        magnitude = np.maximum(ba.magnitude_m[:, None], bb.magnitude_m[None, :])
        thr = tol + RHO * magnitude + ba.slack[:, None] + bb.slack[None, :]
        dx = bb.centre_x_m[None, :] - ba.centre_x_m[:, None]
        dy = bb.centre_y_m[None, :] - ba.centre_y_m[:, None]
        reach = ba.radius_m[:, None] + bb.radius_m[None, :] + 2.0 * thr
        clear = (
            (ba.min_x_m[:, None] > bb.max_x_m[None, :] + tol)
            | (bb.min_x_m[None, :] > ba.max_x_m[:, None] + tol)
            | (ba.min_y_m[:, None] > bb.max_y_m[None, :] + tol)
            | (bb.min_y_m[None, :] > ba.max_y_m[:, None] + tol)
            | (dx * dx + dy * dy > reach * reach)
        )
        flat = np.flatnonzero(~clear)
        ia, ib = np.divmod(flat, b.n)
        self.stats = SatStats(pairs=a.n * b.n, box_or_circle=a.n * b.n - ia.size)
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
        """Collision verdicts of the pairs (a[ia], b[ib]) that no box or circle separates.

        Both sides are stacked on a leading axis (0: A, 1: B) and padded to one K, so each
        step below is one numpy call for both polygons of every pair.
        """
        ws = self._ws
        n = ia.size
        k = max(a.k, b.k)
        v = ws.get("v", (2, 2, k, n))
        np.take(a.vertices_m, ia, axis=2, out=v[0, :, : a.k])
        np.take(b.vertices_m, ib, axis=2, out=v[1, :, : b.k])
        if a.k < k:
            v[0, :, a.k :] = v[0, :, :1]
        if b.k < k:
            v[1, :, b.k :] = v[1, :, :1]
        x, y = v[:, 0], v[:, 1]
        magnitude = np.maximum(ba.magnitude_m[ia], bb.magnitude_m[ib])
        thr = self.tolerance_m + RHO * magnitude + ba.slack[ia] + bb.slack[ib]
        cx = np.stack([ba.centre_x_m[ia], bb.centre_x_m[ib]])
        cy = np.stack([ba.centre_y_m[ia], bb.centre_y_m[ib]])
        ex, ey, c, length = _edges(ws, x, y)
        cols = np.arange(n)

        # Centre line: project both polygons on d = cB - cA.
        dx, dy = cx[1] - cx[0], cy[1] - cy[0]
        proj = _project(ws, "p", dx, dy, x, y)
        top_a = proj[0].argmax(axis=0)
        low_b = proj[1].argmin(axis=0)
        sep = proj[1, low_b, cols] - proj[0, top_a, cols] > np.sqrt(dx * dx + dy * dy) * thr
        decided_line = int(sep.sum())

        # Certificates: B's vertex farthest back along d strictly inside A, or A's vertex
        # farthest along d strictly inside B (with a margin above rounding): an overlap.
        px = np.stack([x[1, low_b, cols], x[0, top_a, cols]])
        py = np.stack([y[1, low_b, cols], y[0, top_a, cols]])
        cert = _inside(ws, px, py, ex, ey, c, length, CERT_KAPPA * magnitude).any(axis=0)
        cert &= ~sep
        undecided = ~(sep | cert)

        rest = np.flatnonzero(undecided)
        if rest.size:
            e = ws.get("e", (4, 2, k, n))
            er = e[..., rest]
            vr = v[::-1][..., rest]
            sep[rest] = _separated_full(
                ws, er[0], er[1], er[2], er[3], vr[:, 0], vr[:, 1], thr[rest]
            )
        stats = self.stats
        stats.centre_line = decided_line
        stats.certificate = int(cert.sum())
        stats.full_sat = int(rest.size)
        collide: BoolArray = ~sep
        return collide


def _check(polygons: ConvexPolygons, name: str) -> None:
    if not isinstance(polygons, ConvexPolygons):
        raise GeometryError(
            f"{name}: expected ConvexPolygons (see safety.geometry.convex_polygons), "
            f"got {type(polygons).__name__}"
        )


def _edges(
    ws: Workspace, x: FloatArray, y: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Edge vectors (ex, ey), offsets c = n . v with n = (ey, -ex) outward, lengths |e|.

    ``x``, ``y`` are (sides, K, n); edge i runs from vertex i to vertex i+1 (cyclically).
    """
    shape = x.shape
    # One buffer for all four, so the few pairs left for the full test gather in one call.
    ex, ey, c, length = ws.get("e", (4, *shape))
    tmp = ws.get("tmp", shape)
    np.subtract(x[:, 1:], x[:, :-1], out=ex[:, :-1])
    np.subtract(x[:, 0], x[:, -1], out=ex[:, -1])
    np.subtract(y[:, 1:], y[:, :-1], out=ey[:, :-1])
    np.subtract(y[:, 0], y[:, -1], out=ey[:, -1])
    np.multiply(ey, x, out=c)
    np.multiply(ex, y, out=tmp)
    np.subtract(c, tmp, out=c)
    np.multiply(ex, ex, out=length)
    np.multiply(ey, ey, out=tmp)
    np.add(length, tmp, out=length)
    np.sqrt(length, out=length)
    return ex, ey, c, length


def _project(
    ws: Workspace, tag: str, dx: FloatArray, dy: FloatArray, x: FloatArray, y: FloatArray
) -> FloatArray:
    """d . v for every vertex; d broadcasts against the (sides, K, n) vertex arrays."""
    out: FloatArray = ws.get(tag, x.shape)
    tmp = ws.get(tag + "t", x.shape)
    np.multiply(x, dx, out=out)
    np.multiply(y, dy, out=tmp)
    np.add(out, tmp, out=out)
    return out


def _inside(
    ws: Workspace,
    px: FloatArray,
    py: FloatArray,
    ex: FloatArray,
    ey: FloatArray,
    c: FloatArray,
    length: FloatArray,
    kappa: FloatArray,
) -> BoolArray:
    """Point (px[s], py[s]) certainly strictly inside polygon s: n.p - c < -kappa |n|."""
    v = ws.get("in", ex.shape)
    tmp = ws.get("int", ex.shape)
    np.multiply(ey, px[:, None, :], out=v)
    np.multiply(ex, py[:, None, :], out=tmp)
    np.subtract(v, tmp, out=v)
    np.subtract(v, c, out=v)
    np.multiply(length, kappa, out=tmp)
    np.add(v, tmp, out=v)
    # Padding edges have n = 0, c = 0: v = 0 there, which must not veto the certificate.
    inside: BoolArray = np.logical_and.reduce((v < 0) | (length == 0), axis=1)
    return inside


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
