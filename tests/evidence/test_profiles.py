"""What each profile runs (SR-EVD-3): certify-full is certify with the campaigns at full size."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from evidence import profiles


@pytest.fixture
def restore() -> Iterator[None]:
    previous = profiles.active_profile()
    yield
    profiles.set_active_profile(previous)


@pytest.mark.requirement("SR-EVD-3", kind="example", code=["evidence/profiles.py"])
@pytest.mark.parametrize(
    ("name", "certifying", "sized", "unsized", "scaled"),
    [
        ("ci", False, "ci", "ci", 10),
        ("dev", False, "ci", "ci", 5),
        ("certify", True, "certify", "certify", 30),
        ("certify-full", True, "full", "certify", 30),
    ],
)
def test_each_profile_picks_its_campaign_size(
    restore: None, name: str, certifying: bool, sized: str, unsized: str, scaled: int
) -> None:
    profiles.set_active_profile(name)
    assert profiles.certifying() is certifying
    assert profiles.by_profile(ci="ci", certify="certify", full="full") == sized
    assert profiles.by_profile(ci="ci", certify="certify") == unsized
    assert profiles.examples(10) == scaled
    assert profiles.PROFILES["certify-full"] == profiles.PROFILES["certify"]
