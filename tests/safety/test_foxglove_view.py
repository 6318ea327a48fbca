"""A recording read back by :mod:`safety.foxglove_view` (SR-RUN-7): the cycles' stamps, the
cycle nearest a time (or the last), the records, the picture of one cycle read from the
figure's artists (positions worked out by hand in the odom frame, colours, sizes, labels,
layers, title, limits), and the comparison with the audit log of a short simulated run, with
every kind of disagreement it reports and its exact text."""

from __future__ import annotations

import copy
import json
import math
import shutil
from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.markers import MarkerStyle
from matplotlib.patches import Circle
from matplotlib.text import Annotation

from pipeline.config import default_config
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.source import SimSource
from pipeline.types import Action, Scan
from properties.cycle_scenes import empty_scene
from safety.audit.log import anchor_path
from safety.audit.verify import verify_log
from safety.foxglove import TOPICS, McapRecorder
from safety.foxglove_scene import CycleScene
from safety.foxglove_view import (
    compare_with_audit,
    cycle_figure,
    cycle_stamps,
    read_cycle,
    read_records,
)
from safety.run import run_audited

CODE = ["safety/foxglove_view.py"]


def _f(values: Sequence[Sequence[float]] | Sequence[float]) -> np.ndarray[Any, Any]:
    return np.array(values, dtype=np.float64)


def _i(values: Sequence[int]) -> np.ndarray[Any, Any]:
    return np.array(values, dtype=np.int64)


def _grid() -> np.ndarray[Any, np.dtype[np.bool_]]:
    """3 x 4 cells, marked at two opposite corners, so the crop keeps it whole."""
    grid = np.zeros((3, 4), dtype=np.bool_)
    grid[0, 0] = grid[2, 3] = True
    return grid


# The robot at (2, 1) facing +y (a quarter turn): a point (x, y) of base_link is at
# (2 - y, 1 + x) in odom. The scanner sits 0.5 m ahead of it, turned a further quarter: at
# (2, 1.5) in odom facing -x, so a return at range r and angle a is at
# (2 - r cos a, 1.5 - r sin a).
DRAWN = CycleScene(
    stamp_s=3.25,
    robot_pose=(2.0, 1.0, math.pi / 2),
    mount=(0.5, 0.0, math.pi / 2),
    scan=Scan(
        stamp_s=3.2,
        angles_rad=_f([0.0, 0.5, 1.0]),
        ranges_m=_f([1.0, np.nan, 2.0]),
        beam_period_s=0.001,
    ),
    points_xy_m=_f([[1.0, 0.0, 2.0], [0.0, 1.0, 2.0]]),
    point_labels=_i([0, -1, 3]),
    track_id=_i([5, 6]),
    track_xy_m=_f([[3.0, -1.0], [4.0, -2.0]]),
    track_v_mps=_f([[1.0, 0.0], [0.0, -0.5]]),
    track_radius_m=_f([0.5, 0.25]),
    track_class=("person", ""),
    envelopes=(
        _f([[1.0, 0.0], [2.0, 0.0], [2.0, 1.0]]),
        _f([[0.0, 1.0], [1.0, 1.0], [0.0, 2.0]]),
        _f([[-1.0, -1.0], [0.0, -1.0], [0.0, 0.0]]),
        _f([[3.0, 3.0], [4.0, 3.0], [4.0, 4.0]]),
    ),
    envelope_tier=_i([0, 1, 2, 4]),
    envelope_track=_i([5, 6, 5, 6]),
    path_xy_m=_f([[2.0, 1.0], [2.0, 2.0], [2.0, 3.0]]),
    occupied=_grid(),
    costmap_origin_m=(1.0, -1.0),
    costmap_resolution_m=0.5,
    action=Action.SLOW,
    speed_mps=0.25,
    reasons=("first", "second", "third"),
    verdicts=(),
    record={
        "command": {"action": "SLOW", "speed_mps": 0.25, "reasons": ["first", "second", "third"]}
    },
)

# Nothing but the robot (facing +x at (0.5, -0.5)) and a command without reasons.
BARE = empty_scene(
    stamp_s=4.0,
    robot_pose=(0.5, -0.5, 0.0),
    record={"command": {"action": "PROCEED", "speed_mps": 1.0}},
)


def _write(path: Path, *scenes: CycleScene) -> Path:
    with McapRecorder(path) as recorder:
        for scene in scenes:
            recorder.write(scene)
    return path


# -- cycle_stamps, read_cycle, read_records -----------------------------------------------------


