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

from pipeline.config import SafecaseConfig
from pipeline.training.data import Rows, simulation_of

__all__ = ["DRAWN", "row_roles"]

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
