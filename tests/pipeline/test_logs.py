"""Examples for the log readers (formats in ../shared/data/real/README.md)."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from pipeline.sources.logs import LogFormatError, read_breezyslam, read_carmen, read_ros1_bag
from properties.real_logs import MISSING_REASON, REAL_DATA


def test_carmen_flaser_lines_become_scans(tmp_path: Path) -> None:
    log = tmp_path / "x.log.gz"
    with gzip.open(log, "wt") as handle:
        handle.write("PARAM a b\nODOM 1 2 3\n")
        handle.write("FLASER 3 1.0 2.0 81.9 0 0 0 0 0 0 12.5 host 12.5\n")
    (scan,) = list(read_carmen(log))
    assert scan.ranges_m.tolist() == [1.0, 2.0, 81.9]
    assert scan.angles_rad[0] == pytest.approx(-np.pi / 2)
    assert scan.stamp_s == 12.5


def test_a_truncated_carmen_line_names_file_and_line(tmp_path: Path) -> None:
    log = tmp_path / "bad.log"
    log.write_text("FLASER 3 1.0 2.0\n")
    with pytest.raises(LogFormatError, match=r"bad.log:1: bad FLASER line"):
        list(read_carmen(log))


def test_breezyslam_error_codes_become_nan(tmp_path: Path) -> None:
    line = " ".join(["1000000"] + ["0"] * 23 + ["5"] + ["1500"] * 681 + [""])
    dat = tmp_path / "e.dat"
    dat.write_text(line + "\n")
    (scan,) = list(read_breezyslam(dat))
    assert np.isnan(scan.ranges_m[0])
    assert scan.ranges_m[1] == pytest.approx(1.5)
    assert scan.n_beams == 682
    assert scan.stamp_s == pytest.approx(1.0)


def test_leg_tracker_bag_reads_with_rosbags() -> None:
    bag = REAL_DATA / "leg_tracker" / "positive_2_extracted.bag"
    if not bag.is_file():
        pytest.skip(MISSING_REASON)
    scans = list(read_ros1_bag(bag))
    assert len(scans) == 83
    assert scans[0].n_beams == 768
    assert np.all(np.diff([s.stamp_s for s in scans]) > 0)
    with pytest.raises(LogFormatError, match="3 LaserScan topics"):
        list(read_ros1_bag(REAL_DATA / "leg_tracker" / "negative_2.bag"))
