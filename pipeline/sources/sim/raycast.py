"""Vectorized 2D ray casting against polygon edges (SR-SIM-1, SR-SIM-4).

Ray ``i`` is ``o + t d_i`` (``t >= 0``, ``|d_i| = 1`` so ``t`` is the range in metres); edge
``s`` is ``a_s + u e_s`` (``0 <= u <= 1``). With ``w = a - o``, the crossing is at
``t = (w x e) / (d x e)`` and ``u = (w x d) / (d x e)``. All beams share the scanner origin in
a snapshot scan, so ``w x e`` is one number per edge and the two denominators' worth of cross
products for every (beam, edge) pair are one ``(B, 2) @ (2, 2S)`` matrix product.

Edges are the edges of closed counter-clockwise polygons and the sensor is outside all of
them, so a ray's first crossing is always where it *enters* a polygon. That happens only on
edges that face the sensor (``w x e < 0``); back-facing edges are dropped before the product
(exact, not a heuristic: see :func:`cast_snapshot`), as are edges farther than the maximum
range. Large per-scan temporaries live in buffers kept by :class:`RayCaster` (fresh arrays
over 128 KB would be mmap'd and page-faulted every scan).

:func:`cast_per_beam` is the general form for time-skewed scans, where every beam has its own
origin and its own copy of the moving edges; it makes no culling assumption.
"""

from __future__ import annotations

import numpy as np

from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = ["NO_HIT", "RayCaster", "cast_per_beam", "point_segment_distance"]

NO_HIT = -1  # edge index of a beam that hit nothing within range

# A ray that touches a polygon exactly at a vertex (a tangent, common when layouts sit on a
# grid and beams on round angles) gives u = 0 or 1 up to round-off; this allowance on the
# cross product w x d (m^2 scale) keeps such touches, as GEOS does.
_TOUCH = 1e-12

# Row blocks of the (B, 2) @ (2, 2S) products stay below this many output elements: OpenBLAS
# hands larger products to its thread pool, which on a loaded 2-core machine was measured 15x
# slower than one thread (16 ms instead of 1 ms for 1080 x 800).
_MATMUL_BLOCK_ELEMENTS = 1 << 17


