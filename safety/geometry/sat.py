"""Separating-axis collision checks between batches of convex polygons (SR-SAT-1, SR-SAT-6).

The verdict for a pair (A, B) is *clear* exactly when one of these axis tests separates them
by more than the pair's threshold ``thr = tolerance + RHO * M + slack_A + slack_B`` (metres;
``M`` the largest coordinate magnitude of the pair, ``slack`` from the normalisation):

* the x or y axis (bounding boxes; their threshold is ``tolerance + (slack_A + RHO * M_A) +
  (slack_B + RHO * M_B)``, ``M_X`` the largest coordinate magnitude of X, which is at least
  ``thr`` and the same in both entry points),
* the line through the two bounding-box centres,
* any edge normal of A or of B (the separating axis theorem: two convex polygons are disjoint
  if and only if one of these separates them).

Each projection gap is computed in floating point within ``8u |n| M`` of its exact value, and
``RHO`` is 64u, so "clear" is a proof in exact arithmetic that the polygons share no point:
zero false negatives. A pair reported as colliding is either overlapping or touching, or
separated by no more than ``thr`` along every edge normal (the tolerance band).

The other step only decides pairs sooner, never differently: a point certified inside both
polygons (with a margin above rounding) proves an overlap that no axis test can contradict,
so those pairs skip the edge-normal tests. So the all-pairs and the matched-pairs entry points
return identical verdicts, in either argument order.

Hot path: the pairs no box separates are gathered into buffers ``[row, K, column]`` whose
first ``n`` columns hold the A sides and the next ``n`` the B sides of the ``n`` pairs, so each
step is one whole-array numpy call for both sides of every pair, and reductions run over the
leading axis. At a few thousand pairs the number of calls and of passes over memory, not the
arithmetic, is what costs, so the kernel is a fixed sequence of about sixty calls. Large
scratch arrays come from a :class:`~safety.geometry.polygons.Workspace` (no fresh mapping per call).
The kernel takes at most :data:`CHUNK_PAIRS` pairs at a time and the edge-normal tests at most
:data:`FULL_CHUNK_PAIRS`, so their scratch is bounded by the polygons' vertex count ``K`` alone,
whatever the batch: ``8 * (10 K * 2 CHUNK_PAIRS + 2 K^2 * 2 FULL_CHUNK_PAIRS)`` bytes, 13.6 MB
at 32 vertices (SR-RUN-5: resident memory flat over a shift, not grown at each new largest
scene).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.types import BoolArray, ConvexPolygons, FloatArray, IntArray
from safety.geometry.polygons import GeometryError, U, Workspace

__all__ = ["CERT_KAPPA", "CHUNK_PAIRS", "FULL_CHUNK_PAIRS", "RHO", "SatChecker", "SatStats"]

RHO = 64.0 * U
CERT_KAPPA = 16.0 * U
# Pairs per pass of the kernel and of the edge-normal tests. Each pass is a fixed sequence of
# whole-array calls; passes of this many pairs cost no more than one pass over a batch of 3,500
# random pairs (its scratch then stays in cache), smaller ones up to 40 % more.
CHUNK_PAIRS = 1024
FULL_CHUNK_PAIRS = 256


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


def _reach(vertices: FloatArray, slack_m: FloatArray) -> FloatArray:
    """How far each polygon's exact region may reach beyond its bounding box, with the rounding
    of the box comparison: ``slack + RHO * M`` per polygon (``vertices`` (2, K, N)) [m]."""
    magnitude: FloatArray = np.abs(vertices).max(axis=(0, 1))
    return np.asarray(slack_m, dtype=np.float64) + RHO * magnitude


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
    # The box test: A and B are clear along x or y when min_A > max_B + tol or min_B >
    # max_A + tol (the rounded sum is >= max, so a box separation is exact). Both entry
    # points evaluate exactly these comparisons (negation is exact), so they agree.
    def overlap_pairs(self, a: ConvexPolygons, b: ConvexPolygons) -> BoolArray:
        """Collision verdict of each matched pair (a[i], b[i]); shape (N,)."""
        _check(a, "a")
        _check(b, "b")
        if a.n != b.n:
            raise GeometryError(f"overlap_pairs: {a.n} polygons in a but {b.n} in b")
        n_all = a.n
        va, vb = a.vertices_m, b.vertices_m
        box = self._ws.get("box", (4, 2, n_all))  # rows min x, min y, max x, max y; [side]
        np.minimum.reduce(va, axis=1, out=box[:2, 0])
        np.maximum.reduce(va, axis=1, out=box[2:, 0])
        np.minimum.reduce(vb, axis=1, out=box[:2, 1])
        np.maximum.reduce(vb, axis=1, out=box[2:, 1])
        # min_A <= max_B + pad and min_B <= max_A + pad, pad = tol + reach_A + reach_B with
        # reach_X = slack_X + RHO * M_X: a polygon's exact region may lie up to its slack
        # beyond its vertices, and RHO * M covers the rounding of these sums.
        pad = np.add(_reach(va, a.slack_m), _reach(vb, b.slack_m))
        pad += self.tolerance_m
        reach = self._ws.get("reach", (2, 2, n_all))  # [row, side]: the other side's max + pad
        np.add(box[2:, 1], pad, out=reach[:, 0])
        np.add(box[2:, 0], pad, out=reach[:, 1])
        near = np.less_equal(box[:2], reach).reshape(4, n_all)
        idx = np.flatnonzero(np.logical_and.reduce(near, axis=0))
        self.stats = SatStats(pairs=n_all, box=n_all - idx.size)
        out = np.zeros(n_all, dtype=bool)
        if idx.size:
            bx = np.take(box, idx, axis=2, mode="clip").reshape(4, 2 * idx.size)
            out[idx] = self._decide(va, vb, a.slack_m, b.slack_m, bx, idx, idx)
        return out

    def overlap_all(self, a: ConvexPolygons, b: ConvexPolygons) -> BoolArray:
        """Collision verdict of every pair (a[i], b[j]); shape (Na, Nb)."""
        _check(a, "a")
        _check(b, "b")
        va, vb = a.vertices_m, b.vertices_m
        tol = self.tolerance_m
        # left[r, i] <= right[r, j] for all four rows r: min_A <= max_B + tol and, negated,
        # -(max_A + tol) <= -min_B. box = (min x, min y, max x, max y) per polygon.
        box_a, left = np.empty((4, a.n)), np.empty((4, a.n))
        box_b, right = np.empty((4, b.n)), np.empty((4, b.n))
        np.minimum.reduce(va, axis=1, out=box_a[:2])
        np.maximum.reduce(va, axis=1, out=box_a[2:])
        np.minimum.reduce(vb, axis=1, out=box_b[:2])
        np.maximum.reduce(vb, axis=1, out=box_b[2:])
        # The same pad as overlap_pairs, split by side: min_A - reach_A <= max_B + tol +
        # reach_B and -(max_A + tol + reach_A) <= -(min_B - reach_B).
        reach_a, reach_b = _reach(va, a.slack_m), _reach(vb, b.slack_m)
        np.subtract(box_a[:2], reach_a, out=left[:2])
        np.subtract(-tol, box_a[2:], out=left[2:])
        left[2:] -= reach_a
        np.add(box_b[2:], tol, out=right[:2])
        right[:2] += reach_b
        np.negative(box_b[:2], out=right[2:])
        right[2:] += reach_b
        # The longer side of the (Na, Nb) table runs innermost (numpy's inner loop).
        if a.n >= b.n:
            near = np.less_equal(left[:, None, :], right[:, :, None])
            flat = np.flatnonzero(np.logical_and.reduce(near, axis=0))
            ib = flat // a.n
            ia = flat - ib * a.n
            flat = ia * b.n + ib
        else:
            near = np.less_equal(left[:, :, None], right[:, None, :])
            flat = np.flatnonzero(np.logical_and.reduce(near, axis=0))
            ia = flat // b.n
            ib = flat - ia * b.n
        pairs = a.n * b.n
        self.stats = SatStats(pairs=pairs, box=pairs - flat.size)
        out = np.zeros((a.n, b.n), dtype=bool)
        if flat.size:
            n = flat.size
            bx = np.empty((4, 2 * n))
            np.take(box_a, ia, axis=1, out=bx[:, :n], mode="clip")
            np.take(box_b, ib, axis=1, out=bx[:, n:], mode="clip")
            out.reshape(-1)[flat] = self._decide(va, vb, a.slack_m, b.slack_m, bx, ia, ib)
        return out

    # -- the kernel -----------------------------------------------------------------------
    def _decide(
        self,
        va: FloatArray,
        vb: FloatArray,
        slack_a: FloatArray,
        slack_b: FloatArray,
        bx: FloatArray,
        ia: IntArray,
        ib: IntArray,
    ) -> BoolArray:
        """Collision verdicts of the pairs (A[ia], B[ib]) that no box separates, at most
        :data:`CHUNK_PAIRS` at a time (each pair's verdict is its own).

        ``va``/``vb`` are (xy, K, N) vertices; ``bx`` (4, 2n) the boxes (min x, min y, max x,
        max y) of the n pairs' A sides then B sides.
        """
        n = ia.size
        collide = np.empty(n, dtype=bool)
        for lo in range(0, n, CHUNK_PAIRS):
            hi = min(n, lo + CHUNK_PAIRS)
            part = np.concatenate((bx[:, lo:hi], bx[:, n + lo : n + hi]), axis=1)
            sides = (va, vb, slack_a, slack_b)
            collide[lo:hi] = self._decide_chunk(sides, part, ia[lo:hi], ib[lo:hi])
        return collide

    def _decide_chunk(
        self,
        sides: tuple[FloatArray, FloatArray, FloatArray, FloatArray],
        bx: FloatArray,
        ia: IntArray,
        ib: IntArray,
    ) -> BoolArray:
        """:meth:`_decide` on one chunk of pairs (``sides``: A's and B's vertices, then their
        slacks); adds its counts to :attr:`stats`. Column c < n of every buffer is pair c's A
        side, column n + c its B side."""
        va, vb, slack_a, slack_b = sides
        n = ia.size
        m = 2 * n
        ka, kb = va.shape[1], vb.shape[1]
        k = max(ka, kb)
        scratch = self._ws.get("kernel", (10, k, m))
        v, ed, prod, val = scratch[:2], scratch[2:6], scratch[6:8], scratch[8:10]
        np.take(va, ia, axis=2, out=v[:, :ka, :n], mode="clip")
        np.take(vb, ib, axis=2, out=v[:, :kb, n:], mode="clip")
        if ka < k:
            v[:, ka:, :n] = v[:, :1, :n]
        if kb < k:
            v[:, kb:, n:] = v[:, :1, n:]

        # Per pair: M = max |coordinate| (the largest |bound| of the two boxes), thr =
        # (slack_A + slack_B) + (tol + RHO * M), and the centre-line direction 2d = (min +
        # max)_B - (min + max)_A (twice the centre difference, exactly: the same axis, and the
        # test below is scale-free); A's columns hold 2d, B's -2d.
        scale = np.maximum.reduce(np.abs(bx), axis=0)
        magnitude = np.maximum(scale[:n], scale[n:])
        neg_thr = np.multiply(magnitude, -RHO)  # -thr, exactly: rounding is symmetric
        neg_thr -= self.tolerance_m
        neg_thr -= np.add(slack_a.take(ia), slack_b.take(ib))
        twice = np.add(bx[:2], bx[2:]).reshape(2, 2, n)
        d = np.subtract(twice[:, ::-1], twice).reshape(2, m)

        # Edges: rows ey, ex, c, |e|^2 (edge i from vertex i to i + 1 cyclically, outward
        # normal (ey, -ex), c = n . v_i). Zero-length (padding) edges get c = +inf: they then
        # never separate (gap -inf) and never veto a certificate (n . p - c = -inf).
        np.subtract(v[1::-1, 1:], v[1::-1, :-1], out=ed[:2, :-1])
        np.subtract(v[1::-1, 0], v[1::-1, -1], out=ed[:2, -1])
        np.multiply(ed[:2], v, out=prod)
        np.subtract(prod[0], prod[1], out=ed[2])
        np.multiply(ed[:2], ed[:2], out=prod)
        np.add(prod[0], prod[1], out=ed[3])
        np.copyto(ed[2], np.inf, where=ed[3] == 0)

        # Centre line: A's side projected on d, B's on -d (negation is exact), so one max
        # gives top = (max_A d.a, -min_B d.b), and the gap min_B - max_A = -(top_A + top_B)
        # exceeds |d| thr exactly when top_A + top_B < |d| * -thr.
        line = prod.reshape(2, k, 2, n)
        np.multiply(v.reshape(2, k, 2, n)[0], d.reshape(2, 2, n)[0], out=line[0])
        np.multiply(v.reshape(2, k, 2, n)[1], d.reshape(2, 2, n)[1], out=line[1])
        np.add(line[0], line[1], out=line[0])
        top, pick = _column_max(prod[0])
        limit = np.hypot(d[0, :n], d[1, :n])
        limit *= neg_thr
        sep = np.less(np.add(top[:n], top[n:]), limit)

        # Certificates: the first vertex of each side extreme towards the other side (A's
        # farthest along d, B's farthest back) strictly inside the other polygon, with a
        # margin above rounding, is a common point: an overlap.
        pts = np.take(v.reshape(2, k * m), pick, axis=1).reshape(2, 2, n)[:, ::-1]
        # Margin: with t = fl(n . p - c), t < -(8 CERT_KAPPA M^2) implies t + |e| CERT_KAPPA
        # M < 0 (every computed |e| <= 2.9 M, 8 CERT_KAPPA = 2^-46 is a power of two), which
        # is the certificate condition whose margin covers the rounding of t: still a proof.
        margin = np.multiply(magnitude, -8.0 * CERT_KAPPA)
        margin *= magnitude
        ed4, val4 = ed.reshape(4, k, 2, n), val.reshape(2, k, 2, n)
        np.multiply(ed4[0], pts[0], out=val4[0])
        np.multiply(ed4[1], pts[1], out=val4[1])
        np.subtract(val4[0], val4[1], out=val4[0])
        np.subtract(val4[0], ed4[2], out=val4[0])
        inside = np.logical_and.reduce(np.less(val4[0], margin), axis=0)
        decided = np.logical_or(inside[0], inside[1])
        decided |= sep
        rest = np.flatnonzero(~decided)
        stats = self.stats
        line_sep = int(np.count_nonzero(sep))
        stats.centre_line += line_sep
        stats.certificate += n - rest.size - line_sep
        stats.full_sat += int(rest.size)
        thr = np.negative(neg_thr.take(rest))
        for lo in range(0, rest.size, FULL_CHUNK_PAIRS):
            part = slice(lo, lo + FULL_CHUNK_PAIRS)
            sep[rest[part]] = _separated_full(self._ws, ed, v, rest[part], thr[part])
        collide: BoolArray = ~sep
        return collide


def _check(polygons: ConvexPolygons, name: str) -> None:
    if not isinstance(polygons, ConvexPolygons):
        raise GeometryError(
            f"{name}: expected ConvexPolygons (see safety.geometry.polygons.convex_polygons), "
            f"got {type(polygons).__name__}"
        )


def _column_max(x: FloatArray) -> tuple[FloatArray, IntArray]:
    """Per column of a (K, m) array: the maximum, and the flat index of its first row.

    ``argmax`` along a leading axis copies the array and loops per column: fine for few
    columns; for many, a weighted maximum of the "equals the maximum" mask over the leading
    axis, in the narrowest integer type, is several times faster.
    """
    k, m = x.shape
    if m < 16 * k:
        flat: IntArray = np.multiply(np.argmax(x, axis=0), m)
        flat += np.arange(m)
        return x.reshape(-1).take(flat), flat
    top: FloatArray = np.maximum.reduce(x, axis=0)
    weight = np.arange(k, 0, -1, dtype=np.min_scalar_type(k))[:, None]  # k - row
    first = np.maximum.reduce(np.multiply(np.equal(x, top), weight), axis=0)
    flat = np.multiply(first, -m, dtype=np.intp)
    flat += np.arange(k * m, k * m + m)
    return top, flat


def _separated_full(
    ws: Workspace, ed: FloatArray, v: FloatArray, rest: IntArray, thr: FloatArray
) -> BoolArray:
    """Does any edge normal of either side of the pairs ``rest`` separate it from the other
    side's vertices by more than |n| * thr? (``thr`` holds those pairs' thresholds.)"""
    k, m = v.shape[1:]
    r = rest.size
    own = rest + np.array([[0], [m // 2]])  # [side, pair]: the columns of the pairs' sides
    e = np.take(ed, own, axis=2)  # [row, K, side, pair]
    w = np.take(v, own[::-1], axis=2).reshape(2, k, 2 * r)  # the other side's vertices
    proj = ws.get("full", (2, k, k, 2 * r))  # [., vertex j, edge i, column]
    np.multiply(e[0].reshape(k, 2 * r), w[0][:, None, :], out=proj[0])
    np.multiply(e[1].reshape(k, 2 * r), w[1][:, None, :], out=proj[1])
    np.subtract(proj[0], proj[1], out=proj[0])
    low = np.minimum.reduce(proj[0], axis=0).reshape(k, 2, r)
    low -= e[2]
    limit = np.sqrt(e[3])
    limit *= thr
    separated: BoolArray = np.logical_or.reduce(low > limit, axis=(0, 1))
    return separated
