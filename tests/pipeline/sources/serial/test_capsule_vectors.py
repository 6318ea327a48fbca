"""The express and ultra capsule decoders against a third-party driver's decoded nodes.

The vectors (tests/data/rplidar/capsule_vectors.json, MIT, see SOURCE.md beside it) hold
capsules as hex and the nodes pyrplidar decodes from each consecutive pair. Requirement
SR-DRV-4.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from evidence.record import current
from pipeline.sources.serial.rplidar_capsule import (
    CAPSULE_BYTES,
    ULTRA_CAPSULE_BYTES,
    capsule_validity,
    decode_express_pairs,
    decode_ultra_pairs,
    varbitscale_decode,
)

VECTORS = Path(__file__).resolve().parents[3] / "data" / "rplidar" / "capsule_vectors.json"


def _vectors() -> dict[str, Any]:
    return dict(json.loads(VECTORS.read_text(encoding="utf-8")))


@pytest.mark.requirement(
    "SR-DRV-4", kind="cross-check", code=["pipeline/sources/serial/rplidar_capsule.py"]
)
@pytest.mark.parametrize(
    ("key", "size"),
    [("test_capsule_parsing", CAPSULE_BYTES), ("test_ultra_capsule_parsing", ULTRA_CAPSULE_BYTES)],
)
def test_every_capsule_pair_decodes_to_the_reference_nodes(key: str, size: int) -> None:
    case = _vectors()[key]
    raw = np.frombuffer(b"".join(bytes.fromhex(h) for h in case["data"]), dtype=np.uint8)
    raw = raw.reshape(-1, size)
    assert capsule_validity(raw).all()
    decode = decode_express_pairs if size == CAPSULE_BYTES else decode_ultra_pairs
    nodes = decode(raw)
    # pyrplidar's node form: flag 1 (sync) or 2, quality 0x2f << 2 when a return, the angle
    # in 90/16384 degree units from 1/64 degree, the distance in 1/4 mm.
    ours = np.stack(
        [
            np.where(nodes.sync, 1, 2),
            np.where(nodes.distance_q2 > 0, 188, 0),
            (nodes.angle_q6 << 8) // 90,
            nodes.distance_q2,
        ],
        axis=1,
    )
    expected = np.array(case["nodes_result"], dtype=np.int64).reshape(-1, 4)
    assert ours.shape == expected.shape
    mismatched = int(np.count_nonzero(np.any(ours != expected, axis=1)))
    current().counts(f"{key} nodes", {"compared": len(expected), "mismatched": mismatched})
    assert mismatched == 0


@pytest.mark.requirement(
    "SR-DRV-4", kind="cross-check", code=["pipeline/sources/serial/rplidar_capsule.py"]
)
def test_variable_bit_scale_matches_the_reference() -> None:
    case = _vectors()["test_varbitscale_decode"]
    value, level = varbitscale_decode(np.array(case["dist_major_input"], dtype=np.int64))
    assert value.tolist() == case["dist_major_output"]
    assert level.tolist() == case["scalelvl_output"]
