"""The drivers' frame checks at their exact limits, and the errors they raise.

Each check is exercised on both sides of what it accepts: a SCIP line one byte too short, a
character at the edge of the 6-bit alphabet, an info line checksummed either way, an express
capsule with one sync nibble wrong and its checksum right. The errors must carry the offset
they were given and a reason that names the bad frame, since the runtime records both (the
mutation campaign of the per-cycle stages, SR-EVD-6 in docs/findings/mutation.md, showed these
unwatched).
"""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.sources.serial.errors import ChecksumError, FrameError
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
    [b";:", b"AB", b"PROT;SCIP;X", b"PROT:SCIP2", b"PROT:SCIP;"],
    ids=["two bytes", "no colon, too short", "no colon", "no semicolon", "no checksum"],
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
    for data, offset in ((_capsule()[:-1], 0), (_capsule() + b"\0", 84)):
        with pytest.raises(FrameError) as raised:
            decode_capsule(data) if offset == 0 else decode_capsule(data, offset)
        assert type(raised.value) is FrameError
        assert raised.value.offset == offset
        assert raised.value.reason == f"express capsule: {len(data)} bytes, expected 84"
    with pytest.raises(ChecksumError) as defaulted:
        decode_capsule(bytes(CAPSULE_BYTES))
    assert defaulted.value.offset == 0
