"""``nav2 export`` (SR-NAV-3): the band staircase, its tightness, the refusal of an unproved file.

Every exported velocity polygon is a staircase: bands from standstill to the robot's maximum
speed, each a non-empty speed interval starting where the last ended, each zone deeper than the
one before (a deeper zone for the same speeds is never kept). Tiers whose margins tie or nearly
tie, margins out of tier order and a maximum speed equal to a tier's proved speed are the cases
where a careless staircase would write an empty band or a redundant zone.
"""

from __future__ import annotations

import itertools
from fractions import Fraction
from typing import Any

import pytest

import safety.nav2.export as export
from pipeline.config import SafecaseConfig, config_hash, default_config, overridden
from safety.model.stopping import ClosingClass
from safety.nav2.verdicts import build_model

CODE = ["safety/nav2/export.py"]
STEP = Fraction(1, 10**5)


def _stopping(**updates: Any) -> SafecaseConfig:
    return overridden(default_config(), {"stopping": updates})


def _check_staircase(bands: tuple[export.Band, ...], top_mps: Fraction) -> None:
    assert [b.name for b in bands] == [f"band_{i}" for i in range(len(bands))]
    assert bands[0].low_mps == 0
    assert bands[-1].high_mps == top_mps
    for before, after in itertools.pairwise(bands):
        assert after.low_mps == before.high_mps
        assert after.x_front_m > before.x_front_m
    assert all(b.low_mps < b.high_mps for b in bands)


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
@pytest.mark.parametrize(
    ("updates", "tiers"),
    [
        ({}, ["tier high", "tier medium"]),
        # Equal margins: one band, not an empty second one.
        ({"margin_medium_m": 0.4}, ["tier medium"]),
        # 1 um deeper proves the same speed to 0.01 mm/s: the shallower zone is kept.
        ({"margin_medium_m": 0.400001}, ["tier high"]),
        # Margins out of tier order: the staircase follows speed, not the tier's name.
        ({"margin_high_m": 0.7, "margin_medium_m": 0.4}, ["tier medium", "tier high"]),
        # A tier proved exactly to the maximum speed gives way to the top band.
        ({"robot_max_speed_mps": 0.89617}, ["tier high"]),
    ],
    ids=["default", "equal-margins", "near-equal-margins", "reordered", "tier-at-top-speed"],
)
def test_the_bands_are_a_staircase_of_non_empty_speed_intervals(
    updates: dict[str, float], tiers: list[str]
) -> None:
    config = _stopping(**updates)
    bands = export.export_bands(config)
    _check_staircase(bands, Fraction(repr(config.stopping.robot_max_speed_mps)))
    assert [b.why.split(":")[0] for b in bands[:-1]] == tiers
    assert bands[-1].why.startswith("the maximum speed: separation ")


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
@pytest.mark.parametrize("closing", [ClosingClass.STATIC, ClosingClass.PERSON])
def test_each_band_is_tight_to_one_step(closing: ClosingClass) -> None:
    """A tier's band ends at the largest speed its zone proves (less one step); the top band's
    zone is the shallowest whole 0.01 mm step that proves the maximum speed."""
    config = default_config()
    model, _ = build_model(export._EMPTY, config, latency="project", closing=closing)
    bands = export.export_bands(config, closing)
    top = bands[-1]
    for band in bands[:-1]:
        assert export._proved_speed(model, band.x_front_m, band.half_width_m) == band.high_mps
    proved = export._proved_speed(model, top.x_front_m, top.half_width_m)
    assert proved is not None
    assert proved >= top.high_mps
    shallower = export._proved_speed(model, top.x_front_m - STEP, top.half_width_m)
    assert shallower is None or shallower < top.high_mps
    assert (top.x_front_m / STEP).denominator == 1


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
def test_a_zone_that_proves_no_more_than_one_step_gives_no_band() -> None:
    """Against a static obstacle the robot needs 27.44 mm at standstill (it may be accelerating
    for the whole reaction time). Zones 27.441-27.443 mm deep prove standstill only, 27.444-27.447
    mm one step (0.01 mm/s) which, less the step Nav2's edge needs, is standstill again: no band;
    27.448 mm proves two steps, a band to one step."""
    config = default_config()
    model, _ = build_model(export._EMPTY, config, latency="project", closing=ClosingClass.STATIC)
    front = Fraction(repr(config.geometry.footprint_length_m)) / 2
    half_width = Fraction(repr(config.geometry.footprint_width_m)) / 2 + export.LATERAL_MARGIN_M
    for micrometres in (27440, 27441, 27443, 27444, 27447):
        x_front = front + Fraction(micrometres, 10**6)
        assert export._proved_speed(model, x_front, half_width) is None, micrometres
    x_front = front + Fraction(27448, 10**6)
    assert export._proved_speed(model, x_front, half_width) == STEP


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
def test_the_file_names_the_configuration_it_was_written_from() -> None:
    config = _stopping(margin_high_m=0.5)
    first = export.export_yaml(config).split("\n", 1)[0]
    written_from = f"from the configuration {config_hash(config)[:16]}."
    assert first == f"# Written by `safecase nav2 export` {written_from}"


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
def test_a_file_whose_zones_are_not_proved_is_refused_naming_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Bands sized for a static obstacle, exported for a walking person: check refutes them and
    export writes nothing, naming every band that failed."""
    config = default_config()
    static = export.export_bands(config, ClosingClass.STATIC)
    monkeypatch.setattr(export, "export_bands", lambda *_: static)
    failed = [f"VelocityPolygonStop/band_{i}" for i in range(len(static))]
    with pytest.raises(RuntimeError) as raised:
        export.export_yaml(config, ClosingClass.PERSON)
    assert str(raised.value) == f"nav2 export: the exported zones are not all proved: {failed}"
    # The same bands exported for the static obstacle they were sized for pass.
    assert export.export_yaml(config, ClosingClass.STATIC)


@pytest.mark.requirement("SR-NAV-3", kind="example", code=CODE)
def test_a_malformed_file_from_the_writer_is_refused_naming_export(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(export, "_yaml", lambda *_: "collision_monitor: [")
    with pytest.raises(ValueError, match=r"^export: not valid YAML"):
        export.export_yaml(default_config())
