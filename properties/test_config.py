"""Configuration properties (requirement family SR-CFG-*)."""

from __future__ import annotations

import math
from random import Random
from typing import Any

import numpy as np
import pytest
from hypothesis import given, reject, settings
from hypothesis import strategies as st
from pydantic import BaseModel

from evidence.profiles import examples
from evidence.record import current
from pipeline.classify.model import Classifier
from pipeline.compat import tomllib
from pipeline.config import (
    SafecaseConfig,
    config_hash,
    default_config,
    to_toml,
    validate_config,
)
from pipeline.errors import ConfigError
from pipeline.types import Scan, ThermalDetections
from properties.strategies import (
    NUMERIC_FIELDS,
    ConfigField,
    config_fields,
    out_of_range_value,
    valid_value,
)
from safety.runtime import CycleInput, Runtime


@pytest.mark.requirement("SR-CFG-1")
@given(data=st.data(), field=config_fields())
def test_out_of_range_values_are_rejected_naming_key_value_and_range(
    data: st.DataObject, field: ConfigField
) -> None:
    value = data.draw(out_of_range_value(field), label="value")
    with pytest.raises(ConfigError) as caught:
        validate_config({field.section: {field.key: value}}, origin="t.toml")
    lines = caught.value.lines
    assert len(lines) == 1, lines
    line = lines[0]
    assert line.startswith("t.toml: ")
    assert field.dotted in line
    shown = repr(value) if not (isinstance(value, float) and math.isnan(value)) else "nan"
    assert shown in line, (shown, line)
    assert "allowed:" in line


@pytest.mark.requirement("SR-CFG-1")
@given(field=config_fields(), name=st.from_regex(r"[a-z][a-z_]{0,12}", fullmatch=True))
def test_unknown_keys_are_rejected_with_the_allowed_keys(field: ConfigField, name: str) -> None:
    section_model = SafecaseConfig.model_fields[field.section].annotation
    assert isinstance(section_model, type)
    assert issubclass(section_model, BaseModel)
    if name in section_model.model_fields:
        reject()
    with pytest.raises(ConfigError) as caught:
        validate_config({field.section: {name: 1.0}}, origin="t.toml")
    (line,) = caught.value.lines
    assert f"unknown key {field.section}.{name};" in line
    assert field.key in line  # the allowed keys are listed


def _dump() -> dict[str, dict[str, Any]]:
    return default_config().model_dump(mode="json")


@pytest.mark.requirement("SR-CFG-2")
@given(rng=st.randoms(use_true_random=False), pad=st.sampled_from([" = ", "=", "    =\t"]))
def test_hash_ignores_key_order_and_formatting(rng: Random, pad: str) -> None:
    dump = _dump()
    sections = list(dump)
    rng.shuffle(sections)
    shuffled: dict[str, dict[str, Any]] = {}
    for section in sections:
        keys = list(dump[section])
        rng.shuffle(keys)
        shuffled[section] = {k: dump[section][k] for k in keys}
    text = to_toml(shuffled).replace(" = ", pad)
    reloaded = validate_config(tomllib.loads(text))
    assert config_hash(reloaded) == config_hash(default_config())


@pytest.mark.requirement("SR-CFG-2")
@given(data=st.data(), field=config_fields())
def test_changing_any_value_changes_the_hash(data: st.DataObject, field: ConfigField) -> None:
    base = default_config()
    old = getattr(getattr(base, field.section), field.key)
    new = data.draw(valid_value(field).filter(lambda v: v != old), label="new")
    try:
        changed = validate_config({field.section: {field.key: new}})
    except ConfigError:
        reject()  # the new value conflicts with a paired key (e.g. min above max)
    assert config_hash(changed) != config_hash(base)
    assert config_hash(changed) == config_hash(validate_config({field.section: {field.key: new}}))


@pytest.mark.requirement("SR-CFG-1", kind="example")
def test_inconsistent_pairs_are_named() -> None:
    with pytest.raises(ConfigError) as caught:
        validate_config({"stopping": {"decel_min_mps2": 3.0, "decel_max_mps2": 2.0}}, "f.toml")
    assert caught.value.lines == [
        "f.toml: stopping.decel_min_mps2 (3.0) must not exceed stopping.decel_max_mps2 (2.0)"
    ]


def test_defaults_are_valid_and_frozen() -> None:
    config = default_config()
    with pytest.raises(ValueError, match="frozen"):
        config.cluster.eps_m = 1.0  # type: ignore[misc]
    assert config == SafecaseConfig()


@pytest.fixture(scope="module")
def classifier() -> Classifier:
    """The packaged model, loaded once (the property changes one key at a time)."""
    return Classifier.from_config(default_config().classify)


def _room_scan() -> Scan:
    """A 360-beam scan of a 6 m x 4 m room around the scanner, a box 2 m ahead."""
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    c, s = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore"):
        walls = np.minimum(np.abs(3.0 / c), np.abs(2.0 / s))
    box = (np.abs(angles) < 0.12) * 2.0
    return Scan(10.0, angles, np.where(box > 0, box, walls))


@pytest.mark.requirement("SR-CFG-1", kind="property", code=["pipeline/config/__init__.py"])
@pytest.mark.parametrize("field", NUMERIC_FIELDS, ids=lambda f: f.dotted)
@settings(max_examples=examples(8), deadline=None)
@given(data=st.data())
def test_a_configuration_that_loads_runs_and_one_that_does_not_is_refused_at_load(
    data: st.DataObject, field: ConfigField, classifier: Classifier
) -> None:
    """Every cross-section rule is checked when the configuration loads: a configuration that
    loads never makes a cycle fail on itself (only a scan over ``scan.max_beams`` may), and
    thermal-only pedestrians keep the most cautious margin tier (SR-FUS-3)."""
    value = data.draw(valid_value(field), label="value")
    try:
        config = validate_config({field.section: {field.key: value}}, origin="t.toml")
    except ConfigError as exc:
        refused = exc.lines
    else:
        refused = []
    if refused:
        current().count("single-key changes", "refused at load")
        assert all(line.startswith("t.toml: ") for line in refused), refused
        return
    current().count("single-key changes", "loaded and ran")
    runtime = Runtime(config, classifier=classifier)
    person = ThermalDetections(np.array([10.05]), np.array([1.0]), np.array([0.3]), np.ones(1))
    out = runtime.step(
        CycleInput.standing(_room_scan(), 10.1, config, charge_s=0.01, thermal=person)
    )
    failed = [r for r in out.command.reasons if r.startswith("stage:")]
    assert all(r.startswith("stage:points: ScanError") for r in failed), (field.dotted, failed)
    # A thermal-only pedestrian's confidence falls in the tier of no confidence at all.
    no = np.zeros(1, dtype=bool)
    ped = np.array([config.fusion.thermal_only_confidence])
    assert (
        runtime.envelopes.margins(ped, no)[1][0] == runtime.envelopes.margins(np.zeros(1), no)[1][0]
    )