def _matmul_rows(lhs: FloatArray, rhs: FloatArray, out: FloatArray) -> None:
    """``out[:] = lhs @ rhs`` in row blocks (see ``_MATMUL_BLOCK_ELEMENTS``)."""
    step = max(1, _MATMUL_BLOCK_ELEMENTS // max(1, rhs.shape[1]))
    for i in range(0, lhs.shape[0], step):
        np.matmul(lhs[i : i + step], rhs, out=out[i : i + step])


def point_segment_distance(p: FloatArray, a: FloatArray, b: FloatArray) -> FloatArray:
    """Distance from point ``p`` ``(2,)`` to each segment ``a``-``b`` ``(S, 2)``."""
    e = b - a
    w = p - a
    len2 = np.einsum("ij,ij->i", e, e)
    u = np.clip(np.einsum("ij,ij->i", w, e) / np.where(len2 > 0, len2, 1.0), 0.0, 1.0)
    q = a + u[:, None] * e
    return np.hypot(q[:, 0] - p[0], q[:, 1] - p[1])  # type: ignore[no-any-return]


class RayCaster:
    """First-hit ray casting from one origin, with reusable work buffers.

    Not thread-safe (the buffers are shared between calls); create one per thread.
    """

    def __init__(self) -> None:
        self._shape = (0, 0)
        self._prod = np.empty((0, 0))
        self._t = np.empty((0, 0))
        self._ok = np.empty((0, 0), dtype=np.bool_)
        self._tmp = np.empty((0, 0), dtype=np.bool_)

    def _buffers(self, n_beams: int, n_edges: int) -> None:
        if n_beams > self._shape[0] or n_edges > self._shape[1]:
            b = max(n_beams, self._shape[0])
            s = max(n_edges, self._shape[1], 16)
            self._shape = (b, s)
            self._prod = np.empty((b, 2 * s))
            self._t = np.empty((b, s))
            self._ok = np.empty((b, s), dtype=np.bool_)
            self._tmp = np.empty((b, s), dtype=np.bool_)

    def cast_snapshot(
        self,
        origin: FloatArray,
        dirs: FloatArray,
        a: FloatArray,
        b: FloatArray,
        max_range_m: float,
    ) -> tuple[FloatArray, IntArray]:
        """Range of the first hit of each ray and the index of the edge it hit.

        ``origin`` ``(2,)``; ``dirs`` ``(B, 2)`` unit vectors; ``a``, ``b`` ``(S, 2)`` the edges
        (start, end) of CCW polygons, the origin outside all of them. Returns ranges ``(B,)``
        (``inf`` where nothing lies within ``max_range_m``) and edge indices (``NO_HIT``).

        Why culling is exact: on edge ``s`` the ray's crossing satisfies
        ``(w x e) = t (d x e)``. Entering a CCW polygon means moving to the edge's left,
        ``e x d > 0``, i.e. ``d x e < 0``; with ``t > 0`` that forces ``w x e < 0``.
        """
        n_beams = dirs.shape[0]
        w = a - origin
        e = b - a
        cwe = w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]
        keep = cwe < 0.0
        keep &= point_segment_distance(origin, a, b) <= max_range_m
        idx = np.flatnonzero(keep)
        s = idx.size
        ranges = np.full(n_beams, np.inf)
        hit = np.full(n_beams, NO_HIT, dtype=np.int64)
        if s == 0:
            return ranges, hit
        self._buffers(n_beams, s)
        we, ee, cw = w[idx], e[idx], cwe[idx]
        m = np.empty((2, 2 * s))
        m[0, :s] = ee[:, 1]
        m[1, :s] = -ee[:, 0]
        m[0, s:] = -we[:, 1]
        m[1, s:] = we[:, 0]
        prod = self._prod[:n_beams, : 2 * s]
        _matmul_rows(dirs, m, prod)
        den = prod[:, :s]  # d x e
        num_u = prod[:, s:]  # w x d;  u = num_u / den
        return self._nearest(den, num_u, cw, idx, max_range_m, per_pair_facing=False)

    def cast_moving_origin(
        self,
        origins: FloatArray,
        dirs: FloatArray,
        a: FloatArray,
        b: FloatArray,
        max_range_m: float,
    ) -> tuple[FloatArray, IntArray]:
        """First hits when each beam has its own origin but the edges are shared (static
        structure seen from a scanner that moves during the scan).

        Same contract as :meth:`cast_snapshot` with ``origins`` ``(B, 2)``. The cross products
        are again matrix products: ``d x e`` and ``o x e`` come from ``[d; o] @ [e_y; -e_x]``
        and ``a x d`` from ``d @ [-a_y; a_x]``. Back-facing edges are culled per (beam, edge)
        pair, and edges that face away from every origin of the scan are dropped up front
        (the origins lie on a short, nearly straight path, so the test is made at its two
        ends and middle with a 0.01 m allowance for the path's curvature).
        """
        n_beams = dirs.shape[0]
        e = b - a
        axe = a[:, 0] * e[:, 1] - a[:, 1] * e[:, 0]
        probe = origins[[0, n_beams // 2, n_beams - 1]]
        cwe_probe = axe[None, :] - (probe[:, 0:1] * e[None, :, 1] - probe[:, 1:2] * e[None, :, 0])
        elen = np.hypot(e[:, 0], e[:, 1])
        keep = (cwe_probe < 0.01 * elen[None, :]).any(axis=0)
        travel = float(np.hypot(*(origins[-1] - origins[0]))) + 0.01
        keep &= point_segment_distance(origins[n_beams // 2], a, b) <= max_range_m + travel
        idx = np.flatnonzero(keep)
        s = idx.size
        ranges = np.full(n_beams, np.inf)
        hit = np.full(n_beams, NO_HIT, dtype=np.int64)
        if s == 0:
            return ranges, hit
        self._buffers(2 * n_beams, s)
        ak, ek, axk = a[idx], e[idx], axe[idx]
        m = np.empty((2, 2 * s))
        m[0, :s] = ek[:, 1]
        m[1, :s] = -ek[:, 0]
        m[0, s:] = -ak[:, 1]
        m[1, s:] = ak[:, 0]
        prod = self._prod[: 2 * n_beams, : 2 * s]
        _matmul_rows(np.concatenate([dirs, origins], axis=0), m, prod)
        den = prod[:n_beams, :s]  # d x e
        cwe = prod[n_beams:, :s]  # o x e  ->  w x e = a x e - o x e
        np.subtract(axk, cwe, out=cwe)
        cwd = prod[:n_beams, s:]  # a x d  ->  w x d = a x d - o x d
        oxd = origins[:, 0] * dirs[:, 1] - origins[:, 1] * dirs[:, 0]
        np.subtract(cwd, oxd[:, None], out=cwd)
        return self._nearest(den, cwd, cwe, idx, max_range_m, per_pair_facing=True)

    def _nearest(
        self,
        den: FloatArray,
        num_u: FloatArray,
        cwe: FloatArray,
        idx: IntArray,
        max_range_m: float,
        *,
        per_pair_facing: bool,
    ) -> tuple[FloatArray, IntArray]:
        """The nearest entering crossing of each beam from the cross products ``d x e``
        ``(B, S)``, ``w x d`` ``(B, S)`` and ``w x e`` (``(S,)`` or ``(B, S)``); ``idx`` maps the
        ``S`` columns to edge indices. ``per_pair_facing`` also requires ``w x e < 0`` per
        pair (edges not culled up front)."""
        n_beams, s = den.shape
        ok = self._ok[:n_beams, :s]
        tmp = self._tmp[:n_beams, :s]
        t = self._t[:n_beams, :s]
        # den < 0 (entering) and 0 <= u <= 1  <=>  den <= num_u <= 0 with den < 0.
        np.less(den, 0.0, out=ok)
        if per_pair_facing:
            np.less(cwe, 0.0, out=tmp)
            np.logical_and(ok, tmp, out=ok)
        np.less_equal(num_u, _TOUCH, out=tmp)
        np.logical_and(ok, tmp, out=ok)
        np.subtract(den, _TOUCH, out=t)
        np.greater_equal(num_u, t, out=tmp)
        np.logical_and(ok, tmp, out=ok)
        t.fill(np.inf)
        np.divide(cwe, den, out=t, where=ok)
        best = np.argmin(t, axis=1)
        ranges = t[np.arange(n_beams), best]
        inside = ranges <= max_range_m
        ranges[~inside] = np.inf
        hit = np.full(n_beams, NO_HIT, dtype=np.int64)
        hit[inside] = idx[best[inside]]
        return ranges, hit


def cast_per_beam(
    origins: FloatArray,
    dirs: FloatArray,
    a: FloatArray,
    b: FloatArray,
    max_range_m: float,
) -> tuple[FloatArray, IntArray]:
    """First hits when every beam has its own origin and edges (time-skewed scans).

    ``origins``, ``dirs`` ``(B, 2)``; ``a``, ``b`` ``(B, S, 2)`` (or ``(S, 2)``, shared). No
    orientation assumption: any crossing with ``t >= 0`` and ``0 <= u <= 1`` counts.
    """
    o = origins[:, None, :]
    d = dirs[:, None, :]
    w = a - o
    e = b - a
    den = d[..., 0] * e[..., 1] - d[..., 1] * e[..., 0]
    cwe = w[..., 0] * e[..., 1] - w[..., 1] * e[..., 0]
    cwd = w[..., 0] * d[..., 1] - w[..., 1] * d[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = cwe / den
        u = cwd / den
    tol = _TOUCH / np.maximum(np.abs(den), 1e-300)  # the same allowance, as a fraction of u
    ok: BoolArray = (den != 0) & (t >= 0) & (u >= -tol) & (u <= 1 + tol)
    t = np.where(ok, t, np.inf)
    best = np.argmin(t, axis=1)
    rows = np.arange(dirs.shape[0])
    ranges = t[rows, best]
    inside = ranges <= max_range_m
    ranges = np.where(inside, ranges, np.inf)
    hit = np.where(inside, best, NO_HIT).astype(np.int64)
    return ranges, hit
