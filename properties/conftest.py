"""Session hooks of the property suite: when collection ends, the soaks (SR-RUN-5) start in
workers beside the suite (:mod:`properties.beside`) under every profile, and under certify the
bodies of the campaigns decorated with :func:`properties.ahead.ahead` too; the tests that wait
for them run last: the campaigns, then the soaks.

A soak measures its own process's resident memory, so it never runs in the test session's,
whose heap, as the earlier tests left it (fragmented, trimmed), would add growth of its own to
the runtime's."""

from __future__ import annotations

import pytest

from evidence.plugin_xdist import worker_id
from evidence.profiles import active_profile, certifying
from pipeline.config import load_config
from properties import ahead, beside
from properties.soak import SOAK_FILE, soak_calls


def _waits(item: pytest.Item) -> int:
    """0 for a test that runs in turn, 1 for a campaign run ahead (certify), 2 for a soak."""
    if item.path.name == SOAK_FILE:
        return 2
    return 1 if certifying() and ahead.is_ahead(getattr(item, "obj", None)) else 0


@pytest.hookimpl(trylast=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if worker_id(config) is not None:
        return  # under pytest-xdist nothing is started beside the suite (below): no waiting
    # The tests that wait for a worker run last, when it has had the rest of the suite.
    items.sort(key=_waits)


def pytest_collection_finish(session: pytest.Session) -> None:
    if worker_id(session.config) is not None:
        # Under pytest-xdist every worker collects the whole suite but runs only its share, and
        # the workers already use the cores: each waiting test runs its body where it lands.
        return
    waiting = [item for item in session.items if _waits(item)]
    if not waiting:
        return
    # The same configuration the safecase_config fixture loads (a bad file has already
    # stopped the session as a usage error by now).
    config = load_config(session.config.getoption("safecase_config"))
    if any(_waits(item) == 2 for item in waiting):
        for call, args in soak_calls(config, active_profile()):
            beside.start(call, *args)
    for item in waiting:
        if _waits(item) == 1:
            if hasattr(item, "callspec"):
                raise pytest.UsageError(f"{item.nodeid}: a parametrized test cannot run ahead")
            ahead.start(getattr(item, "obj"), config)  # noqa: B009 (a Function item)


def pytest_unconfigure(config: pytest.Config) -> None:
    beside.stop()
