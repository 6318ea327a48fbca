"""A second scanner merged with the first (SR-LID-1, SR-LID-2): the union in the robot frame,
clustered as scikit-learn clusters it, and only while fresh."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import event, given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from pipeline.cluster.dbscan import dbscan_points
from pipeline.config import SafecaseConfig, overridden
from pipeline.points import scan_to_points
from pipeline.scanners import SecondScanner, SecondScanState
from pipeline.types import Frame, Pose, Scan, SecondScan
from properties.oracles.tracking import compare_partitions, sklearn_dbscan
from safety.model.freshness import is_fresh

CODE = ["pipeline/scanners.py", "pipeline/points.py"]

poses = st.tuples(st.floats(-20.0, 20.0), st.floats(-20.0, 20.0), st.floats(-math.pi, math.pi)).map(
    lambda p: (float(p[0]), float(p[1]), float(p[2]))
)


@st.composite
def scans(draw: st.DrawFn, stamp_s: float = 0.0) -> Scan:
    """A scan of random ranges (some invalid, some dense near the scanner) over any fov."""
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    n = draw(st.integers(2, 500))
    span = draw(st.sampled_from([math.pi, 1.5 * math.pi, 2 * math.pi]))
    angles = np.linspace(-span / 2, span / 2, n, endpoint=span < 2 * math.pi)
    ranges = rng.uniform(0.0, draw(st.floats(0.5, 12.0)), n)
    ranges[rng.random(n) < 0.1] = np.nan
    return Scan(stamp_s, angles, ranges)


def _scanner(config: SafecaseConfig, mount: Pose) -> SecondScanner:
    second = config.scan2.model_copy(
        update={"enabled": True, "mount_x_m": mount[0], "mount_y_m": mount[1]}
    )
    second = second.model_copy(update={"mount_yaw_rad": mount[2]})
    return SecondScanner(config.scan, second, config.monitors, is_fresh)


def _reference_points(scan: Scan, config: SafecaseConfig, mount: Pose) -> np.ndarray:
    """The second scan's valid beams, written with complex numbers: the robot frame is
    ``mount`` composed with the polar beam (an implementation independent of pipeline.frames)."""
    r = scan.ranges_m
    keep = np.isfinite(r) & (r >= config.scan.min_range_m) & (r <= config.scan.max_range_m)
    beam = r[keep] * np.exp(1j * (scan.angles_rad[keep] + mount[2]))
    return np.asarray(complex(mount[0], mount[1]) + beam)


def _moved(z: np.ndarray, from_pose: Pose, to_pose: Pose) -> np.ndarray:
    """Robot-frame points at ``from_pose`` expressed in the robot frame at ``to_pose``."""
    world = complex(from_pose[0], from_pose[1]) + z * np.exp(1j * from_pose[2])
    return np.asarray((world - complex(to_pose[0], to_pose[1])) * np.exp(-1j * to_pose[2]))


@pytest.mark.requirement("SR-LID-1", kind="property", code=CODE)
@settings(max_examples=examples(100))
@given(
    first=scans(), second=scans(), mount=poses, first_pose=poses, step=poses, moving=st.booleans()
)
def test_merged_points_are_the_union_in_the_first_scans_robot_frame(
    first: Scan,
    second: Scan,
    mount: Pose,
    first_pose: Pose,
    step: Pose,
    moving: bool,
    safecase_config: SafecaseConfig,
) -> None:
    config = safecase_config
    # The robot a little further on at the second stamp (or without odometry at all).
    second_pose = (first_pose[0] + step[0] / 20, first_pose[1] + step[1] / 20, step[2])
    frame = Frame(
        first,
        0.05,
        pose=first_pose if moving else None,
        second=SecondScan(second, second_pose if moving else None),
    )
    base = scan_to_points(first, config.scan)
    merged, report = _scanner(config, mount).merge(frame, base, 0.05)
    assert report.state is SecondScanState.MERGED
    z = _reference_points(second, config, mount)
    if moving:
        z = _moved(z, second_pose, first_pose)
    assert report.n_points == z.shape[0]
    assert merged.n == base.n + z.shape[0]
    # The same points both ways: each one's nearest counterpart within 1e-9 m.
    expected = np.concatenate([base.x_m + 1j * base.y_m, z])
    got = merged.x_m + 1j * merged.y_m
    if got.size:
        gap = np.abs(got[:, None] - expected[None, :])
        assert gap.min(axis=1).max() <= 1e-9
        assert gap.min(axis=0).max() <= 1e-9
    # Bearings and ranges about the robot's origin, in sweep order, as clustering needs them.
    assert np.all(np.diff(merged.angle_rad) >= 0.0)
    assert np.all((merged.angle_rad >= -math.pi) & (merged.angle_rad < math.pi))
    assert np.allclose(merged.range_m, np.hypot(merged.x_m, merged.y_m), rtol=0.0, atol=1e-12)
    # The second scanner's beams are numbered after the first's.
    from_second = merged.beam_index >= first.n_beams
    assert int(np.count_nonzero(from_second)) == z.shape[0]
    assert merged.drops == base.drops


@pytest.mark.requirement("SR-LID-1", kind="cross-check", code=[*CODE, "pipeline/cluster/dbscan.py"])
@settings(max_examples=examples(60))
@given(first=scans(), second=scans(), mount=poses)
def test_the_merged_cloud_clusters_as_sklearn_clusters_it(
    first: Scan, second: Scan, mount: Pose, safecase_config: SafecaseConfig
) -> None:
    # Mounts on a robot's body: within 1 m of its centre, facing any way.
    mount = (mount[0] / 20, mount[1] / 20, mount[2])
    config = safecase_config
    frame = Frame(first, 0.05, second=SecondScan(second))
    merged, _ = _scanner(config, mount).merge(frame, scan_to_points(first, config.scan), 0.05)
    eps, ms = config.cluster.eps_m, config.cluster.min_samples
    ours = dbscan_points(merged, eps, ms)
    xy = np.stack([merged.x_m, merged.y_m], axis=1)
    ref_labels, ref_core = sklearn_dbscan(xy, eps, ms)
    diff = compare_partitions(xy, ours, ref_labels, ref_core, eps)
    assert diff.agrees, diff


@pytest.mark.requirement("SR-LID-2", kind="property", code=CODE)
@settings(max_examples=examples(200))
@given(
    first=scans(),
    second=scans(),
    # The age is drawn directly, around the freshness window [-skew, max_age - skew] (0.18 s
    # by default), so that merged, stale and blocked scans all come up often; the wide draw
    # keeps far-off stamps in.
    age_s=st.one_of(st.floats(-0.1, 0.3), st.floats(-1.0, 1.5)),
    now=st.floats(-1.0, 1.5),
    skew=st.sampled_from([0.0, 0.01, 0.05]),
    blocked=st.sampled_from([False, False, True]),
)
def test_a_second_scan_contributes_only_while_fresh_and_unblocked(
    first: Scan,
    second: Scan,
    age_s: float,
    now: float,
    skew: float,
    blocked: bool,
    safecase_config: SafecaseConfig,
) -> None:
    config = overridden(safecase_config, {"monitors": {"clock_skew_s": skew}})
    second_stamp = now - age_s
    ranges = np.full(second.n_beams, 0.01) if blocked else second.ranges_m
    late = Scan(second_stamp, second.angles_rad, ranges)
    frame = Frame(first, now, second=SecondScan(late))
    base = scan_to_points(first, config.scan)
    merged, report = _scanner(config, (0.0, 0.0, math.pi)).merge(frame, base, now)
    mon = config.monitors
    fresh = bool(is_fresh(now, second_stamp, mon.scan_max_age_s, mon.clock_skew_s))
    event(report.state.value)
    if not fresh:
        assert report.state is SecondScanState.STALE
    elif blocked:
        assert report.state is SecondScanState.BLOCKED
    else:
        assert report.state is SecondScanState.MERGED
    assert report.age_s == now - second_stamp
    if report.state is SecondScanState.MERGED:
        # Merged: the first scanner's points and every valid beam of the second's.
        valid = _reference_points(late, config, (0.0, 0.0, math.pi))
        assert report.n_points == valid.size
        assert merged.x_m.size == base.x_m.size + valid.size
    else:
        # Left out: the first scanner's points, untouched, and nothing of the second's.
        assert merged is base
        assert report.n_points == 0


@pytest.mark.requirement("SR-LID-2", kind="example", code=CODE)
def test_a_frame_without_a_second_scan_reports_it_absent(safecase_config: SafecaseConfig) -> None:
    first = Scan(0.0, np.linspace(-1.0, 1.0, 50), np.full(50, 3.0))
    base = scan_to_points(first, safecase_config.scan)
    merged, report = _scanner(safecase_config, (0.0, 0.0, 0.0)).merge(
        Frame(first, 0.05), base, 0.05
    )
    assert merged is base
    assert report.state is SecondScanState.ABSENT
    assert report.stamp_s is None
