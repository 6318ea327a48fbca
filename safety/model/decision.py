"""The decision step of one cycle: governor, monitors, fold (SR-AUD-2, SR-FUS-2, SR-TIM-2).

:func:`decide` is what the runtime runs once the perception stages are done, and what
:func:`safety.audit.replay.replay` re-runs from an audit log: the governor's command for the
recorded
:class:`GovernorInputs`, every monitor's verdict on the recorded
:class:`~safety.model.monitors.Observation`, plus the STOP verdicts the runtime raised for stages
that failed, folded by :func:`~safety.model.monitors.combine`. Everything it reads is recorded, so
the command can be recomputed from the log alone.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.config import MonitorSection
from pipeline.jsoncodec import float_to_json, floats_from_json, floats_to_json
from pipeline.types import Action, BoolArray, Command, FloatArray
from safety.model.governor import Governor
from safety.model.monitors import MonitorVerdict, Observation, combine, run_monitors

__all__ = [
    "Decision",
    "GovernorInputs",
    "command_from_dict",
    "command_to_dict",
    "decide",
]


def command_to_dict(command: Command) -> dict[str, Any]:
    """A command as JSON-ready values."""
    return {
        "action": command.action.value,
        "speed_mps": command.speed_mps,
        "stamp_s": float_to_json(command.stamp_s),
        "reasons": list(command.reasons),
    }


def command_from_dict(data: Mapping[str, Any]) -> Command:
    """Inverse of :func:`command_to_dict`."""
    return Command(
        Action(data["action"]),
        float(data["speed_mps"]),
        float(data["stamp_s"]),
        tuple(str(r) for r in data["reasons"]),
    )


@dataclass(frozen=True, slots=True)
class GovernorInputs:
    """Per-obstacle inputs of :meth:`safety.model.governor.Governor.command` for one cycle.

    One entry per obstacle (tracks and thermal-only pedestrians alike): free distance along
    the path [m], closing speed [m/s] (None: the worst class's), classification confidence in
    [0, 1] (None: unknown, the most cautious tier) and near-reversal flag (None: False).
    """

    stamp_s: float
    free_distance_m: FloatArray
    closing_speed_mps: FloatArray | None = None
    confidence: FloatArray | None = None
    near_reversal: BoolArray | None = None

    def command(self, governor: Governor) -> Command:
        """The governor's command for these inputs (never raises)."""
        return governor.command(
            self.stamp_s,
            self.free_distance_m,
            self.closing_speed_mps,
            self.confidence,
            self.near_reversal,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form; absent arrays as None, non-finite floats as text."""

        def opt(values: npt.ArrayLike | None) -> list[float | str] | None:
            return None if values is None else floats_to_json(values)

        return {
            "stamp_s": floats_to_json([self.stamp_s])[0],
            "free_distance_m": floats_to_json(self.free_distance_m),
            "closing_speed_mps": opt(self.closing_speed_mps),
            "confidence": opt(self.confidence),
            "near_reversal": (
                None
                if self.near_reversal is None
                else [bool(v) for v in np.asarray(self.near_reversal).ravel()]
            ),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> GovernorInputs:
        """Inverse of :meth:`to_dict`."""

        def opt(values: Sequence[float | str] | None) -> FloatArray | None:
            return None if values is None else floats_from_json(values)

        flags = data["near_reversal"]
        return cls(
            stamp_s=float(data["stamp_s"]),
            free_distance_m=floats_from_json(data["free_distance_m"]),
            closing_speed_mps=opt(data["closing_speed_mps"]),
            confidence=opt(data["confidence"]),
            near_reversal=None if flags is None else np.array(flags, dtype=bool),
        )


@dataclass(frozen=True, slots=True)
class Decision:
    """The outcome of :func:`decide`: final command, the governor's own command (None when no
    governor inputs existed) and every verdict (monitors first, then stage failures)."""

    command: Command
    governor_command: Command | None
    verdicts: tuple[MonitorVerdict, ...]


def decide(
    governor: Governor,
    inputs: GovernorInputs | None,
    observation: Observation,
    monitors: MonitorSection,
    stage_verdicts: Sequence[MonitorVerdict] = (),
) -> Decision:
    """One cycle's decision (SR-FUS-2, SR-TIM-2, SR-AUD-2); never raises.

    ``inputs`` is None when a perception stage failed before the governor could run (the
    runtime then passes a STOP verdict for that stage in ``stage_verdicts``).
    """
    governor_command = None if inputs is None else inputs.command(governor)
    verdicts = (*run_monitors(observation, monitors), *stage_verdicts)
    command = combine(
        governor_command,
        verdicts,
        stamp_s=observation.now_s,
        min_moving_mps=governor.min_moving_mps,
    )
    return Decision(command, governor_command, verdicts)
