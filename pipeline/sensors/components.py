"""Binary morphology and connected components of a mask, vectorised over runs (SR-FUS-5).

:func:`opening` is the morphological opening by a 3 x 3 square (erosion then dilation, the
outside of the image counting as background, as ``scipy.ndimage.binary_opening`` with that
structure). :func:`label_runs` labels the 8-connected components of a mask without a per-pixel
loop:

1. **runs**: each row's maximal horizontal runs of foreground, found from the differences of
   the zero-padded flat mask; in raster order;
2. **adjacency**: a run ``[s, e)`` in row ``r`` touches the runs of row ``r - 1`` that end at or
   after ``s`` (exclusive end) and start at or before ``e`` (8-connectivity); runs of a row are
   disjoint and sorted, so those form a contiguous index range found by two ``searchsorted``
   on keys ``row * (width + 2) + column``;
3. **union-find** on the run graph: every round hooks, for each edge, the larger of the two
   roots onto the smaller (``np.minimum.at``) and then jumps pointers until every run points
   at its root; rounds repeat until no edge joins two roots. Each round lowers at least one
   root, so it ends, and every root is the smallest run index of its component;
4. **numbering**: the components are numbered 1.. in the raster order of their first pixel (the
   start of their smallest run), which is ``scipy.ndimage.label``'s numbering.

:class:`Components` keeps the runs and their labels; per-component areas, bounding boxes and
the largest value of an image over each component follow from the runs alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.types import BoolArray, FloatArray, IntArray

__all__ = ["Components", "label_runs", "opening"]


def _erode(mask: BoolArray) -> BoolArray:
    """Erosion by a 3 x 3 square, outside = background (rows, then columns)."""
    rows = np.zeros_like(mask)
    rows[:, 1:-1] = mask[:, :-2] & mask[:, 1:-1] & mask[:, 2:]
    out = np.zeros_like(mask)
    out[1:-1] = rows[:-2] & rows[1:-1] & rows[2:]
    return out


def _dilate(mask: BoolArray) -> BoolArray:
    """Dilation by a 3 x 3 square (rows, then columns)."""
    rows = mask.copy()
    rows[:, 1:] |= mask[:, :-1]
    rows[:, :-1] |= mask[:, 1:]
    out: BoolArray = rows.copy()
    out[1:] |= rows[:-1]
    out[:-1] |= rows[1:]
    return out


def opening(mask: BoolArray) -> BoolArray:
    """Morphological opening by a 3 x 3 square: removes specks narrower than 3 pixels."""
    return _dilate(_erode(mask))


@dataclass(frozen=True, slots=True)
class Components:
    """The 8-connected components of a mask ``shape`` (module docstring).

    Runs in raster order: ``run_row``, ``run_start`` (first column) and ``run_end`` (one past the
    last); ``run_label`` the component (1..``n``) of each run.
    """

    shape: tuple[int, int]
    run_row: IntArray
    run_start: IntArray
    run_end: IntArray
    run_label: IntArray
    n: int

    def area_px(self) -> IntArray:
        """Pixels per component, ``(n,)``."""
        out: IntArray = np.bincount(
            self.run_label - 1, weights=self.run_end - self.run_start, minlength=self.n
        ).astype(np.int64)
        return out

    def boxes(self) -> tuple[IntArray, IntArray, IntArray, IntArray]:
        """Bounding boxes ``(row_min, row_max, col_min, col_max)`` (inclusive), each ``(n,)``."""
        lab = self.run_label - 1
        big = np.iinfo(np.int64).max
        row_min = np.full(self.n, big, dtype=np.int64)
        col_min = np.full(self.n, big, dtype=np.int64)
        row_max = np.full(self.n, -1, dtype=np.int64)
        col_max = np.full(self.n, -1, dtype=np.int64)
        np.minimum.at(row_min, lab, self.run_row)
        np.maximum.at(row_max, lab, self.run_row)
        np.minimum.at(col_min, lab, self.run_start)
        np.maximum.at(col_max, lab, self.run_end - 1)
        return row_min, row_max, col_min, col_max

    def maximum(self, image: npt.NDArray[np.floating]) -> FloatArray:
        """The largest value of ``image`` (same shape as the mask) over each component."""
        out = np.full(self.n, -np.inf)
        if self.n == 0:
            return out
        flat = image.reshape(-1)
        width = self.shape[1]
        starts = self.run_row * width + self.run_start
        bounds = np.empty(2 * starts.shape[0], dtype=np.int64)
        bounds[0::2] = starts
        bounds[1::2] = self.run_row * width + self.run_end
        if bounds[-1] == flat.shape[0]:
            bounds = bounds[:-1]  # the last run reaches the end: reduceat runs to the end
        per_run = np.maximum.reduceat(flat, bounds)[0::2].astype(np.float64)
        np.maximum.at(out, self.run_label - 1, per_run)
        return out

    def label_image(self) -> IntArray:
        """The labels as an image (0: background), for comparison with other labellings."""
        height, width = self.shape
        edges = np.zeros(height * width + 1, dtype=np.int64)
        base = self.run_row * width
        np.add.at(edges, base + self.run_start, self.run_label)
        np.add.at(edges, base + self.run_end, -self.run_label)
        out: IntArray = np.cumsum(edges[:-1]).reshape(height, width)
        return out


def _runs(mask: BoolArray) -> tuple[IntArray, IntArray, IntArray]:
    """Rows, starts and (exclusive) ends of the foreground runs, in raster order."""
    height, width = mask.shape
    padded = np.zeros((height, width + 2), dtype=np.int8)
    padded[:, 1:-1] = mask
    step = np.diff(padded.reshape(-1))
    rise = np.flatnonzero(step == 1)
    fall = np.flatnonzero(step == -1)
    # step[k] compares padded cells k and k + 1: a run starts in padded column (k + 1) % (w + 2),
    # which is image column k % (w + 2); it ends (exclusive) likewise.
    row = rise // (width + 2)
    return row, rise % (width + 2), fall % (width + 2)


def _edges(row: IntArray, start: IntArray, end: IntArray, width: int) -> tuple[IntArray, IntArray]:
    """Pairs (run in the row above, run below) that touch, 8-connectivity."""
    key = width + 2
    above = row - 1
    lo = np.searchsorted(row * key + end, above * key + start, side="left")
    hi = np.searchsorted(row * key + start, above * key + end, side="right")
    count = np.maximum(hi - lo, 0)
    total = int(count.sum())
    below = np.repeat(np.arange(row.shape[0]), count)
    offsets = np.repeat(np.cumsum(count) - count, count)
    upper = np.repeat(lo, count) + (np.arange(total) - offsets)
    return upper.astype(np.int64), below.astype(np.int64)


def _roots(n: int, a: IntArray, b: IntArray) -> IntArray:
    """Each run's root (smallest run index of its component): hooking and pointer jumping."""
    parent = np.arange(n, dtype=np.int64)
    while True:
        pa, pb = parent[a], parent[b]
        apart = pa != pb
        if not apart.any():
            return parent
        pa, pb = pa[apart], pb[apart]
        np.minimum.at(parent, np.maximum(pa, pb), np.minimum(pa, pb))
        while True:
            jumped = parent[parent]
            if np.array_equal(jumped, parent):
                break
            parent = jumped


def label_runs(mask: BoolArray) -> Components:
    """The 8-connected components of ``mask`` (module docstring)."""
    if mask.ndim != 2:
        raise ValueError(f"label_runs: the mask must be 2-D, got shape {mask.shape}")
    row, start, end = _runs(mask)
    upper, below = _edges(row, start, end, mask.shape[1])
    root = _roots(row.shape[0], upper, below)
    is_root = root == np.arange(root.shape[0])
    number = np.cumsum(is_root)  # roots in raster order of their first pixel: 1, 2, ...
    return Components(
        shape=(int(mask.shape[0]), int(mask.shape[1])),
        run_row=row.astype(np.int64),
        run_start=start.astype(np.int64),
        run_end=end.astype(np.int64),
        run_label=number[root].astype(np.int64),
        n=int(np.count_nonzero(is_root)),
    )
