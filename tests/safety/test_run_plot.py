"""The picture of one closed-loop run (SR-RUN-1, SR-AVL-1), read from the figure's artists:
what is drawn, from which series, in which colour, with which label."""

from __future__ import annotations

from collections import Counter
from dataclasses import replace

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_rgb
from matplotlib.figure import Figure

from pipeline.config import SafecaseConfig
from pipeline.sources.sim.ego import ConstantSpeed
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import SimResult
from properties.figures import in_upper_right
from safety.run import RunSummary, contact_speeds
from safety.run_plot import run_figure

CODE = ["safety/run_plot.py"]


def _driven(config: SafecaseConfig, name: str, speed_mps: float) -> SimResult:
    return make_simulation(config, name, 0, 8.0).run(ConstantSpeed(speed_mps))


def _summary(sim: SimResult) -> RunSummary:
    return RunSummary(sim.name, cycles=5, actions=Counter({"STOP": 2, "PROCEED": 3}), sim=sim)


def _xy(line: object) -> tuple[list[float], list[float]]:
    return (
        np.asarray(line.get_xdata()).tolist(),  # type: ignore[attr-defined]
        np.asarray(line.get_ydata()).tolist(),  # type: ignore[attr-defined]
    )


def _legend(ax: Axes) -> list[str]:
    legend = ax.get_legend()
    assert legend is not None
    return [t.get_text() for t in legend.get_texts()]


def _shaded(fig: Figure) -> PolyCollection:
    (fill,) = [c for c in fig.axes[0].collections if isinstance(c, PolyCollection)]
    return fill


def _spans(fig: Figure) -> list[tuple[float, float]]:
    """The time spans shaded in the speed panel, each over the panel's full height."""
    spans = []
    for path in _shaded(fig).get_paths():
        xy = np.asarray(path.vertices, dtype=np.float64)
        assert (xy[:, 1].min(), xy[:, 1].max()) == (0.0, 1.0)
        spans.append((float(xy[:, 0].min()), float(xy[:, 0].max())))
    return spans


def _stopped(sim: SimResult) -> list[tuple[float, float]]:
    """From the log: each run of samples with a zero command, its first and last time."""
    t, stopped = sim.ego_log["t_s"], sim.ego_log["command_mps"] == 0.0
    spans, start = [], None
    for i, s in enumerate(stopped):
        if s and start is None:
            start = i
        if start is not None and (not s or i == len(t) - 1):
            spans.append((float(t[start]), float(t[i if s else i - 1])))
            start = None
    return spans


def test_a_run_without_a_simulation_is_refused() -> None:
    with pytest.raises(ValueError) as refused:
        run_figure(RunSummary("log"))
    assert str(refused.value) == "run_figure: the run has no simulation result"


@pytest.mark.requirement("SR-RUN-1", kind="example", code=CODE)
def test_the_speeds_the_separations_and_the_contact_are_drawn_from_the_run(
    safecase_config: SafecaseConfig,
) -> None:
    sim = _driven(safecase_config, "reversing_forklift_aisle", 1.0)
    log = sim.ego_log
    fig = run_figure(_summary(sim))
    top, bottom = fig.axes
    command, speed = top.get_lines()
    assert _xy(command) == (log["t_s"].tolist(), log["command_mps"].tolist())
    assert (command.get_drawstyle(), command.get_color(), command.get_label()) == (
        "steps-post",
        "tab:orange",
        "command",
    )
    assert _xy(speed) == (log["t_s"].tolist(), log["speed_mps"].tolist())
    assert (speed.get_color(), speed.get_label()) == ("tab:blue", "robot speed")
    assert top.get_title() == "reversing_forklift_aisle seed 0: 5 cycles, PROCEED 3, STOP 2"
    assert top.get_ylabel() == "m/s"
    assert _legend(top) == [
        "command",
        "robot speed",
        "STOP in force",
    ]
    # Driving at a constant 1 m/s the command drops to zero only after the contact.
    assert _shaded(fig).get_label() == "STOP in force"
    assert _spans(fig) == _stopped(sim) == [(6.42, 6.5)]
    assert _shaded(fig).get_alpha() == 0.12
    separations = bottom.get_lines()[: len(sim.world.objects)]
    assert [s.get_label() for s in separations] == ["forklift", "reach_truck_parked", "walker"]
    for i, line in enumerate(separations):
        assert _xy(line) == (sim.separation_t_s.tolist(), sim.separation_m[:, i].tolist())
    # The forklift is hit at 6.41 s with the robot at its 1 m/s.
    (contact,) = bottom.get_lines()[len(sim.world.objects) :]
    assert _xy(contact)[0] == [6.41, 6.41]
    assert (contact.get_color(), contact.get_linestyle()) == ("red", "--")
    (note,) = bottom.texts
    assert note.get_text() == f"contact at {contact_speeds(sim)[0]:.2f} m/s"
    assert note.get_text() == "contact at 1.00 m/s"
    assert note.xy == (6.41, 0)  # type: ignore[attr-defined]
    assert bottom.get_ylim()[0] == 0.0
    assert (bottom.get_ylabel(), bottom.get_xlabel()) == ("separation [m]", "time [s]")
    assert _legend(bottom) == [
        "forklift",
        "reach_truck_parked",
        "walker",
    ]


