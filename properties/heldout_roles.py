"""Held-out rows by scenario and object role: where the classifier's errors come from (SR-CLS-6).

The per-class accuracy alone hides which situations the errors come from. Splitting the rows by
the scenario and the object they follow shows it. For example, the reversal drill's
cross-aisle forklift shuttles across the main aisle 24-27 m ahead, and the robot sees it
through the 3.5 m gap between the rack rows. A truck longer than the gap fills it whether it
moves or not, so its cluster's centroid hardly moves and its motion state cannot be seen.

Named scenarios and the drill place the same objects under the same ids whatever the seed
(their builders fix them), so one world per scenario names them. ``random_encounter`` draws
its objects per seed; its rows are one group.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from pipeline.classify_data import Rows, simulation_of
from pipeline.config import SafecaseConfig

__all__ = ["DRAWN", "accuracy_by_role", "recall_cell", "row_roles"]

DRAWN = "(objects drawn per seed)"


def row_roles(rows: Rows, config: SafecaseConfig) -> list[tuple[str, str]]:
    """``(scenario, object name)`` of every row of ``rows`` (module docstring)."""
    names: dict[str, dict[int, str]] = {}
    for spec in rows.runs:
        if spec.scenario not in names and spec.scenario != "random_encounter":
            world = simulation_of(config, spec).world
            names[spec.scenario] = {o.object_id: o.name for o in world.objects}
    out = []
    for run, object_id in zip(rows.run.tolist(), rows.object_id.tolist(), strict=True):
        scenario = rows.runs[run].scenario
        if scenario == "random_encounter":
            out.append((scenario, DRAWN))
        else:
            out.append((scenario, names[scenario].get(object_id, f"object {object_id}")))
    return out


def recall_cell(predicted: np.ndarray, selection: np.ndarray, code: int) -> str:
    """``"93.1% of 812"``: the share of the selected rows predicted as ``code``, and their count;
    ``"-"`` when nothing is selected."""
    n = int(selection.sum())
    return f"{(predicted[selection] == code).mean():.1%} of {n}" if n else "-"


def accuracy_by_role(
    roles: list[tuple[str, str]],
    label: np.ndarray,
    predicted: np.ndarray,
    classes: Mapping[str, int],
) -> list[list[object]]:
    """One table row per role with rows of ``classes`` (name -> class code): the scenario, the
    object, then per class its :func:`recall_cell`."""
    order = sorted(set(roles))
    index = {role: k for k, role in enumerate(order)}
    role_code = np.array([index[role] for role in roles], dtype=np.int64)
    out: list[list[object]] = []
    for k, (scenario, name) in enumerate(order):
        mine = role_code == k
        if not np.isin(label[mine], list(classes.values())).any():
            continue
        cells: list[object] = [scenario, name]
        cells += [recall_cell(predicted, mine & (label == code), code) for code in classes.values()]
        out.append(cells)
    return out
