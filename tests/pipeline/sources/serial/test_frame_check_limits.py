"""The drivers' frame checks at their exact limits, and the errors they raise.

Each check is exercised on both sides of what it accepts: a SCIP line one byte too short, a
character at the edge of the 6-bit alphabet, an info line checksummed either way, an express
capsule with one sync nibble wrong and its checksum right, an RPLIDAR node at exactly 360
degrees, a request one byte short at an offset into the buffer. The errors must carry the offset
they were given and a reason that names the bad frame, since the runtime records both (the
mutation campaign of the per-cycle stages, SR-EVD-6 in docs/findings/mutation.md, showed these
unwatched).
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.sources.serial.errors import ChecksumError, EncodeError, FrameError
from pipeline.sources.serial.rplidar import (
    NODE_BYTES,
    Q6_PER_TURN,
    SYNC_BYTE,
    Request,
    StandardNodes,
    decode_nodes,
    encode_nodes,
    encode_request,
    node_validity,
    parse_request,
)
from pipeline.sources.serial.rplidar_capsule import (
    CAPSULE_BYTES,
    NODES_PER_CAPSULE,
    CapsuleFields,
    capsule_validity,
    decode_capsule,
    encode_capsule,
)
from pipeline.sources.serial.scip import (
    CHAR_MAX,
    CHAR_MIN,
    checksum,
    decode_info_lines,
    encoded_line_ok,
    line_ok,
)

SCIP = ["pipeline/sources/serial/scip.py"]
CAPSULE = ["pipeline/sources/serial/rplidar_capsule.py"]
STANDARD = ["pipeline/sources/serial/rplidar.py"]


def _signed(payload: bytes) -> bytes:
    """``payload`` followed by its SCIP checksum character (no LF)."""
    return payload + bytes((checksum(payload),))


def _info(payload: bytes, *, with_semicolon: bool = False) -> bytes:
    """An info line ``payload;c``, ``c`` over ``payload`` or over ``payload;``."""
    summed = payload + b";" if with_semicolon else payload
    return payload + b";" + bytes((checksum(summed),))


# -- SCIP lines ------------------------------------------------------------------------------


@pytest.mark.requirement("SR-DRV-2", code=SCIP)
def test_a_line_needs_a_payload_byte_and_a_checksum() -> None:
    assert line_ok(_signed(b"0"))  # the shortest line: one payload byte and its checksum
    # A lone byte is no line, even where it equals the checksum of nothing (0x30).
    assert checksum(b"") == ord("0")
    assert not line_ok(b"0")
    assert not line_ok(b"")
    assert not line_ok(_signed(b"0")[:-1] + b"1")


@pytest.mark.requirement("SR-DRV-2", code=SCIP)
def test_an_encoded_line_keeps_to_the_alphabet_up_to_its_last_payload_byte() -> None:
    edge = bytes((CHAR_MIN, CHAR_MAX, CHAR_MAX))
    assert encoded_line_ok(_signed(edge))
    for outside in (CHAR_MIN - 1, CHAR_MAX + 1):
        for at in range(3):
            payload = bytearray(edge)
            payload[at] = outside
            # The checksum is right: only the alphabet can reject it, wherever the byte sits.
            assert line_ok(_signed(bytes(payload)))
            assert not encoded_line_ok(_signed(bytes(payload))), (outside, at)
    assert not encoded_line_ok(_signed(edge)[:-1] + b"1")


@pytest.mark.requirement("SR-DRV-2", code=SCIP)
def test_info_lines_are_parsed_whichever_way_the_device_sums_them() -> None:
    lines = [
        _info(b"PROT:SCIP 2.0"),
        _info(b"MODL:UTM-30LX", with_semicolon=True),
        _info(b"STAT:mode:normal"),  # the value keeps its own colons
        _info(b":"),  # the shortest line: an empty key and value
        _info("SERI:caf\u00e9".encode()),  # not ASCII: each byte is replaced, nothing raised
    ]
    assert decode_info_lines(lines) == {
        "PROT": "SCIP 2.0",
        "MODL": "UTM-30LX",
        "STAT": "mode:normal",
        "": "",
        "SERI": "caf\ufffd\ufffd",
    }


@pytest.mark.requirement("SR-DRV-2", code=SCIP)
@pytest.mark.parametrize(
    "line",
    [b";:", b"AB", b"PROT;SCIP;X", b"PROT:SCIP2", b"PROT:SCIP;", b"MODL;" + b"U" * 60],
    ids=["two bytes", "no colon, too short", "no colon", "no semicolon", "no checksum", "long"],
)
def test_a_malformed_info_line_is_a_frame_error_not_a_checksum_error(line: bytes) -> None:
    with pytest.raises(FrameError) as raised:
        decode_info_lines([_info(b"PROT:SCIP 2.0"), line], offset=7)
    assert type(raised.value) is FrameError
    assert raised.value.offset == 7
    assert raised.value.reason == f"scip info line {line[:40]!r}: expected KEY:value;c"


@pytest.mark.requirement("SR-DRV-2", code=SCIP)
def test_an_info_line_failing_both_checksums_names_its_first_40_bytes() -> None:
    payload = b"MODL:" + b"U" * 60
    good = _info(payload)
    bad = good[:-1] + bytes((good[-1] + 1,))
    assert bad[-1] != checksum(payload + b";")
    with pytest.raises(ChecksumError) as raised:
        decode_info_lines([bad])
    assert raised.value.offset == 0
    assert raised.value.reason == f"scip info line {bad[:40]!r}: checksum mismatch"
    with pytest.raises(FrameError) as malformed:
        decode_info_lines([payload + b"X"])
    assert malformed.value.offset == 0


# -- RPLIDAR express capsules ----------------------------------------------------------------


def _capsule() -> bytes:
    nodes = np.arange(NODES_PER_CAPSULE, dtype=np.int64)
    return encode_capsule(CapsuleFields(1234, False, 500 + 10 * nodes, nodes % 64))


@pytest.mark.requirement("SR-DRV-2", code=CAPSULE)
@pytest.mark.parametrize("byte", [0, 1])
def test_one_wrong_sync_nibble_rejects_a_capsule_whose_checksum_is_right(byte: int) -> None:
    good = bytearray(_capsule())
    bad = bytearray(good)
    bad[byte] ^= 0x10  # the sync nibble only; the checksum nibbles stay right
    raw = np.frombuffer(bytes(good + bad), dtype=np.uint8).reshape(2, CAPSULE_BYTES)
    assert capsule_validity(raw).tolist() == [True, False]
    with pytest.raises(ChecksumError) as raised:
        decode_capsule(bytes(bad), offset=168)
    assert raised.value.offset == 168
    assert raised.value.reason == "express capsule: sync nibbles or XOR checksum wrong"


@pytest.mark.requirement("SR-DRV-2", code=CAPSULE)
def test_a_capsule_of_the_wrong_length_is_a_frame_error_naming_its_length() -> None:
    short, long = _capsule()[:-1], _capsule() + b"\0"
    with pytest.raises(FrameError) as raised:
        decode_capsule(short)  # the default offset is 0
    assert type(raised.value) is FrameError
    assert raised.value.offset == 0
    assert raised.value.reason == "express capsule: 83 bytes, expected 84"
    with pytest.raises(FrameError) as raised:
        decode_capsule(long, 84)
    assert raised.value.offset == 84
    assert raised.value.reason == "express capsule: 85 bytes, expected 84"
    with pytest.raises(ChecksumError) as defaulted:
        decode_capsule(bytes(CAPSULE_BYTES))
    assert defaulted.value.offset == 0


# -- RPLIDAR standard nodes and requests -----------------------------------------------------


def _nodes(angle_q6: list[int]) -> bytes:
    n = len(angle_q6)
    return encode_nodes(
        StandardNodes(
            start=np.zeros(n, dtype=np.bool_),
            quality=np.full(n, 47, dtype=np.int64),
            angle_q6=np.asarray(angle_q6, dtype=np.int64),
            distance_q2=np.full(n, 4000, dtype=np.int64),
        )
    )


@pytest.mark.requirement("SR-DRV-2", code=STANDARD)
def test_a_node_at_360_degrees_is_invalid_and_one_q6_step_below_is_not() -> None:
    data = _nodes([0, Q6_PER_TURN - 1, Q6_PER_TURN])
    raw = np.frombuffer(data, dtype=np.uint8).reshape(-1, NODE_BYTES)
    assert node_validity(raw).tolist() == [True, True, False]
    with pytest.raises(ChecksumError) as raised:
        decode_nodes(data, offset=100)
    assert raised.value.offset == 100 + 2 * NODE_BYTES
    assert raised.value.reason == (
        f"rplidar node 2: start-flag pair, check bit or angle invalid (bytes {data[10:].hex()})"
    )


@pytest.mark.requirement("SR-DRV-2", code=STANDARD)
def test_nodes_decode_from_a_strided_array_as_from_bytes() -> None:
    data = _nodes([64 * a for a in (0, 90, 180, 359)])
    spread = np.zeros(2 * len(data), dtype=np.uint8)
    spread[::2] = np.frombuffer(data, dtype=np.uint8)
    view = spread[::2]  # not contiguous: no buffer to read bytes from
    assert not view.flags.c_contiguous
    ours, theirs = decode_nodes(view), decode_nodes(data)
    for name in ("start", "quality", "angle_q6", "distance_q2"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(theirs, name), err_msg=name)
    np.testing.assert_array_equal(theirs.angle_q6, [0, 5760, 11520, 22976])


@pytest.mark.requirement("SR-DRV-2", code=STANDARD)
def test_bytes_that_are_not_whole_nodes_are_a_frame_error_naming_the_count() -> None:
    with pytest.raises(FrameError) as raised:
        decode_nodes(_nodes([0, 64])[:-1], offset=3)
    assert type(raised.value) is FrameError
    assert raised.value.offset == 3
    assert raised.value.reason == f"rplidar nodes: 9 bytes is not a multiple of {NODE_BYTES}"


@pytest.mark.requirement("SR-DRV-2", code=STANDARD)
def test_a_request_takes_any_byte_as_command_and_up_to_255_payload_bytes() -> None:
    assert encode_request(0x7F) == bytes((SYNC_BYTE, 0x7F))
    longest = encode_request(0xFF, bytes(255))
    assert parse_request(longest) == (Request(0xFF, bytes(255)), len(longest))
    for cmd, payload, reason in (
        (256, b"", "rplidar request: cmd 256 is not a byte"),
        (-1, b"", "rplidar request: cmd -1 is not a byte"),
        (0x25, b"x", "rplidar request: cmd 0x25 takes no payload"),
        (0x84, bytes(256), "rplidar request: payload of 256 bytes exceeds 255"),
    ):
        with pytest.raises(EncodeError) as raised:
            encode_request(cmd, payload)
        assert raised.value.reason == reason


@pytest.mark.requirement("SR-DRV-2", code=STANDARD)
def test_a_request_short_of_its_end_at_an_offset_waits_for_more_bytes() -> None:
    stop, express = encode_request(0x25), encode_request(0x82, bytes(5))
    buf = stop + express
    at = len(stop)
    assert parse_request(buf, 0) == (Request(0x25), 2)
    assert parse_request(buf, at) == (Request(0x82, bytes(5)), len(express))
    for cut in range(at, len(buf)):  # every prefix of the second request: not yet complete
        assert parse_request(buf[:cut], at) == (None, 0), cut
    bad = bytearray(buf)
    bad[at] = 0x5A
    with pytest.raises(FrameError) as frame:
        parse_request(bytes(bad), at)
    assert frame.value.offset == at
    assert frame.value.reason == "rplidar request: sync byte 0x5A, expected 0xA5"
    wrong = bytearray(buf)
    wrong[-1] ^= 0x01
    with pytest.raises(ChecksumError) as checksum_error:
        parse_request(bytes(wrong), at)
    assert checksum_error.value.offset == len(buf) - 1
    assert checksum_error.value.reason == (
        f"rplidar request 0x82: checksum 0x{wrong[-1]:02X}, expected 0x{buf[-1]:02X}"
    )
