"""Regression examples for faults the properties found (requirements SR-DRV-2, SR-DRV-3).

Each builds a clean device stream, applies one specific fault at a chosen place and checks
that the decoder emits no data that was not sent and notices the loss.
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.sources.serial.rplidar import fields_of
from pipeline.types import Scan
from properties.driver_streams import decode, device_frames, foreign_beams, judge

STREAMS = ["pipeline/sources/serial/rplidar_stream.py", "pipeline/sources/serial/scip_stream.py"]


def _rplidar_scans(n: int = 360) -> list[Scan]:
    rng = np.random.default_rng(9)
    angles = -np.arange(n, dtype=np.float64) * (2 * np.pi / n)
    return [
        Scan(0.0, angles, rng.uniform(0.5, 8.0, n), rng.integers(1, 64, n).astype(float))
        for _ in range(3)
    ]


def _scip_scans(seed: int) -> list[Scan]:
    """Two UTM-30LX revolutions (1081 steps) of random ranges."""
    steps = np.arange(0, 1081)
    rng = np.random.default_rng(seed)
    return [
        Scan(
            0.0,
            (steps - 540).astype(np.float64) * (2 * np.pi / 1440),
            np.rint(rng.uniform(100, 20000, 1081)) / 1000,
        )
        for _ in range(2)
    ]


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", code=STREAMS)
def test_duplicated_byte_cannot_forge_a_start_flag() -> None:
    scans = _rplidar_scans()
    frames = device_frames("rplidar-standard", scans)
    clean, clean_counters = decode("rplidar-standard", frames, frames.data)
    # Duplicating byte 1 (angle low bits + check bit) of a node whose byte 1 has bit 0 set
    # and bit 1 clear makes the shifted window read as a node with the start flag set, the
    # right angle and the right distance: a start of turn in the middle of a revolution.
    index = next(
        i
        for i in range(400, frames.n_scan_frames)
        if frames.frames[i][1] & 0b11 == 0b01
        and not fields_of(np.frombuffer(frames.frames[i], dtype=np.uint8)[None]).start[0]
    )
    faulty = list(frames.frames)
    frame = faulty[index]
    faulty[index] = frame[:2] + frame[1:]
    got, counters = decode("rplidar-standard", frames, frames.prefix + b"".join(faulty))
    assert foreign_beams(clean, got) == 0
    assert judge(clean, clean_counters, got, counters) == "detected"


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", code=STREAMS)
def test_scip_merged_line_rejects_the_revolution() -> None:
    scans = _scip_scans(10)
    frames = device_frames("scip-md", scans)
    clean, clean_counters = decode("scip-md", frames, frames.data)
    faulty = list(frames.frames)
    faulty[10] = faulty[10][:-1]  # lose a data line's LF: it merges with the next line
    got, counters = decode("scip-md", frames, frames.prefix + b"".join(faulty))
    # The line count no longer adds up: no line of that answer can be placed for certain.
    assert foreign_beams(clean, got) == 0
    assert len(got) == len(clean) - 1
    assert counters.scans_dropped == clean_counters.scans_dropped + 1
    assert judge(clean, clean_counters, got, counters) == "detected"


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", code=STREAMS)
def test_scip_timestamp_line_that_swallowed_the_first_data_line() -> None:
    # Found by make certify: the timestamp line loses its LF (it swallows data line 0) and a
    # later data line gains a byte. Counting data lines from either end would then put lines
    # a slot off: right values at the wrong angles. The count does not add up: rejected.
    scans = _scip_scans(11)
    frames = device_frames("scip-md", scans)
    clean, clean_counters = decode("scip-md", frames, frames.data)
    faulty = list(frames.frames)
    stamp = next(i for i, f in enumerate(faulty) if len(f) == 6)  # 4 chars + sum + LF
    faulty[stamp] = faulty[stamp][:-1]
    faulty[stamp + 20] = b"0" + faulty[stamp + 20]
    got, counters = decode("scip-md", frames, frames.prefix + b"".join(faulty))
    assert foreign_beams(clean, got) == 0
    assert len(got) == len(clean) - 1
    assert judge(clean, clean_counters, got, counters) == "detected"


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", code=STREAMS)
def test_express_revolution_starting_in_a_gap_is_incomplete() -> None:
    scans = _rplidar_scans(720)
    frames = device_frames(
        "rplidar-express", [Scan(s.stamp_s, s.angles_rad, s.ranges_m) for s in scans]
    )
    clean, clean_counters = decode("rplidar-express", frames, frames.data)
    # 720 beams = 22.5 capsules per turn: capsule 45 holds the wrap into the third turn.
    for index in (44, 45):
        faulty = list(frames.frames)
        corrupted = bytearray(faulty[index])
        corrupted[50] ^= 0x04
        faulty[index] = bytes(corrupted)
        got, counters = decode("rplidar-express", frames, frames.prefix + b"".join(faulty))
        assert foreign_beams(clean, got) == 0
        # A turn that lost beams is never complete; one that begins right after the gap at
        # an angle wrap is marked incomplete too (its first beams may be the lost ones).
        assert all(s.n_beams == 720 for s in got if s.complete)
        assert any(not s.complete for s in got)
        assert judge(clean, clean_counters, got, counters) == "detected"


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", code=STREAMS)
@pytest.mark.parametrize("bit", [6, 7])
def test_scip_status_bit_flip_outside_the_checksum_is_rejected(bit: int) -> None:
    # Certify found it: the 6-bit checksum cannot see bit 6 or 7, so a flip in the status
    # "99" left a valid-looking "9\xb9" whose scan was skipped without a trace.
    angles = (np.arange(0, 1081, dtype=np.float64) - 540) * (2 * np.pi / 1440)
    rng = np.random.default_rng(11)
    scans = [Scan(0.0, angles, np.rint(rng.uniform(100, 9000, 1081)) / 1e3) for _ in range(3)]
    frames = device_frames("scip-md", scans)
    clean, clean_counters = decode("scip-md", frames, frames.data)
    index = next(i for i, f in enumerate(frames.frames) if f == b"99b\n")
    faulty = list(frames.frames)
    faulty[index] = b"9" + bytes([ord("9") ^ (1 << bit)]) + b"b\n"
    got, counters = decode("scip-md", frames, frames.prefix + b"".join(faulty))
    assert foreign_beams(clean, got) == 0
    assert counters.frames_rejected > clean_counters.frames_rejected
    assert judge(clean, clean_counters, got, counters) == "detected"