# Per test, not per module (except the closed-loop run below): mutation testing credits the
# code a fixture runs to the test that set it up, so a module-scoped drawing would be checked by
# its first test only.
@pytest.fixture
def three(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Cycles at 1 s (with scan and costmap), 1 ns later (without) and at 2 s (with)."""
    return _write(
        tmp_path_factory.mktemp("three") / "three.mcap",
        replace(DRAWN, stamp_s=1.0, record={"n": 0}),
        replace(BARE, stamp_s=1.000000001, record={"n": 1}),
        replace(DRAWN, stamp_s=2.0, record={"n": 2}),
    )


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_cycles_stamps_and_records_are_read_in_order(three: Path) -> None:
    assert cycle_stamps(three) == [1_000_000_000, 1_000_000_001, 2_000_000_000]
    assert read_records(three) == [{"n": 0}, {"n": 1}, {"n": 2}]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_without_a_time_the_last_cycle_is_read_with_every_topic(three: Path) -> None:
    cycle = read_cycle(three)
    assert sorted(cycle) == sorted([*TOPICS, "stamp_s"])
    assert cycle["stamp_s"] == 2.0
    assert json.loads(cycle["/safety/record"].data) == {"n": 2}


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_cycle_nearest_the_time_is_read_and_only_its_messages(three: Path) -> None:
    first = read_cycle(three, 1.0)
    assert sorted(first) == sorted([*TOPICS, "stamp_s"])
    assert first["stamp_s"] == 1.0
    assert json.loads(first["/safety/record"].data) == {"n": 0}
    # 1 ns later: the bare cycle, without the scan and costmap of the cycle before it.
    second = read_cycle(three, 1.0000000011)
    assert sorted(second) == sorted({*TOPICS, "stamp_s"} - {"/scan", "/safety/costmap"})
    assert second["stamp_s"] == pytest.approx(1.000000001, abs=1e-15)
    assert json.loads(second["/safety/record"].data) == {"n": 1}
    assert json.loads(read_cycle(three, 1.4)["/safety/record"].data) == {"n": 1}
    assert read_cycle(three, 1.6)["stamp_s"] == 2.0


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_recording_without_cycles_has_no_cycle_to_read(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mcap"
    McapRecorder(empty).close()
    assert cycle_stamps(empty) == []
    assert read_records(empty) == []
    with pytest.raises(ValueError) as refused:
        read_cycle(empty)
    assert str(refused.value) == f"{empty}: no cycle recorded"
    with pytest.raises(ValueError) as refused:
        read_cycle(empty, 1.0)
    assert str(refused.value) == f"{empty}: no cycle recorded"


# -- cycle_figure -------------------------------------------------------------------------------


@pytest.fixture
def drawn(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return read_cycle(_write(tmp_path_factory.mktemp("drawn") / "drawn.mcap", DRAWN))


@pytest.fixture
def bare(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    return read_cycle(_write(tmp_path_factory.mktemp("bare") / "bare.mcap", BARE))


def _figure(cycle: dict[str, Any]) -> Iterator[Figure]:
    import matplotlib.pyplot as plt

    fig = cycle_figure(cycle)
    try:
        yield fig
    finally:
        plt.close(fig)


@pytest.fixture
def fig(drawn: dict[str, Any]) -> Iterator[Figure]:
    yield from _figure(drawn)


@pytest.fixture
def bare_fig(bare: dict[str, Any]) -> Iterator[Figure]:
    yield from _figure(bare)


def _scatters(fig: Figure) -> dict[str, PathCollection]:
    return {str(c.get_label()): c for c in fig.axes[0].collections if isinstance(c, PathCollection)}


def _near(actual: Any, expected: Any) -> None:
    np.testing.assert_allclose(np.asarray(actual, dtype=float), np.array(expected), atol=1e-6)


def _triangle(line: Any, degrees: float) -> None:
    """``line`` is drawn as a regular triangle (matplotlib's (3, 0, angle) marker) turned by
    ``degrees`` from pointing up."""
    marker = line.get_marker()
    assert isinstance(marker, tuple)
    assert marker[:2] == (3, 0)
    assert marker[2] == pytest.approx(degrees, abs=1e-9)


def _marker_path(marker: str) -> np.ndarray[Any, Any]:
    style = MarkerStyle(marker)
    return np.asarray(style.get_path().transformed(style.get_transform()).vertices)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_costmap_cells_are_drawn_at_their_centres_in_odom(fig: Figure) -> None:
    cells = _scatters(fig)["costmap (marked)"]
    # cell (0, 0) centre (1.25, -0.75) and cell (2, 3) centre (2.75, 0.25) in base_link
    _near(cells.get_offsets(), [[2.75, 2.25], [1.75, 3.75]])
    assert np.asarray(cells.get_sizes()).tolist() == [2.0]
    _near(cells.get_facecolor(), [to_rgba("0.85")])
    _near(cells.get_paths()[0].vertices, _marker_path("s"))
    assert cells.get_zorder() == 1


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_scan_is_drawn_from_the_scanner_without_its_missing_returns(fig: Figure) -> None:
    scan = _scatters(fig)["scan"]
    _near(scan.get_offsets(), [[1.0, 1.5], [2.0 - 2.0 * math.cos(1.0), 1.5 - 2.0 * math.sin(1.0)]])
    assert np.asarray(scan.get_sizes()).tolist() == [1.0]
    _near(scan.get_facecolor(), [to_rgba("0.4")])
    assert scan.get_zorder() == 2


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_clustered_points_are_drawn_coloured_by_cluster_and_loose_ones_left_out(
    fig: Figure,
) -> None:
    clusters = _scatters(fig)["clusters"]
    _near(clusters.get_offsets(), [[2.0, 2.0], [0.0, 3.0]])
    assert np.asarray(clusters.get_array()).tolist() == [0.0, 3.0]
    assert clusters.get_cmap().name == "tab20"
    assert np.asarray(clusters.get_sizes()).tolist() == [4.0]
    assert clusters.get_zorder() == 3


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_envelopes_are_closed_outlines_coloured_by_tier_black_when_unknown(
    fig: Figure,
) -> None:
    lines = fig.axes[0].lines
    outlines = [
        ("tab:green", [(2, 2), (2, 3), (1, 3), (2, 2)]),
        ("tab:orange", [(1, 1), (1, 2), (0, 1), (1, 1)]),
        ("tab:red", [(3, 0), (3, 1), (2, 1), (3, 0)]),
        ("k", [(-1, 4), (-1, 5), (-2, 5), (-1, 4)]),
    ]
    assert len(lines) == len(outlines) + 2  # and the path, and the robot
    for line, (colour, xy) in zip(lines, outlines, strict=False):
        assert line.get_color() == colour
        assert line.get_linewidth() == 1.2
        _near(np.column_stack([line.get_xdata(), line.get_ydata()]), xy)


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_each_track_is_a_disc_an_arrow_and_its_label(fig: Figure) -> None:
    ax = fig.axes[0]
    discs = [p for p in ax.patches if isinstance(p, Circle)]
    assert len(discs) == len(ax.patches) == 2
    for disc, centre, radius in zip(discs, [(3.0, 4.0), (-1.0, -2.0)], [0.5, 0.25], strict=True):
        assert disc.get_center() == pytest.approx(centre)
        assert disc.get_radius() == radius
        assert disc.get_alpha() == 0.3
        _near(disc.get_facecolor(), to_rgba("tab:blue", 0.3))
        _near(disc.get_edgecolor(), to_rgba("tab:blue", 0.3))
    arrows = [t for t in ax.texts if isinstance(t, Annotation)]
    assert [(a.xy, a.xyann) for a in arrows] == [((4.0, 4.0), (3.0, 4.0)),
                                                 ((-1.0, -2.5), (-1.0, -2.0))]  # fmt: skip
    for arrow in arrows:
        assert arrow.get_text() == ""
        assert arrow.arrowprops == {"arrowstyle": "->", "color": "b"}
    labels = [t for t in ax.texts if not isinstance(t, Annotation)]
    _near([t.get_position() for t in labels], [(3.0, 4.4), (-1.0, -1.6)])
    assert [t.get_text() for t in labels] == ["5 person 1.0 m/s", "6 unscored 0.5 m/s"]
    for label in labels:
        assert label.get_fontsize() == 6
        assert label.get_color() == "tab:blue"
        assert label.get_clip_on() is True


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_path_and_the_robot_are_drawn_in_odom(fig: Figure) -> None:
    path, robot = fig.axes[0].lines[-2:]
    _near(np.column_stack([path.get_xdata(), path.get_ydata()]), [(2, 1), (2, 2), (2, 3)])
    assert (path.get_color(), path.get_linestyle(), path.get_linewidth()) == ("k", "--", 1.0)
    assert path.get_label() == "path ahead"
    _near(np.column_stack([robot.get_xdata(), robot.get_ydata()]), [(2.0, 1.0)])
    # a triangle pointing along the robot's heading (+y: matplotlib's upright triangle)
    _triangle(robot, 0.0)
    assert robot.get_markersize() == 12
    assert robot.get_color() == "k"


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_title_axes_legend_and_view_frame_the_cycle_around_the_robot(fig: Figure) -> None:
    ax = fig.axes[0]
    assert len(fig.axes) == 1
    assert fig.get_size_inches().tolist() == [8.0, 8.0]
    assert ax.get_title() == "t = 3.25 s: SLOW 0.25 m/s\nfirst; second"
    assert ax.title.get_fontsize() == 9
    assert ax.get_aspect() == 1.0
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x [m] (odom)", "y [m] (odom)")
    assert ax.get_xlim() == (-2.0, 16.0)
    assert ax.get_ylim() == (-8.0, 10.0)
    legend = ax.get_legend()
    assert legend is not None
    texts = legend.get_texts()
    assert [t.get_text() for t in texts] == ["costmap (marked)", "scan", "clusters", "path ahead"]
    assert {t.get_fontsize() for t in texts} == {7.0}
    assert legend._loc == 1  # type: ignore[attr-defined]  # matplotlib's code of "upper right"


def _drawn_again(cycle: dict[str, Any]) -> tuple[list[Any], list[str]]:
    """The costmap offsets and the envelope colours of ``cycle`` drawn."""
    import matplotlib.pyplot as plt

    fig = cycle_figure(cycle)
    try:
        cells = np.asarray(_scatters(fig)["costmap (marked)"].get_offsets()).tolist()
        colours = [str(line.get_color()) for line in fig.axes[0].lines[:-2]]
    finally:
        plt.close(fig)
    return cells, colours


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_any_occupancy_above_free_is_drawn_and_unknown_cells_are_not(
    drawn: dict[str, Any],
) -> None:
    cycle = copy.deepcopy(drawn)
    grid = cycle["/safety/costmap"]
    data = np.asarray(grid.data).copy()
    # row-major, 4 cells a row: cell (0, 1) barely occupied, cell (1, 0) unknown (-1)
    data[1], data[4] = 1, -1
    grid.data = data
    cells, _ = _drawn_again(cycle)
    # cell (0, 1) centre (1.75, -0.75) in base_link
    _near(cells, [[2.75, 2.25], [2.75, 2.75], [1.75, 3.75]])


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_only_a_tier_name_after_envelope_picks_a_tier_colour(drawn: dict[str, Any]) -> None:
    cycle = copy.deepcopy(drawn)
    markers = [m for m in cycle["/safety/envelopes"].markers if m.action == 0]
    for marker, ns in zip(
        markers,
        ["envelope high extra", "envelope extra high", "envelope  high", "envelope medium"],
        strict=True,
    ):
        marker.ns = ns
    _, colours = _drawn_again(cycle)
    assert colours == ["k", "k", "k", "tab:orange"]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_bare_cycle_draws_the_robot_and_its_command_only(bare_fig: Figure) -> None:
    ax = bare_fig.axes[0]
    assert list(_scatters(bare_fig)) == ["clusters"]
    assert np.asarray(_scatters(bare_fig)["clusters"].get_offsets()).size == 0
    (robot,) = ax.lines
    _near(np.column_stack([robot.get_xdata(), robot.get_ydata()]), [(0.5, -0.5)])
    _triangle(robot, -90.0)
    assert list(ax.patches) == []
    assert list(ax.texts) == []
    assert ax.get_title() == "t = 4.00 s: PROCEED 1.00 m/s"
    assert (ax.get_xlim(), ax.get_ylim()) == ((-3.5, 14.5), (-9.5, 8.5))


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_heading_of_a_tilted_robot_is_its_yaw(drawn: dict[str, Any]) -> None:
    import matplotlib.pyplot as plt

    cycle = copy.deepcopy(drawn)
    # Yaw 0.7 after a roll of 0.3 (on a ramp): q = q_z(0.7) q_x(0.3).
    yaw, roll = 0.7, 0.3
    base = next(t for t in cycle["/tf"].transforms if t.child_frame_id == "base_link")
    q = base.transform.rotation
    q.x = math.cos(yaw / 2) * math.sin(roll / 2)
    q.y = math.sin(yaw / 2) * math.sin(roll / 2)
    q.z = math.sin(yaw / 2) * math.cos(roll / 2)
    q.w = math.cos(yaw / 2) * math.cos(roll / 2)
    fig = cycle_figure(cycle)
    try:
        robot = fig.axes[0].lines[-1]
        _triangle(robot, math.degrees(yaw) - 90.0)
    finally:
        plt.close(fig)


# -- compare_with_audit -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def audited(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A 1 s run (10 cycles) recorded and logged."""
    config = default_config()
    tmp = tmp_path_factory.mktemp("audited")
    sim = make_simulation(config, "reversing_forklift_aisle", 1, 1.0)
    mcap, audit = tmp / "run.mcap", tmp / "run.jsonl"
    outs = list(run_audited(config, SimSource(sim), audit_path=audit, recording=mcap))
    assert len(outs) == 10
    return mcap, audit


def _logged(audit: Path) -> list[dict[str, Any]]:
    """The log's cycle records without their chain fields, read line by line here."""
    records = [json.loads(line) for line in audit.read_text(encoding="utf-8").splitlines()]
    chain = {"kind", "seq", "prev", "hash"}
    return [{k: v for k, v in r.items() if k not in chain} for r in records if r["kind"] == "cycle"]


def _recording(path: Path, records: list[dict[str, Any]]) -> Path:
    return _write(
        path, *(replace(BARE, stamp_s=0.1 * (n + 1), record=r) for n, r in enumerate(records))
    )


def _changed(records: list[dict[str, Any]], cycles: Sequence[int]) -> list[dict[str, Any]]:
    out = copy.deepcopy(records)
    for n in cycles:
        out[n]["command"]["speed_mps"] += 1.0
    return out


DIFFERS = "the recording's record differs from the audit log's"


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_the_recorded_records_are_the_logged_cycle_records(audited: tuple[Path, Path]) -> None:
    mcap, audit = audited
    logged = _logged(audit)
    assert len(logged) == 10
    assert read_records(mcap) == logged
    assert compare_with_audit(mcap, audit) == []


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_each_differing_cycle_is_named_up_to_five_then_counted(
    audited: tuple[Path, Path], tmp_path: Path
) -> None:
    _, audit = audited
    logged = _logged(audit)
    one = _recording(tmp_path / "one.mcap", _changed(logged, [3]))
    assert compare_with_audit(one, audit) == [f"cycle 3: {DIFFERS}"]
    five = _recording(tmp_path / "five.mcap", _changed(logged, [0, 2, 4, 6, 9]))
    assert compare_with_audit(five, audit) == [f"cycle {n}: {DIFFERS}" for n in (0, 2, 4, 6, 9)]
    six = _recording(tmp_path / "six.mcap", _changed(logged, range(1, 7)))
    assert compare_with_audit(six, audit) == [
        *(f"cycle {n}: {DIFFERS}" for n in range(1, 6)),
        "and 1 more cycles differ",
    ]
    eight = _recording(tmp_path / "eight.mcap", _changed(logged, range(8)))
    assert compare_with_audit(eight, audit) == [
        *(f"cycle {n}: {DIFFERS}" for n in range(5)),
        "and 3 more cycles differ",
    ]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_recording_with_fewer_or_more_cycles_than_the_log_says_how_many_each_holds(
    audited: tuple[Path, Path], tmp_path: Path
) -> None:
    _, audit = audited
    logged = _logged(audit)
    fewer = _recording(tmp_path / "fewer.mcap", logged[:8])
    assert compare_with_audit(fewer, audit) == ["8 cycles recorded, 10 in the audit log"]
    more = _recording(tmp_path / "more.mcap", [*logged, logged[-1]])
    assert compare_with_audit(more, audit) == ["11 cycles recorded, 10 in the audit log"]
    both = _recording(tmp_path / "both.mcap", _changed(logged, [2])[:8])
    assert compare_with_audit(both, audit) == [
        f"cycle 2: {DIFFERS}",
        "8 cycles recorded, 10 in the audit log",
    ]


@pytest.mark.requirement("SR-RUN-7", kind="example", code=CODE)
def test_a_log_that_does_not_verify_is_the_one_problem_reported(
    audited: tuple[Path, Path], tmp_path: Path
) -> None:
    mcap, audit = audited
    edited = tmp_path / "edited.jsonl"
    shutil.copy(audit, edited)
    shutil.copy(anchor_path(audit), anchor_path(edited))
    assert compare_with_audit(mcap, edited) == []
    lines = edited.read_text(encoding="utf-8").splitlines(keepends=True)
    lines[3] = lines[3].replace('"action":', '"action" :', 1)
    edited.write_text("".join(lines), encoding="utf-8")
    problems = compare_with_audit(mcap, edited)
    assert problems == [f"{edited}: {verify_log(edited).describe()}"]
    assert problems[0].startswith(f"{edited}: TAMPERED at line 4")
    unanchored = tmp_path / "unanchored.jsonl"
    shutil.copy(audit, unanchored)
    (problem,) = compare_with_audit(mcap, unanchored)
    assert problem.startswith(f"{unanchored}: UNANCHORED: head anchor unanchored.jsonl.head")
