"""Tasks run without a client: here, in submission order, a raise kept as a failure (SR-RUN-8).

The same contract as on a cluster (``properties/test_campaign.py`` checks that one on a
LocalCluster): one outcome per item, at the item's index, a task that raised a
:class:`~pipeline.distributed.TaskFailed` naming the error.
"""

from __future__ import annotations

import pytest

from pipeline.distributed import Done, TaskFailed, as_done, in_order


def _inverse(x: int) -> float:
    if x == 0:
        raise ValueError("no inverse of 0")
    return 1.0 / x


@pytest.mark.requirement("SR-RUN-8", kind="example", code=["pipeline/distributed.py"])
@pytest.mark.parametrize("run", [as_done, in_order])
def test_without_a_client_every_task_runs_here_in_order(run: object) -> None:
    assert callable(run)
    outcomes = list(run(None, _inverse, iter([4, 0, 2])))
    assert outcomes == [
        Done(0, 0.25),
        Done(1, TaskFailed(1, "ValueError: no inverse of 0")),
        Done(2, 0.5),
    ]
