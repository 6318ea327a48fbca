"""Evidence tables over the held-out rows: recall by band, by role, errors by role (SR-CLS-6).

Each function takes the rows' true and predicted class codes (and a grouping) and returns the
table's rows, ready for :meth:`evidence.record.Recorder.table`; cells are strings such as
``"93.1% of 812"`` so that a share always comes with the count it is a share of.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["accuracy_by_role", "accuracy_in_bands", "errors_by_role", "recall_cell"]


def recall_cell(predicted: np.ndarray, selection: np.ndarray, code: int) -> str:
    """``"93.1% of 812"``: the share of the selected rows predicted as ``code``, and their count;
    ``"-"`` when nothing is selected."""
    n = int(selection.sum())
    return f"{(predicted[selection] == code).mean():.1%} of {n}" if n else "-"


def accuracy_in_bands(
    label: np.ndarray,
    predicted: np.ndarray,
    classes: Mapping[str, int],
    value: np.ndarray,
    bands: Sequence[tuple[float, float]],
) -> list[list[object]]:
    """One table row per class of ``classes`` (name -> code): the name, then the recall among
    its rows whose ``value`` (range [m], box length [m], ...) lies in each ``[lo, hi)`` band."""
    out: list[list[object]] = []
    for name, code in classes.items():
        mine = label == code
        cells: list[object] = [name]
        for lo, hi in bands:
            cells.append(recall_cell(predicted, mine & (value >= lo) & (value < hi), code))
        out.append(cells)
    return out


def _role_codes(roles: Sequence[tuple[str, str]]) -> tuple[list[tuple[str, str]], np.ndarray]:
    order = sorted(set(roles))
    index = {role: k for k, role in enumerate(order)}
    return order, np.array([index[role] for role in roles], dtype=np.int64)


def accuracy_by_role(
    roles: Sequence[tuple[str, str]],
    label: np.ndarray,
    predicted: np.ndarray,
    classes: Mapping[str, int],
) -> list[list[object]]:
    """One table row per role (``(scenario, object)`` of each row) with rows of ``classes``
    (name -> class code): the scenario, the object, then per class its :func:`recall_cell`."""
    order, role_code = _role_codes(roles)
    out: list[list[object]] = []
    for k, (scenario, name) in enumerate(order):
        mine = role_code == k
        if not np.isin(label[mine], list(classes.values())).any():
            continue
        cells: list[object] = [scenario, name]
        cells += [recall_cell(predicted, mine & (label == code), code) for code in classes.values()]
        out.append(cells)
    return out


def errors_by_role(
    roles: Sequence[tuple[str, str]],
    error: np.ndarray,
    population: np.ndarray,
    predicted: np.ndarray,
    names: Sequence[str],
) -> list[list[object]]:
    """Where a kind of error comes from: one table row per role with at least one ``error``
    row, most errors first: the scenario, the object, ``"116 of 821"`` (its error rows of its
    ``population`` rows, e.g. safety-relevant errors of its near-reversal rows), and what those
    rows were predicted as (``names`` indexes the class codes), most frequent first."""
    order, role_code = _role_codes(roles)
    counts = np.bincount(role_code[error], minlength=len(order))
    totals = np.bincount(role_code[population], minlength=len(order))
    out: list[list[object]] = []
    for k in sorted(np.flatnonzero(counts), key=lambda j: (-counts[j], order[j])):
        as_what = Counter(names[int(c)] for c in predicted[error & (role_code == k)])
        cells: list[object] = [*order[k], f"{counts[k]} of {totals[k]}"]
        cells.append(", ".join(f"{name} {n}" for name, n in as_what.most_common()))
        out.append(cells)
    return out
