"""evidence.timing: interleaved same-run comparisons."""

from __future__ import annotations

import time

import pytest

from evidence.record import current
from evidence.timing import compare


def test_compare_orders_a_slow_and_a_fast_candidate() -> None:
    def fast() -> None:
        pass

    def slow() -> None:
        time.sleep(0.0005)

    timings = compare({"fast": fast, "slow": slow}, reference="slow", rounds=20, warmup=1)
    assert timings["slow"].p50_s >= 0.0005
    assert timings["fast"].p50_s < timings["slow"].p50_s
    record = current().peek()
    assert record is not None
    types = [d["type"] for d in record.details]
    assert types == ["table", "samples", "samples"]
    assert record.details[0]["rows"][0][0] == "fast"


def test_compare_rejects_an_unknown_reference() -> None:
    with pytest.raises(ValueError, match="reference 'x'"):
        compare({"a": lambda: None}, reference="x")
