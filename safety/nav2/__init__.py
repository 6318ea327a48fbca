"""Nav2 collision monitor zones, proved or refuted with the project's stopping model (SR-NAV-*).

:mod:`.params` reads and validates a ``collision_monitor`` parameter file (in Nav2's own
reading of it), :mod:`.geometry` measures what a zone gives beyond the robot's footprint,
:mod:`.usage` finds the directions and speeds each zone is in use for, :mod:`.obligations`
writes the claims with :func:`safety.model.stopping.separation_m`, :mod:`.solver` decides them
with z3, :mod:`.verdicts` puts it together into per-zone verdicts, and :mod:`.export` writes the
governor's proved zones as a Nav2 velocity polygon. docs/nav2.md explains the criterion.
"""

from safety.nav2.params import Nav2Params, load_params
from safety.nav2.reader import Nav2ParamsError
from safety.nav2.solver import Verdict
from safety.nav2.usage import Overrides
from safety.nav2.verdicts import EXIT_CODES, LATENCIES, Finding, Report, check

__all__ = [
    "EXIT_CODES",
    "LATENCIES",
    "Finding",
    "Nav2Params",
    "Nav2ParamsError",
    "Overrides",
    "Report",
    "Verdict",
    "check",
    "load_params",
]