@pytest.mark.requirement("SR-AVL-1", kind="example", code=CODE)
def test_other_runs_and_nuisance_stops_are_drawn_beside_ours(
    safecase_config: SafecaseConfig,
) -> None:
    ours = _driven(safecase_config, "crossing_pedestrian", 0.0)
    oracle = _driven(safecase_config, "crossing_pedestrian", 0.5)
    baseline = _driven(safecase_config, "crossing_pedestrian", 0.3)
    fig = run_figure(
        _summary(ours),
        {"oracle": oracle, "baseline": baseline, "mine": oracle},
        nuisance_t_s=(0.5, 1.5),
    )
    top, bottom = fig.axes
    command, speed, seen_oracle, seen_baseline, seen_mine, marks = top.get_lines()
    # Braking from its start at 1 m/s, the robot's speed is not its command.
    log = ours.ego_log
    assert _xy(command) == (log["t_s"].tolist(), log["command_mps"].tolist())
    assert _xy(speed) == (log["t_s"].tolist(), log["speed_mps"].tolist())
    assert log["speed_mps"][20] > 0.5
    for line, run, colour, label in (
        (seen_oracle, oracle, "tab:green", "oracle speed"),
        (seen_baseline, baseline, "tab:purple", "baseline speed"),
        (seen_mine, oracle, "tab:gray", "mine speed"),
    ):
        assert _xy(line) == (run.ego_log["t_s"].tolist(), run.ego_log["speed_mps"].tolist())
        assert (line.get_color(), line.get_label(), line.get_linewidth()) == (colour, label, 1.2)
    assert _xy(marks) == ([0.5, 1.5], [1.02, 1.02])
    assert (marks.get_marker(), marks.get_color(), marks.get_label()) == (
        "v",
        "tab:red",
        "nuisance STOP",
    )
    assert marks.get_linestyle() == "None"
    assert marks.get_clip_on() is False
    # Standing still from the first command on: the shade spans the rest of the run.
    assert _spans(fig) == _stopped(ours) == [(0.16, 8.0)]
    assert len(bottom.texts) == 0  # no contact


def test_a_run_without_objects_has_no_separation_legend(safecase_config: SafecaseConfig) -> None:
    sim = _driven(safecase_config, "crossing_pedestrian", 0.0)
    empty = replace(
        sim,
        world=replace(sim.world, objects=()),
        contact_time_s=sim.contact_time_s[:0],
        separation_m=sim.separation_m[:, :0],
    )
    bottom = run_figure(_summary(empty)).axes[1]
    assert bottom.get_legend() is None
    assert bottom.get_lines() == []


@pytest.mark.requirement("SR-RUN-1", kind="example", code=CODE)
def test_the_figure_is_laid_out_for_reading(safecase_config: SafecaseConfig) -> None:
    """What a reader of docs/ sees beyond the series: the size, one time axis for both panels,
    the marks and the shading placed on the speed panel's height (not on its speeds), the
    legends in the upper right corner in small type, the contact drawn thin and noted in red."""
    sim = _driven(safecase_config, "reversing_forklift_aisle", 1.0)
    fig = run_figure(_summary(sim), nuisance_t_s=(1.0,))
    top, bottom = fig.axes
    assert tuple(fig.get_size_inches()) == (10.0, 6.5)
    assert top.get_shared_x_axes().joined(top, bottom)
    marks = top.get_lines()[2]
    assert marks.get_markersize() == 4
    assert marks.get_transform() is top.get_xaxis_transform()
    shade = _shaded(fig)
    assert shade.get_transform() is top.get_xaxis_transform()
    face = np.asarray(shade.get_facecolor(), dtype=np.float64)
    assert face[0].tolist() == pytest.approx([*to_rgb("tab:red"), 0.12])
    # Standing, the separations leave the lower middle free, where matplotlib's "best" place
    # would put the legend.
    standing = run_figure(_summary(_driven(safecase_config, "reversing_forklift_aisle", 0.0)))
    for figure in (fig, standing):
        figure.canvas.draw()
        for ax in figure.axes:
            legend = ax.get_legend()
            assert legend is not None
            assert {text.get_fontsize() for text in legend.get_texts()} == {8.0}
            assert in_upper_right(ax)
    (contact,) = bottom.get_lines()[len(sim.world.objects) :]
    assert contact.get_linewidth() == 1
    (note,) = bottom.texts
    assert (note.get_color(), note.get_fontsize()) == ("red", 8.0)
