"""Example tests of the RPLIDAR and SCIP 2.0 codecs against the vendors' documented values."""

from __future__ import annotations

import numpy as np
import pytest

from pipeline.errors import SafecaseError
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.errors import ChecksumError, DriverError, EncodeError, FrameError
from pipeline.sources.serial.rplidar_capsule import CapsuleFields, decode_capsule, encode_capsule

CODECS = ["pipeline/sources/serial/rplidar.py", "pipeline/sources/serial/scip.py"]


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/scip.py"])
def test_scip_specification_examples() -> None:
    # The SCIP 2.0 specification's own encoding examples.
    assert scip.decode_values(b"CB", 2).tolist() == [1234]
    assert scip.decode_values(b"1Dh", 3).tolist() == [5432]
    assert scip.decode_values(b"m2@0", 4).tolist() == [16000000]
    assert scip.encode_values([1234], 2) == b"CB"
    assert scip.encode_values([5432], 3) == b"1Dh"
    assert scip.encode_values([16000000], 4) == b"m2@0"
    assert chr(scip.checksum(b"Hokuyo")) == "o"


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/scip.py"])
def test_scip_responses_have_echo_status_and_checksummed_lines() -> None:
    assert scip.encode_response(b"BM", "00") == b"BM\n00P\n\n"
    command = scip.ScipCommand(scip.Name.MD, 0, 1080, 1, 0, 0)
    assert command.encode() == b"MD0000108001000\n"
    assert scip.ScipCommand.parse(b"MD0000108001000") == command
    assert scip.ScipCommand.parse(b"GS0044072501").n_values == 682
    answer = scip.info_response(b"PP", scip.ScipParams().items())
    lines = answer.split(b"\n")
    assert lines[:2] == [b"PP", b"00P"]
    items = scip.decode_info_lines([line for line in lines[2:] if line])
    assert scip.ScipParams.from_items(items) == scip.ScipParams()


@pytest.mark.requirement("SR-DRV-2", code=["pipeline/sources/serial/scip.py"])
def test_scip_bad_input_raises_typed_errors_with_offsets() -> None:
    with pytest.raises(FrameError) as caught:
        scip.decode_values(b"C\x7f", 2)
    assert caught.value.offset == 1
    assert "0x7F" in str(caught.value)
    with pytest.raises(EncodeError):
        scip.encode_values([4096], 2)
    with pytest.raises(DriverError):
        scip.ScipCommand.parse(b"XX")
    with pytest.raises(ChecksumError):
        scip.decode_info_lines([b"DMIN:23;8"])
    assert issubclass(DriverError, SafecaseError)


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/rplidar.py"])
def test_rplidar_requests_and_descriptors_match_the_protocol() -> None:
    assert rp.encode_request(rp.Cmd.SCAN) == b"\xa5\x20"
    # Express scan with the legacy working mode: payload 5 zero bytes, XOR checksum 0x22.
    express = rp.encode_request(rp.Cmd.EXPRESS_SCAN, bytes(5))
    assert express == bytes.fromhex("a58205000000000022")
    assert rp.parse_request(express) == (rp.Request(rp.Cmd.EXPRESS_SCAN, bytes(5)), 9)
    assert rp.parse_request(b"\xa5\x82\x05") == (None, 0)
    assert rp.encode_descriptor(rp.SCAN_DESCRIPTOR) == bytes.fromhex("a55a0500004081")
    assert rp.encode_descriptor(rp.INFO_DESCRIPTOR) == bytes.fromhex("a55a1400000004")
    assert rp.decode_descriptor(bytes.fromhex("a55a5400004082")) == rp.EXPRESS_DESCRIPTOR
    with pytest.raises(ChecksumError) as caught:
        rp.parse_request(express[:-1] + b"\x00")
    assert caught.value.offset == 8
    with pytest.raises(FrameError):
        rp.decode_descriptor(bytes.fromhex("a55b0500004081"))


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/rplidar.py"])
def test_rplidar_answers_round_trip() -> None:
    info = rp.DeviceInfo(0x18, 1, 29, 7, bytes(range(16)))
    assert rp.DeviceInfo.decode(info.encode()) == info
    health = rp.Health(rp.HealthStatus.WARNING, 0x1234)
    assert rp.Health.decode(health.encode()) == health
    rate = rp.SampleRate(500, 250)
    assert rp.SampleRate.decode(rate.encode()) == rate
    with pytest.raises(FrameError):
        rp.Health.decode(b"\x03\x00\x00")


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/rplidar.py"])
def test_rplidar_node_layout() -> None:
    nodes = rp.StandardNodes(
        np.array([True, False]),
        np.array([15, 63]),
        np.array([64 * 90, 0x7FFF]),
        np.array([4000, 0]),
    )
    data = rp.encode_nodes(nodes)
    # quality 15 << 2 | !S << 1 | S = 0x3D; angle 5760 = 0x1680: (0x00 << 1) | C, 0x2D.
    assert data[:5] == bytes([0x3D, 0x01, 0x2D, 0xA0, 0x0F])
    with pytest.raises(ChecksumError) as caught:
        rp.decode_nodes(data)  # the second node's angle is beyond 360 degrees
    assert caught.value.offset == 5
    decoded = rp.decode_nodes(data[:5])
    assert decoded.angle_q6.tolist() == [5760]
    assert decoded.distance_q2.tolist() == [4000]
    with pytest.raises(ChecksumError):
        rp.decode_nodes(bytes([0x3D, 0x00, 0x2D, 0xA0, 0x0F]))  # check bit cleared


@pytest.mark.requirement("SR-DRV-1", code=["pipeline/sources/serial/rplidar_capsule.py"])
def test_express_capsule_fields_round_trip_and_checksum() -> None:
    fields = CapsuleFields(
        1234, True, np.arange(32, dtype=np.int64) * 500, np.arange(32, dtype=np.int64) % 16
    )
    data = encode_capsule(fields)
    back = decode_capsule(data)
    assert (back.start_q6, back.new_scan) == (1234, True)
    assert np.array_equal(back.distance_mm, fields.distance_mm)
    assert np.array_equal(back.dtheta_q3, fields.dtheta_q3)
    corrupted = bytearray(data)
    corrupted[40] ^= 0x10
    with pytest.raises(ChecksumError):
        decode_capsule(bytes(corrupted))
