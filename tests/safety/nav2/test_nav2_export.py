"""``nav2 export`` (SR-NAV-3): the governor's tiers as a Nav2 velocity polygon that check proves."""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import pytest

from pipeline.config import default_config, load_config
from safety.model.stopping import ClosingClass
from safety.nav2 import Verdict, check
from safety.nav2.export import LATERAL_MARGIN_M, _decimal, export_bands, export_yaml
from safety.nav2.params import parse_params

ROOT = Path(__file__).resolve().parents[3]
CODE = ["safety/nav2/export.py"]


def test_the_example_file_is_what_export_writes_for_the_built_in_configuration() -> None:
    written = (ROOT / "examples" / "nav2" / "exported.yaml").read_text()
    # Stale? Regenerate: safecase nav2 export --out examples/nav2/exported.yaml
    # (the first line names the configuration's hash, which changes with any new key).
    assert written.split("\n", 1)[1] == export_yaml(default_config()).split("\n", 1)[1]


def test_bands_follow_the_tiers_and_end_at_the_maximum_speed() -> None:
    config = default_config()
    bands = export_bands(config)
    front = Fraction("0.45")
    # High (0.4 m) and medium (0.7 m) tiers, then a band to 1 m/s; the near-reversal tier
    # (1.0 m) covers a static obstacle beyond 1 m/s and gives way to the tighter top band.
    assert [b.x_front_m - front for b in bands[:2]] == [Fraction("0.4"), Fraction("0.7")]
    assert [b.low_mps for b in bands] == [0, bands[0].high_mps, bands[1].high_mps]
    assert bands[-1].high_mps == 1
    assert Fraction("0.592") <= bands[0].high_mps < Fraction("0.5924")
    assert all(b.half_width_m == Fraction("0.3") + LATERAL_MARGIN_M for b in bands)


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
@pytest.mark.parametrize("closing", list(ClosingClass), ids=lambda c: c.value)
@pytest.mark.parametrize("name", ["default", "source-warehouse"])
def test_export_then_check_proves_every_band(name: str, closing: ClosingClass) -> None:
    config = (
        default_config() if name == "default" else load_config(ROOT / "examples" / f"{name}.toml")
    )
    text = export_yaml(config, closing)
    report = check(parse_params(text), config, closing=closing)
    assert report.verdict is Verdict.PROVED
    assert all(f.verdict is Verdict.PROVED for f in report.findings)


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
def test_a_value_is_written_as_its_exact_decimal() -> None:
    """Every value in the exported file is written in full: sign, whole part, the fewest
    fraction digits that are exact (at least one), up to 30; a value with no such decimal is
    refused naming it."""
    cases = {
        Fraction(0): "0.0",
        Fraction(3): "3.0",
        Fraction(120): "120.0",
        Fraction(1, 8): "0.125",
        Fraction(-1, 2): "-0.5",
        Fraction(-5, 4): "-1.25",
        Fraction(1005, 100): "10.05",
        Fraction(1, 10**30): "0." + "0" * 29 + "1",
    }
    for value, text in cases.items():
        assert _decimal(value) == text, value
        assert Fraction(text) == value
    for value in (Fraction(1, 10**31), Fraction(1, 3)):
        with pytest.raises(ValueError, match=f"^{value} has no short decimal form$"):
            _decimal(value)
