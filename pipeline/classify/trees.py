"""Fast evaluation of an XGBoost multi-class tree ensemble in vectorised numpy (SR-CLS-1).

The model is read from XGBoost's own JSON model file (``Booster.save_model("*.json")``), so
the run time needs no XGBoost; properties check the result against XGBoost's ``predict``.

Semantics reproduced exactly: inputs are cast to float32 (as XGBoost does); a node sends a row
left when ``x < threshold`` (float32 comparison) and a missing value (NaN) to its default child;
per class the margin starts at the model's base score and adds the tree leaves in tree order,
in float32, one tree at a time (XGBoost's CPU predictor does the same, so margins match bit for
bit); probabilities are the softmax of the margins.

Evaluation (trees with at most 64 leaves, e.g. depth 6) uses leaf bitmasks (the QuickScorer
idea, Lucchese et al., SIGIR 2015): number each tree's leaves left to right; a node whose test
fails (the row goes right) rules out the leaves of its left subtree. For every feature the
thresholds are sorted once, and for each position of a value among them the AND of the
ruled-out masks of every node it fails is precomputed per tree. A row then needs, per feature,
one binary search and one table row, an AND over the features, and the lowest set bit of each
tree's mask is its exit leaf: no per-node work at run time. The per-feature tables are stacked
into one array and every feature's thresholds into one sorted array of 64-bit keys (feature
index above an order-preserving image of the float32 bits), so one binary search serves all
features of all rows. The AND then takes one feature at a time (a gather of the batch's table
rows for that feature into a small buffer, and an AND into the masks): gathering every
feature's rows at once would write and read back rows x features x trees x 8 bytes (4.4 MB for
20 rows, 23 features and 1208 trees) per call: measured about 10 % slower back to back and
15-25 % slower when other work runs between calls (docs/findings/classification.md). Deeper trees
fall back to walking all trees level by level (:class:`TreeEnsemble` picks the path on load).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.errors import SafecaseError
from pipeline.types import FloatArray, IntArray

__all__ = ["ModelFormatError", "TreeEnsemble"]

U64 = npt.NDArray[np.uint64]
F32 = npt.NDArray[np.float32]
_ALL = np.uint64(0xFFFF_FFFF_FFFF_FFFF)
_MAX_BITMASK_LEAVES = 64
# Rows per pass: a pass's masks and gathered table rows are rows x trees x 8 bytes each
# (309 kB for 32 rows and 1208 trees), small enough to stay in a core's cache.
_CHUNK_ROWS = 32
_SIGN = np.uint64(0x8000_0000)
_LOW32 = np.uint64(0xFFFF_FFFF)


class ModelFormatError(SafecaseError, ValueError):
    """A model file that is not an XGBoost multi-class tree model this evaluator supports."""


@dataclass(frozen=True, slots=True)
class _Tree:
    left: IntArray
    right: IntArray
    feature: IntArray
    threshold: F32
    default_left: npt.NDArray[np.bool_]


def _param(model: dict[str, Any], *path: str) -> Any:
    node: Any = model
    for key in path:
        if not isinstance(node, dict) or key not in node:
            raise ModelFormatError(f"model JSON: missing {'/'.join(path)}")
        node = node[key]
    return node


def _in_order(tree: _Tree) -> tuple[IntArray, IntArray, IntArray]:
    """Leaf numbering left to right: ``(leaf_node (L,), first_leaf (N,), end_leaf (N,))``.

    ``first_leaf[n] .. end_leaf[n]`` are the leaf numbers under node ``n``.
    """
    n_nodes = tree.left.shape[0]
    first = np.zeros(n_nodes, dtype=np.int64)
    end = np.zeros(n_nodes, dtype=np.int64)
    leaves: list[int] = []
    stack: list[tuple[int, bool]] = [(0, False)]
    while stack:
        node, done = stack.pop()
        left = int(tree.left[node])
        if left < 0:
            first[node] = len(leaves)
            leaves.append(node)
            end[node] = len(leaves)
        elif done:
            first[node] = first[left]
            end[node] = end[int(tree.right[node])]
        else:
            stack.extend(((node, True), (int(tree.right[node]), False), (left, False)))
    return np.array(leaves, dtype=np.int64), first, end


class TreeEnsemble:
    """A parsed multi-class (``multi:softprob``) gradient-boosted tree model.

    ``n_features``, ``n_classes``, ``n_trees``; :meth:`margins` and :meth:`probabilities`
    take an (n, n_features) array (any float dtype; NaN = missing). ``bitmask`` tells which
    evaluation path is in use. Holds scratch buffers: not thread-safe, keep one per thread.
    """

    def __init__(self, model: dict[str, Any]) -> None:
        learner = _param(model, "learner")
        objective = _param(learner, "objective", "name")
        if objective != "multi:softprob":
            raise ModelFormatError(f"model objective {objective!r}; expected 'multi:softprob'")
        lmp = _param(learner, "learner_model_param")
        self.n_classes = int(lmp["num_class"])
        self.n_features = int(lmp["num_feature"])
        if int(lmp.get("num_target", "1")) != 1 or self.n_classes < 2:
            raise ModelFormatError("model: expected one target with at least 2 classes")
        base = np.asarray(json.loads(lmp["base_score"]), dtype=np.float32).reshape(-1)
        if base.shape == (1,):
            base = np.repeat(base, self.n_classes)
        if base.shape != (self.n_classes,):
            raise ModelFormatError(f"model: base_score {base.shape}, {self.n_classes} classes")
        booster = _param(learner, "gradient_booster")
        if booster.get("name") != "gbtree":
            raise ModelFormatError(f"booster {booster.get('name')!r}; expected 'gbtree'")
        raw_trees = _param(booster, "model", "trees")
        tree_class = np.asarray(_param(booster, "model", "tree_info"), dtype=np.int64)
        self.n_trees = len(raw_trees)
        if tree_class.shape != (self.n_trees,) or self.n_trees % self.n_classes:
            raise ModelFormatError("model: tree_info must give one class per tree, all rounds")
        rounds = self.n_trees // self.n_classes
        if not np.array_equal(tree_class, np.tile(np.arange(self.n_classes), rounds)):
            raise ModelFormatError("model: expected one tree per class per round, in class order")
        trees, leaf_values = [], []
        for raw in raw_trees:
            if any(int(t) != 0 for t in raw.get("split_type", [])) or raw.get("categories"):
                raise ModelFormatError("model: categorical splits are not supported")
            if int(raw["tree_param"].get("size_leaf_vector", "1")) > 1:
                raise ModelFormatError("model: vector leaves are not supported")
            cond = np.asarray(raw["split_conditions"], dtype=np.float32)
            tree = _Tree(
                left=np.asarray(raw["left_children"], dtype=np.int64),
                right=np.asarray(raw["right_children"], dtype=np.int64),
                feature=np.asarray(raw["split_indices"], dtype=np.int64),
                threshold=cond,
                default_left=np.asarray(raw["default_left"], dtype=np.bool_),
            )
            if tree.feature.max(initial=0) >= self.n_features:
                raise ModelFormatError("model: a split uses a feature beyond num_feature")
            trees.append(tree)
            leaf_values.append(np.where(tree.left < 0, cond, np.float32(0.0)))
        # The base score enters as one single-leaf tree per class ahead of round 0, so that the
        # per-class sums below start from it exactly as XGBoost's do.
        stumps = [
            _Tree(
                left=np.full(1, -1, dtype=np.int64),
                right=np.full(1, -1, dtype=np.int64),
                feature=np.zeros(1, dtype=np.int64),
                threshold=base[k : k + 1],
                default_left=np.ones(1, dtype=np.bool_),
            )
            for k in range(self.n_classes)
        ]
        trees = stumps + trees
        leaf_values = [t.threshold for t in stumps] + leaf_values
        self._rounds = rounds
        self._trees = trees
        self._n_columns = len(trees)
        self.max_leaves = max(int(np.count_nonzero(t.left < 0)) for t in trees)
        self.bitmask = self.max_leaves <= _MAX_BITMASK_LEAVES
        if self.bitmask:
            self._build_bitmask()
        else:
            self._build_walk(leaf_values)

    @classmethod
    def from_json(cls, data: bytes) -> TreeEnsemble:
        """Parse XGBoost's JSON model file content."""
        try:
            model = json.loads(data)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise ModelFormatError(f"model file is not JSON: {exc}") from None
        if not isinstance(model, dict):
            raise ModelFormatError("model file: expected a JSON object")
        return cls(model)

    # -- construction of the two evaluation paths -------------------------------------------
    def _build_bitmask(self) -> None:
        n_trees, n_feat = self._n_columns, self.n_features
        leaf_table = np.zeros((n_trees, _MAX_BITMASK_LEAVES), dtype=np.float32)
        per_feature: list[list[tuple[IntArray, F32, U64, npt.NDArray[np.bool_]]]] = [
            [] for _ in range(n_feat)
        ]
        bit = np.left_shift(np.uint64(1), np.arange(64, dtype=np.uint64))
        below = np.concatenate([[np.uint64(0)], np.cumsum(bit, dtype=np.uint64)])  # low k bits
        for t, tree in enumerate(self._trees):
            leaf_nodes, first, end = _in_order(tree)
            leaf_table[t, : leaf_nodes.shape[0]] = tree.threshold[leaf_nodes]
            inner = np.flatnonzero(tree.left >= 0)
            lf, le = first[tree.left[inner]], end[tree.left[inner]]
            # Failing the test rules out the left subtree's leaves lf..le-1.
            masks = ~(below[le] & ~below[lf])
            for f in np.unique(tree.feature[inner]):
                sel = tree.feature[inner] == f
                per_feature[int(f)].append(
                    (
                        np.full(int(sel.sum()), t, dtype=np.int64),
                        tree.threshold[inner[sel]],
                        masks[sel],
                        tree.default_left[inner[sel]],
                    )
                )
        thresholds: list[F32] = []
        tables: list[U64] = []
        for f in range(n_feat):
            if per_feature[f]:
                tt = np.concatenate([p[0] for p in per_feature[f]])
                th = np.concatenate([p[1] for p in per_feature[f]])
                mk = np.concatenate([p[2] for p in per_feature[f]])
                dl = np.concatenate([p[3] for p in per_feature[f]])
            else:
                tt = np.zeros(0, dtype=np.int64)
                th = np.zeros(0, dtype=np.float32)
                mk = np.zeros(0, dtype=np.uint64)
                dl = np.zeros(0, dtype=np.bool_)
            uniq = np.unique(th)
            # Row b: the x with exactly b thresholds <= x (searchsorted 'right'); a node fails
            # (x >= threshold) when its threshold's rank is < b. The last row is for NaN.
            table = np.full((uniq.shape[0] + 2, n_trees), _ALL, dtype=np.uint64)
            rank = np.searchsorted(uniq, th)
            np.bitwise_and.at(table, (rank + 1, tt), mk)
            table[:-1] = np.bitwise_and.accumulate(table[:-1], axis=0)
            table[-1] = _ALL
            np.bitwise_and.at(table[-1], tt[~dl], mk[~dl])
            thresholds.append(uniq)
            tables.append(table)
        self._stacked = np.concatenate(tables, axis=0)
        first_row = np.cumsum([0] + [t.shape[0] for t in tables])[:-1]
        n_thr = np.array([t.shape[0] for t in thresholds], dtype=np.intp)
        self._first_row = first_row.astype(np.intp)
        self._nan_row = (first_row + n_thr + 1).astype(np.intp)
        self._key_start = (np.cumsum(n_thr) - n_thr).astype(np.intp)
        self._feature_key = np.left_shift(np.arange(n_feat, dtype=np.uint64), np.uint64(32))
        self._keys = np.concatenate(
            [self._feature_key[f] | _sortable(th) for f, th in enumerate(thresholds)]
            + [np.zeros(0, dtype=np.uint64)]
        )
        self._leaf_flat = leaf_table.reshape(-1)
        self._tree_offset = np.arange(n_trees, dtype=np.intp) * _MAX_BITMASK_LEAVES
        shape = (_CHUNK_ROWS, n_trees)
        self._mask_buf = np.empty(shape, dtype=np.uint64)
        self._scratch_buf = np.empty(shape, dtype=np.uint64)
        self._count_buf = np.empty(shape, dtype=np.uint8)
        self._leaf_buf = np.empty(shape, dtype=np.intp)
        self._value_buf = np.empty(n_trees * _CHUNK_ROWS, dtype=np.float32)

    def _build_walk(self, leaf_values: list[F32]) -> None:
        width = max(t.left.shape[0] for t in self._trees)
        shape = (self._n_columns, width)
        self._w_left = np.zeros(shape, dtype=np.int64)
        self._w_right = np.zeros(shape, dtype=np.int64)
        self._w_feature = np.zeros(shape, dtype=np.int64)
        self._w_threshold = np.zeros(shape, dtype=np.float32)
        self._w_default_left = np.zeros(shape, dtype=np.bool_)
        self._w_leaf = np.zeros(shape, dtype=np.bool_)
        self._w_value = np.zeros(shape, dtype=np.float32)
        depth = 0
        for t, tree in enumerate(self._trees):
            k = tree.left.shape[0]
            leaf = tree.left < 0
            self._w_left[t, :k] = np.where(leaf, np.arange(k), tree.left)
            self._w_right[t, :k] = np.where(leaf, np.arange(k), tree.right)
            self._w_feature[t, :k] = np.where(leaf, 0, tree.feature)
            self._w_threshold[t, :k] = tree.threshold
            self._w_default_left[t, :k] = tree.default_left
            self._w_leaf[t, :k] = leaf
            self._w_value[t, :k] = leaf_values[t]
            depth = max(depth, _depth(tree))
        self._w_depth = depth

    # -- evaluation --------------------------------------------------------------------------
    def _leaf_values(self, x32: F32) -> F32:
        """(rounds + 1, n_classes, n): the leaf each row reaches in each tree, base first."""
        n = x32.shape[0]
        shape = (self._rounds + 1, self.n_classes, n)
        if self.bitmask:
            # Per-call temporaries of (rows, trees) are hundreds of kB: fresh ones would be
            # fresh mmap'd pages every call, so they live in buffers made once.
            mask = self._mask_buf[:n]
            scratch = self._scratch_buf[:n]
            # Row of each feature's table: the number of its thresholds <= x (a key search
            # over all features at once), or the NaN row.
            keys = self._feature_key | _sortable(x32)
            rank = np.searchsorted(self._keys, keys, side="right") - self._key_start
            rows = np.where(np.isnan(x32), self._nan_row, self._first_row + rank).T.copy()
            np.take(self._stacked, rows[0], axis=0, out=mask, mode="clip")
            for feature_rows in rows[1:]:
                np.take(self._stacked, feature_rows, axis=0, out=scratch, mode="clip")
                np.bitwise_and(mask, scratch, out=mask)
            # Exit leaf = index of the lowest set bit = number of zeros below it.
            np.subtract(mask, np.uint64(1), out=scratch)
            np.invert(mask, out=mask)
            np.bitwise_and(mask, scratch, out=mask)
            leaf = self._leaf_buf[:n]
            np.bitwise_count(mask, out=self._count_buf[:n])
            np.add(self._count_buf[:n], self._tree_offset, out=leaf)
            # Tree-major output, so the per-class sums below add whole contiguous planes.
            values = self._value_buf[: self._n_columns * n].reshape(self._n_columns, n)
            np.take(self._leaf_flat, leaf.T, out=values, mode="clip")
            out: F32 = values.reshape(shape)
            return out
        trees = np.arange(self._n_columns)[None, :]
        rows = np.arange(n)[:, None]
        node = np.zeros((n, self._n_columns), dtype=np.int64)
        for _ in range(self._w_depth):
            x = x32[rows, self._w_feature[trees, node]]
            go_left = np.where(
                np.isnan(x), self._w_default_left[trees, node], x < self._w_threshold[trees, node]
            )
            node = np.where(go_left, self._w_left[trees, node], self._w_right[trees, node])
        walked: F32 = np.ascontiguousarray(self._w_value[trees, node].T).reshape(shape)
        return walked

    def margins(self, x: npt.ArrayLike) -> F32:
        """Per-class margins (n, n_classes), float32, equal to XGBoost's ``output_margin``."""
        x32 = np.ascontiguousarray(x, dtype=np.float32)
        if x32.ndim != 2 or x32.shape[1] != self.n_features:
            raise ModelFormatError(
                f"classifier input has shape {x32.shape}; expected (n, {self.n_features})"
            )
        # Reducing the leading (tree) axis adds whole (class, row) planes one round after the
        # other (numpy sums pairwise only along the innermost axis): XGBoost's float32
        # sequence. Large batches go in chunks: the (rows, trees) scratch stays small.
        summed: F32 = np.empty((x32.shape[0], self.n_classes), dtype=np.float32)
        for start in range(0, x32.shape[0], _CHUNK_ROWS):
            part = x32[start : start + _CHUNK_ROWS]
            planes = np.add.reduce(self._leaf_values(part), axis=0, dtype=np.float32)
            summed[start : start + part.shape[0]] = planes.T
        return summed

    def probabilities(self, x: npt.ArrayLike) -> FloatArray:
        """Class probabilities (n, n_classes): the softmax of :meth:`margins`, float64."""
        margin = self.margins(x).astype(np.float64)
        margin -= margin.max(axis=1, keepdims=True)
        np.exp(margin, out=margin)
        margin /= margin.sum(axis=1, keepdims=True)
        return margin


def _sortable(values: F32) -> U64:
    """Order-preserving uint64 image of float32 values (NaN excluded): ``a < b`` as floats
    exactly when ``image(a) < image(b)``, with -0.0 taken as 0.0 (they compare equal)."""
    bits = (np.asarray(values, dtype=np.float32) + np.float32(0.0)).view(np.uint32)
    wide = bits.astype(np.uint64)
    negative = wide >= _SIGN
    image: U64 = np.where(negative, ~wide & _LOW32, wide | _SIGN)
    return image


def _depth(tree: _Tree) -> int:
    """Number of edges on the longest root-to-leaf path."""
    deepest = 0
    stack = [(0, 0)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        if tree.left[node] >= 0:
            stack.extend(((int(tree.left[node]), depth + 1), (int(tree.right[node]), depth + 1)))
    return deepest
