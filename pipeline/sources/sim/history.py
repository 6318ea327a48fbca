"""Bounded records of a long run: evenly thinned rows and windowed interpolation (SR-RUN-5).

:class:`ThinnedRows` keeps at most ``capacity`` rows of an unbounded stream of rows: every
``stride``-th row is kept, and when the buffer is full every other kept row is dropped and
the stride doubles, so the kept rows stay evenly spaced over the whole stream (a run of any
length is kept at ``capacity / 2`` to ``capacity`` rows). A few rows may be *pinned* (kept
whatever the stride: the steps a verdict is read from), and the newest row is always kept.
Memory is ``O(capacity + pinned)``, each append ``O(1)`` amortised.

:func:`interp_window` is :func:`numpy.interp` over only the grid points that bracket the query
times. It returns the same bits as interpolating over the whole grid (the same bracketing pair
and the same arithmetic), but costs ``O(T log n)`` instead of ``O(n)``: :func:`numpy.interp`
copies a read-only grid in full on every call, which on a whole-run trajectory (one sample per
5 ms) made every lookup grow with the run's length.
"""

from __future__ import annotations

import numpy as np

from pipeline.types import FloatArray, IntArray

__all__ = ["ThinnedRows", "grid_window", "interp_window"]


class ThinnedRows:
    """At most ``capacity`` evenly spaced rows of ``width`` floats, plus pinned rows and the
    newest one (module docstring). Rows are numbered from 0 in the order appended."""

    def __init__(self, width: int, capacity: int) -> None:
        if width < 1 or capacity < 2 or capacity % 2:
            raise ValueError(
                f"ThinnedRows: need width >= 1 and an even capacity >= 2, got {width}, {capacity}"
            )
        self.width = width
        self.capacity = capacity
        self._rows = np.empty((capacity, width))
        self._index = np.empty(capacity, dtype=np.int64)
        self._n = 0
        self._stride = 1
        self._seen = 0
        self._pinned: dict[int, FloatArray] = {}
        self._pin_next: set[int] = set()
        self._last: tuple[int, FloatArray] | None = None

    @property
    def seen(self) -> int:
        """How many rows were appended."""
        return self._seen

    @property
    def stride(self) -> int:
        """Every how many rows one is kept now."""
        return self._stride

    def pin(self, index: int) -> None:
        """Keep row ``index`` whatever the stride (it may be appended later or already be)."""
        if index < 0:
            raise ValueError(f"ThinnedRows.pin: row {index} < 0")
        if index >= self._seen:
            self._pin_next.add(index)
            return
        if index in self._pinned:
            return
        if self._last is not None and self._last[0] == index:
            self._pinned[index] = self._last[1]
            return
        pos = int(np.searchsorted(self._index[: self._n], index))
        if pos < self._n and self._index[pos] == index:
            self._pinned[index] = self._rows[pos].copy()
            return
        raise ValueError(f"ThinnedRows.pin: row {index} is gone (stride {self._stride})")

    def append(self, row: FloatArray) -> None:
        """Add the next row (``width`` floats)."""
        values = np.array(row, dtype=np.float64).reshape(self.width)
        index = self._seen
        self._seen += 1
        self._last = (index, values)
        if index in self._pin_next:
            self._pin_next.discard(index)
            self._pinned[index] = values
        if index % self._stride:
            return
        if self._n == self.capacity:
            # Full: keep every other row (those at multiples of twice the stride).
            half = self.capacity // 2
            self._rows[:half] = self._rows[0 : self.capacity : 2]
            self._index[:half] = self._index[0 : self.capacity : 2]
            self._n = half
            self._stride *= 2
            if index % self._stride:
                return
        self._rows[self._n] = values
        self._index[self._n] = index
        self._n += 1

    def rows(self) -> tuple[IntArray, FloatArray]:
        """Row numbers ``(K,)`` and rows ``(K, width)``: the kept, the pinned and the newest,
        in order, each once."""
        index = [self._index[: self._n]]
        rows = [self._rows[: self._n]]
        extra = dict(self._pinned)
        if self._last is not None:
            extra[self._last[0]] = self._last[1]
        if extra:
            keys = np.array(sorted(extra), dtype=np.int64)
            index.append(keys)
            rows.append(np.stack([extra[int(k)] for k in keys]))
        all_index = np.concatenate(index)
        all_rows = np.concatenate(rows).reshape(-1, self.width)
        order = np.argsort(all_index, kind="stable")
        all_index, all_rows = all_index[order], all_rows[order]
        first = np.ones(all_index.size, dtype=np.bool_)
        first[1:] = all_index[1:] != all_index[:-1]
        out_index: IntArray = all_index[first]
        out_rows: FloatArray = all_rows[first]
        return out_index, out_rows


def grid_window(grid: FloatArray, t_s: FloatArray) -> tuple[int, int]:
    """The slice ``[lo, hi)`` of the ascending ``grid`` that holds, for every query time, the
    grid point at or before it and the one after it (the whole grid for non-finite queries
    or none)."""
    if t_s.size == 0 or not np.isfinite(t_s).all():
        return 0, grid.shape[0]
    lo = int(np.searchsorted(grid, t_s.min(), side="right")) - 1
    hi = int(np.searchsorted(grid, t_s.max(), side="right")) + 1
    return max(lo, 0), min(hi, grid.shape[0])


def interp_window(t_s: FloatArray, grid: FloatArray, values: FloatArray) -> FloatArray:
    """``numpy.interp(t_s, grid, values)`` bit for bit, over the bracketing window only."""
    lo, hi = grid_window(grid, t_s)
    out: FloatArray = np.interp(t_s, grid[lo:hi], values[lo:hi])
    return out
