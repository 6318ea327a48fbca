"""Session hooks of the property suite: under certify the soaks (SR-RUN-5) start in a worker
beside the suite when collection ends, and their tests run last (:mod:`properties.beside`)."""

from __future__ import annotations

import pytest

from evidence.profiles import active_profile, certifying
from pipeline.config import load_config
from properties import beside
from properties.soak import SOAK_FILE, soak_calls


def _certify_soak(items: list[pytest.Item]) -> bool:
    return certifying() and any(i.path.name == SOAK_FILE for i in items)


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if _certify_soak(items):
        # The soak tests wait for the worker: run them last, when it has had the whole suite.
        items.sort(key=lambda item: item.path.name == SOAK_FILE)


def pytest_collection_finish(session: pytest.Session) -> None:
    if _certify_soak(session.items):
        # The same configuration the safecase_config fixture loads (a bad file has already
        # stopped the session as a usage error by now).
        config = load_config(session.config.getoption("safecase_config"))
        for call, args in soak_calls(config, active_profile()):
            beside.start(call, *args)


def pytest_unconfigure(config: pytest.Config) -> None:
    beside.stop()
