"""The recorded 10,000-encounter campaign (SR-RUN-8): its committed rows read again and its bound
recomputed, independently of the campaign code (plain JSON, the closed form of the
Clopper-Pearson limit with no violation, and its definition as a Beta quantile).

The rows (``docs/findings/data/c10k.jsonl.gz``) were written by ``safecase campaign
--encounters 10000 --duration 12 --no-shadow`` at e4bbe10 (docs/findings/campaigns.md); this
test does not run them again, it checks that the file says what the docs claim of it.
"""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import pytest
from scipy.stats import beta

from evidence.record import Recorder

ROWS = Path(__file__).resolve().parents[1] / "docs" / "findings" / "data" / "c10k.jsonl.gz"


@pytest.mark.requirement(
    "SR-RUN-8", kind="campaign", code=["docs/findings/data/c10k.jsonl.gz", "safety/campaign.py"]
)
def test_the_recorded_ten_thousand_encounters_bound_the_rate_below_3e_4(
    evidence: Recorder,
) -> None:
    with gzip.open(ROWS, "rt", encoding="utf-8") as handle:
        header, *rows = (json.loads(line) for line in handle)
    assert header["format"] == "safecase-campaign/1"
    assert sorted(r["seed"] for r in rows) == list(range(10_000))
    assert {(r["scenario"], r["duration_s"]) for r in rows} == {("random_encounter", 12.0)}
    raised = [r["seed"] for r in rows if r["error"] is not None]
    moving = [r["seed"] for r in rows if r["moving_contacts_mps"]]
    at_rest = sum(1 for r in rows if r["contacts"] and not r["moving_contacts_mps"])
    n = len(rows)
    upper_95 = 1.0 - 0.05 ** (1.0 / n)
    upper_99 = 1.0 - 0.01 ** (1.0 / n)
    assert upper_95 == pytest.approx(float(beta.ppf(0.95, 1, n)), rel=1e-9)
    evidence.note(
        f"Recorded campaign ({ROWS.name}, e4bbe10): {n} random encounters of 12 s, "
        f"{len(moving)} with a contact while moving, {len(raised)} raised, {at_rest} touched at "
        f"standstill; one-sided upper bound of the per-run rate {upper_95:.3g} (95 %), "
        f"{upper_99:.3g} (99 %)."
    )
    assert raised == []
    assert moving == []
    assert upper_95 < 3.0e-4
