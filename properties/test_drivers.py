"""Serial-driver properties (requirement family SR-DRV-*).

Round trips through each codec and stream decoder (SR-DRV-1), arbitrary and spliced byte
streams (SR-DRV-2), injected faults detected or harmless (SR-DRV-3) and the staleness rule
(SR-DRV-3). Byte streams come from the real device models (the emulator's device side);
decoding is the driver's own stream decoder.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from evidence.record import current
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.devices import ScipDevice
from pipeline.sources.serial.errors import DriverError
from pipeline.sources.serial.faults import BYTE_FAULTS, FaultKind, FaultPlan, inject
from pipeline.sources.serial.rplidar_capsule import CapsuleFields, decode_capsule, encode_capsule
from pipeline.sources.serial.rplidar_stream import RplidarStream
from pipeline.sources.serial.scip_answers import parse_answers
from pipeline.sources.serial.scip_stream import ScipStream
from pipeline.sources.serial.transport import link_state
from pipeline.types import DriverState
from properties.driver_streams import (
    LINKS,
    UTM_30LX,
    Link,
    decode,
    device_frames,
    expected_scans,
    foreign_beams,
    forged_frames,
    judge,
    link_scans,
    wrap_rad,
)
from properties.oracles.drivers import checked_capsule_distances, checked_node_windows

CODECS = ["pipeline/sources/serial/rplidar.py", "pipeline/sources/serial/scip.py"]
STREAMS = ["pipeline/sources/serial/rplidar_stream.py", "pipeline/sources/serial/scip_stream.py"]
# Quantisation of each link: (angle tolerance rad, range tolerance m).
TOLERANCE = {
    "rplidar-standard": (np.deg2rad(1 / 128) + 1e-12, 0.000125 + 1e-12),
    "rplidar-express": (np.deg2rad(8 / 64) + 1e-12, 0.000625 + 1e-12),
    "scip-md": (1e-12, 1e-12),
    "scip-ms": (1e-12, 1e-12),
}


# ------------------------------------------------------------------------- SR-DRV-1
@pytest.mark.requirement("SR-DRV-1", code=[*CODECS, *STREAMS, "pipeline/sources/serial/devices.py"])
@settings(max_examples=examples(60))
@given(data=st.data(), link=st.sampled_from(LINKS))
def test_round_trip_through_device_and_stream_decoder(data: st.DataObject, link: Link) -> None:
    scans = data.draw(link_scans(link), label="scans")
    frames = device_frames(link, scans)
    chunks = data.draw(st.lists(st.integers(1, 4096), min_size=1, max_size=5), label="chunks")
    got, counters = decode(link, frames, frames.data, chunks)
    want = expected_scans(link, scans)
    assert counters.frames_rejected == 0
    assert len(got) >= len(want)
    angle_tol, range_tol = TOLERANCE[link]
    for sent, scan in zip(want, got, strict=False):
        assert scan.complete
        assert scan.n_beams == sent.n_beams
        # The RPLIDAR sends beams in its clockwise sweep order, the scans here are in it.
        assert np.max(np.abs(wrap_rad(scan.angles_rad - sent.angles_rad))) <= angle_tol
        assert np.array_equal(np.isnan(scan.ranges_m), np.isnan(sent.ranges_m))
        finite = ~np.isnan(sent.ranges_m)
        if finite.any():
            assert np.max(np.abs(scan.ranges_m[finite] - sent.ranges_m[finite])) <= range_tol
        if sent.intensities is not None and scan.intensities is not None:
            assert np.array_equal(scan.intensities, sent.intensities)
    current().count("round trip", link, len(want))


@pytest.mark.requirement("SR-DRV-1", code=CODECS)
@given(
    cmd=st.integers(0, 255),
    payload=st.binary(max_size=40),
    length=st.integers(0, (1 << 30) - 1),
    mode=st.integers(0, 3),
    kind=st.integers(0, 255),
)
def test_requests_and_descriptors_round_trip(
    cmd: int, payload: bytes, length: int, mode: int, kind: int
) -> None:
    body = payload if cmd & 0x80 else b""
    wire = rp.encode_request(cmd, body)
    assert rp.parse_request(wire) == (rp.Request(cmd, body), len(wire))
    descriptor = rp.Descriptor(length, mode, kind)
    assert rp.decode_descriptor(rp.encode_descriptor(descriptor)) == descriptor


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/rplidar_capsule.py"])
@given(
    start=st.integers(0, 0x7FFF),
    new_scan=st.booleans(),
    dist=st.lists(st.integers(0, (1 << 14) - 1), min_size=32, max_size=32),
    dtheta=st.lists(st.integers(0, 63), min_size=32, max_size=32),
)
def test_express_capsule_fields_round_trip(
    start: int, new_scan: bool, dist: list[int], dtheta: list[int]
) -> None:
    fields = CapsuleFields(start, new_scan, np.array(dist), np.array(dtheta))
    back = decode_capsule(encode_capsule(fields))
    assert (back.start_q6, back.new_scan) == (start, new_scan)
    assert back.distance_mm.tolist() == dist
    assert back.dtheta_q3.tolist() == dtheta


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/scip.py"])
@given(data=st.data(), width=st.sampled_from([2, 3, 4]))
def test_scip_character_encoding_round_trips(data: st.DataObject, width: int) -> None:
    values = data.draw(st.lists(st.integers(0, (1 << (6 * width)) - 1), max_size=200))
    text = scip.encode_values(values, width)
    assert all(0x30 <= c <= 0x6F for c in text)
    assert scip.decode_values(text, width).tolist() == values
    lines = scip.encode_data_lines(values, width, None)
    checked = [line + bytes((scip.checksum(line),)) for line in lines]
    got, valid, lines_ok = scip.decode_data_lines(checked, width, len(values))
    assert got.tolist() == values
    assert valid.all()
    assert lines_ok.all()


# ------------------------------------------------------------------------- SR-DRV-2
def _decoders() -> list[tuple[str, RplidarStream | ScipStream]]:
    command = scip.ScipCommand(scip.Name.MD, UTM_30LX.amin, UTM_30LX.amax, 1, 0, 0)
    return [
        ("standard", RplidarStream("standard")),
        ("express", RplidarStream("express")),
        ("ultra", RplidarStream("ultra")),
        ("scip", ScipStream(UTM_30LX, command)),
    ]


@pytest.mark.requirement("SR-DRV-2", code=STREAMS)
@settings(max_examples=examples(10_000))
@given(
    data=st.binary(min_size=0, max_size=600),
    cut=st.integers(0, 600),
)
def test_arbitrary_bytes_never_raise_and_emit_only_checked_frames(data: bytes, cut: int) -> None:
    record = current()
    for name, decoder in _decoders():
        try:
            scans = decoder.feed(data[:cut], 0.0) + decoder.feed(data[cut:], 1.0)
        except DriverError:  # the one error a decoder may raise (it is designed not to)
            record.count("arbitrary bytes", f"{name} typed error", 1)
            continue
        counters = decoder.counters
        assert counters.frames_ok >= 0
        assert counters.bytes_discarded <= len(data)
        if name == "standard":
            windows = checked_node_windows(data)
            for scan in scans:
                q6 = np.rint(-np.rad2deg(scan.angles_rad) * 64).astype(int) % rp.Q6_PER_TURN
                q2 = np.where(np.isnan(scan.ranges_m), 0, np.rint(scan.ranges_m * 4000))
                assert scan.intensities is not None
                for beam in zip(scan.intensities.astype(int), q6, q2.astype(int), strict=True):
                    assert tuple(int(v) for v in beam) in windows
        elif name == "express":
            distances = checked_capsule_distances(data)
            for scan in scans:
                mm = np.where(np.isnan(scan.ranges_m), 0, np.rint(scan.ranges_m * 1000))
                assert set(mm.astype(int).tolist()) <= distances
        record.count("arbitrary bytes", f"{name} scans emitted", len(scans))
    record.count("arbitrary bytes", "streams", 1)
    record.count("arbitrary bytes", "bytes", len(data))


@pytest.mark.requirement("SR-DRV-2", code=STREAMS)
@settings(max_examples=examples(150))
@given(data=st.data(), link=st.sampled_from(LINKS))
def test_spliced_garbage_never_yields_data_that_was_not_sent(
    data: st.DataObject, link: Link
) -> None:
    scans = data.draw(link_scans(link), label="scans")
    frames = device_frames(link, scans)
    clean, _ = decode(link, frames, frames.data)
    stream = bytearray(frames.data)
    for _ in range(data.draw(st.integers(1, 4), label="splices")):
        at = data.draw(st.integers(0, len(stream)), label="at")
        junk = data.draw(st.binary(min_size=1, max_size=200), label="junk")
        if data.draw(st.booleans(), label="overwrite"):
            stream[at : at + len(junk)] = junk
        else:
            stream[at:at] = junk
    chunks = data.draw(st.lists(st.integers(1, 3000), min_size=1, max_size=4), label="chunks")
    got, counters = decode(link, frames, bytes(stream), chunks)
    record = current()
    if link == "rplidar-standard":
        # No checksum over standard nodes: the guarantee is that every beam comes from a
        # 5-byte window that passes the protocol's checks (see the README finding).
        windows = checked_node_windows(bytes(stream))
        for scan in got:
            q6 = np.rint(-np.rad2deg(scan.angles_rad) * 64).astype(int) % rp.Q6_PER_TURN
            q2 = np.where(np.isnan(scan.ranges_m), 0, np.rint(scan.ranges_m * 4000)).astype(int)
            assert scan.intensities is not None
            for beam in zip(scan.intensities.astype(int), q6, q2, strict=True):
                assert tuple(int(v) for v in beam) in windows
        record.count("spliced", f"{link} foreign beams (not asserted)", foreign_beams(clean, got))
    else:
        # A checksum cannot see every change (SCIP sums 6 bits per line, an express capsule
        # XORs 8): junk that happens to form a frame passing the protocol's own checks is
        # indistinguishable from a sent frame. Data never sent may come only from such.
        forged = forged_frames(link, frames.data, bytes(stream))
        if not forged:
            assert foreign_beams(clean, got) == 0
        record.count(
            "spliced", f"{link} streams with a forged check-passing frame", int(forged > 0)
        )
    record.count("spliced", f"{link} rejected frames", counters.frames_rejected)
    record.count("spliced", f"{link} streams", 1)


_SIMPLE_COMMANDS = [b"SCIP2.0", b"VV", b"PP", b"II", b"BM", b"QT", b"RS", b"XX"]


@pytest.mark.requirement("SR-DRV-2", code=["pipeline/sources/serial/scip_answers.py"])
@given(
    commands=st.lists(st.sampled_from(_SIMPLE_COMMANDS), min_size=1, max_size=6),
    garbage=st.lists(
        st.lists(st.binary(min_size=1, max_size=40).filter(lambda b: b"\n" not in b), max_size=3),
        min_size=6,
        max_size=6,
    ),
    data=st.binary(max_size=300),
)
def test_scip_answers_between_garbage_lines_are_all_kept(
    commands: list[bytes], garbage: list[list[bytes]], data: bytes
) -> None:
    device = ScipDevice()
    stream = b""
    expected = []
    for command, junk in zip(commands, garbage, strict=False):
        stream += b"".join(line + b"\n" for line in junk)
        answer = device.receive(command + b"\n")
        expected.append(answer.split(b"\n")[:2])
        stream += answer
    parsed = parse_answers(stream, set(commands))
    got = [[a.echo, a.status + bytes((scip.checksum(a.status),))] for a in parsed.answers]
    # Every valid answer comes back, in order, whatever garbage lines lie between them.
    assert got == expected
    assert parsed.consumed == len(stream)
    # Arbitrary bytes never raise, and the settled part never exceeds what was given.
    for buf in (data, stream[: len(stream) // 2] + data):
        assert 0 <= parse_answers(buf).consumed <= len(buf)
    current().count("scip answers", "answers kept", len(got))


# ------------------------------------------------------------------------- SR-DRV-3
@pytest.mark.requirement("SR-DRV-3", code=[*STREAMS, "pipeline/sources/serial/faults.py"])
@settings(max_examples=examples(400))
@given(
    data=st.data(),
    link=st.sampled_from(LINKS),
    kind=st.sampled_from(BYTE_FAULTS),
    seed=st.integers(0, 2**32 - 1),
)
def test_every_injected_fault_is_detected_or_harmless(
    data: st.DataObject, link: Link, kind: FaultKind, seed: int
) -> None:
    scans = data.draw(link_scans(link, count=2), label="scans")
    frames = device_frames(link, scans)
    clean, clean_counters = decode(link, frames, frames.data)
    rng = np.random.default_rng(seed)
    # The frame comes from the seeded generator: Hypothesis's own draws crowd at frame 0,
    # which in an express stream lies in the withheld first turn (harmless by construction).
    index = int(rng.integers(0, frames.n_scan_frames))
    faulty_frames = list(frames.frames)
    faulty_frames[index] = inject(kind, faulty_frames[index], rng, FaultPlan()).data
    stream = frames.prefix + b"".join(faulty_frames)
    chunks = data.draw(st.lists(st.integers(1, 3000), min_size=1, max_size=3), label="chunks")
    faulty, faulty_counters = decode(link, frames, stream, chunks)
    verdict = judge(clean, clean_counters, faulty, faulty_counters)
    record = current()
    record.count(f"faults {link}", f"{kind.value} injected", 1)
    record.count(f"faults {link}", f"{kind.value} {verdict}", 1)
    if link == "rplidar-standard" and verdict == "undetected":
        # No checksum over standard nodes: a flipped distance bit is invisible, and a dropped or
        # duplicated byte can (rarely: certify found one in ~1,000) realign onto 5-byte windows
        # that pass every check bit. What the framing can guarantee is that every emitted beam
        # is such a checked window of the received bytes (README finding); assert that instead.
        windows = checked_node_windows(stream)
        for scan in faulty:
            q6 = np.rint(-np.rad2deg(scan.angles_rad) * 64).astype(int) % rp.Q6_PER_TURN
            q2 = np.where(np.isnan(scan.ranges_m), 0, np.rint(scan.ranges_m * 4000)).astype(int)
            assert scan.intensities is not None
            for beam in zip(scan.intensities.astype(int), q6, q2, strict=True):
                assert tuple(int(v) for v in beam) in windows
        record.count(f"faults {link}", f"{kind.value} undetected, beams from checked windows", 1)
        return
    assert verdict != "undetected", (link, kind, index)


_EVENTS = st.lists(
    st.tuples(
        st.sampled_from(["frame", "reject", "lose", "connect", "wait"]),
        st.floats(0.0, 2.0, allow_nan=False),
    ),
    max_size=30,
)


@pytest.mark.requirement("SR-DRV-3", code=["pipeline/sources/serial/transport.py"])
@given(events=_EVENTS, timeout_s=st.floats(0.01, 5.0), probe_s=st.floats(0.0, 10.0))
def test_health_is_stale_exactly_when_the_last_frame_is_older_than_the_timeout(
    events: list[tuple[str, float]], timeout_s: float, probe_s: float
) -> None:
    now = last_frame = 0.0
    last_reject = -np.inf
    link_up, connecting = True, False
    for event, dt in events:
        now += dt
        if event == "frame":
            last_frame, connecting = now, False
        elif event == "reject":
            last_reject = now
        elif event == "lose":
            link_up = False
        elif event == "connect":
            link_up, connecting = True, True
    at = now + probe_s
    state = link_state(
        now_s=at,
        last_frame_s=last_frame,
        last_reject_s=last_reject,
        silent_timeout_s=timeout_s,
        failed=False,
        link_up=link_up,
        connecting=connecting,
    )
    age = at - last_frame
    assert (state is DriverState.STALE) == (age > timeout_s)
    if state in (DriverState.OK, DriverState.DEGRADED):
        assert age <= timeout_s
        assert link_up
    current().count("staleness", state.value, 1)
