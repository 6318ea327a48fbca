"""Campaign rows made by hand, for the tests of the campaign's log, tables and bounds.

A row as :func:`safety.campaign.run_encounter` would give it for a short run (50 cycles, 40
PROCEED and 10 STOP, 3 m driven, closest approach 1.5 m), with the figures a test varies as
arguments; the tests check bookkeeping (keys, resumption, tables), not a closed loop.
"""

from __future__ import annotations

from collections.abc import Mapping

from safety.campaign import CampaignRow
from safety.campaign_plan import Encounter

__all__ = ["campaign_row"]


def campaign_row(
    encounter: Encounter,
    moving: tuple[float, ...] = (),
    *,
    nuisance: int | None = 4,
    causes: Mapping[str, int] | None = None,
    share: float | None = None,
    route_m: float = 30.0,
) -> CampaignRow:
    """A row for ``encounter`` with a contact at each speed of ``moving`` [m/s] (while moving),
    ``nuisance`` nuisance STOP cycles (None: no shadow oracle) set by ``causes`` (by default
    all but one by a cone, the last by the path's end), progress ``share`` of the oracle's."""
    if causes is None:
        causes = {} if not nuisance else {"zone:CONE": nuisance - 1, "path end": 1}
    return CampaignRow(
        encounter,
        cycles=50,
        commands={"PROCEED": 40, "STOP": 10},
        contacts=len(moving),
        moving_contacts_mps=moving,
        closest_m=1.5,
        progress_m=3.0,
        route_m=route_m,
        cpu_ms={"p50": 10.0, "p99": 20.0, "max": 30.0},
        nuisance_cycles=nuisance,
        nuisance_causes=dict(causes),
        progress_share=share,
    )
