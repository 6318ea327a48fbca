"""The tests that wait for a beside worker run last (properties/conftest.py): the soaks under
every profile, the campaigns run ahead under certify."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

from evidence.profiles import active_profile, set_active_profile
from pipeline.config import SafecaseConfig
from properties import conftest
from properties.ahead import ahead
from properties.soak import SOAK_FILE


def plain() -> None:
    """A test body that runs in turn."""


@ahead
def campaign(safecase_config: SafecaseConfig) -> None:
    """A campaign body that may run ahead."""


@dataclass
class FakeItem:
    """What the ordering reads of a collected test: its file and its function."""

    name: str
    path: Path
    obj: Any = field(default=plain)


@pytest.fixture
def profile() -> Any:
    """Restore the session's profile after the test sets its own."""
    before = active_profile()
    yield set_active_profile
    set_active_profile(before)


def _items() -> list[FakeItem]:
    return [
        FakeItem("soak", Path("properties") / SOAK_FILE),
        FakeItem("campaign", Path("properties/test_x.py"), campaign),
        FakeItem("first", Path("properties/test_a.py")),
        FakeItem("second", Path("tests/test_b.py")),
    ]


def test_under_certify_campaigns_run_ahead_then_soaks_last(profile: Any) -> None:
    profile("certify")
    items = _items()
    conftest.pytest_collection_modifyitems(None, items)  # type: ignore[arg-type]
    assert [i.name for i in items] == ["first", "second", "campaign", "soak"]


def test_other_profiles_move_only_the_soaks_last(profile: Any) -> None:
    profile("ci")
    items = _items()
    conftest.pytest_collection_modifyitems(None, items)  # type: ignore[arg-type]
    assert [i.name for i in items] == ["campaign", "first", "second", "soak"]
