"""Evidence tables over the held-out rows (SR-CLS-6 evidence helpers)."""

from __future__ import annotations

import numpy as np

from properties.heldout_tables import accuracy_by_role, accuracy_in_bands, errors_by_role


def test_accuracy_by_role_counts_each_class_within_each_role() -> None:
    roles = [("a", "x"), ("a", "x"), ("a", "x"), ("b", "y"), ("b", "z")]
    label = np.array([0, 0, 1, 0, 5])
    predicted = np.array([0, 1, 1, 2, 5])
    table = accuracy_by_role(roles, label, predicted, {"m": 0, "s": 1})
    # Role ("b", "z") has only class 5 rows, which the table does not show: no line for it.
    assert table == [["a", "x", "50.0% of 2", "100.0% of 1"], ["b", "y", "0.0% of 1", "-"]]


def test_accuracy_in_bands_splits_each_class_by_half_open_bands() -> None:
    label = np.array([0, 0, 0, 0, 1, 1])
    predicted = np.array([0, 1, 0, 0, 1, 0])
    value = np.array([1.0, 4.9, 5.0, 12.0, 5.0, 30.0])
    bands = [(0.0, 5.0), (5.0, 10.0), (10.0, np.inf)]
    table = accuracy_in_bands(label, predicted, {"m": 0, "s": 1}, value, bands)
    # 5.0 opens the second band; class 1 has no row under 5 m.
    assert table == [
        ["m", "50.0% of 2", "100.0% of 1", "100.0% of 1"],
        ["s", "-", "100.0% of 1", "0.0% of 1"],
    ]


def test_errors_by_role_lists_roles_with_errors_most_first_and_what_they_became() -> None:
    roles = [("d", "cross")] * 4 + [("d", "aisle")] * 3 + [("r", "drawn")] * 2
    population = np.array([1, 1, 1, 0, 1, 1, 1, 1, 1], dtype=bool)
    error = np.array([1, 1, 1, 0, 1, 0, 0, 0, 0], dtype=bool)
    predicted = np.array([0, 2, 2, 0, 1, 2, 2, 2, 2])
    table = errors_by_role(roles, error, population, predicted, ["moving", "stationary", "near"])
    # ("r", "drawn") has no error row: no line for it.
    assert table == [
        ["d", "cross", "3 of 3", "near 2, moving 1"],
        ["d", "aisle", "1 of 3", "stationary 1"],
    ]
