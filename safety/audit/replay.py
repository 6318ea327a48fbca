"""Replay of an audit log: recompute every decision from the recorded inputs (SR-AUD-2).

The header holds the whole configuration (its hash is checked) and the latency bound the
governor ran with; each cycle record holds the monitors' observation, the governor's inputs
and the STOP verdicts of stages that failed. :func:`replay` rebuilds the governor, runs
:func:`safety.model.decision.decide` on every recorded cycle and compares the governor's command,
every verdict and the final command with what was recorded, exactly (floats bit for bit).
A log is verified first; a tampered or empty log is not replayed (it would prove nothing). A
record whose recorded values cannot be decoded or decided on (a re-chained, unsigned log can
hold anything of the right shape) is reported as a mismatch of its line, never raised.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PublicKey

from pipeline.config import SafecaseConfig, config_hash, validate_config
from pipeline.errors import ConfigError, SafecaseError
from safety.audit.log import AuditError
from safety.audit.verify import AuditStatus, AuditVerification, iter_records, verify_log
from safety.model.decision import GovernorInputs, command_to_dict, decide
from safety.model.governor import Governor
from safety.model.monitors import DEFAULT_MONITORS, MonitorVerdict, Observation
from safety.model.stopping import StoppingParams

__all__ = ["ReplayMismatch", "ReplayReport", "governor_for", "replay"]

_MONITOR_NAMES = frozenset(name for name, _ in DEFAULT_MONITORS)


@dataclass(frozen=True, slots=True)
class ReplayMismatch:
    """A recorded value the replay did not reproduce."""

    line: int
    seq: int
    what: str
    recorded: Any
    replayed: Any


@dataclass
class ReplayReport:
    """What :func:`replay` found: ``ok`` when every cycle was reproduced exactly."""

    verification: AuditVerification
    n_cycles: int = 0
    n_reproduced: int = 0
    mismatches: list[ReplayMismatch] = field(default_factory=list)
    refused: str = ""

    @property
    def ok(self) -> bool:
        """True when the log was replayable and every cycle was reproduced."""
        return not self.refused and not self.mismatches and self.n_reproduced == self.n_cycles


def governor_for(header: dict[str, Any]) -> tuple[SafecaseConfig, Governor]:
    """The configuration and governor a log's header describes (config hash checked).

    Raises :class:`~safety.audit.log.AuditError` when the header's configuration does not load
    or does not hash to the recorded hash."""
    try:
        config = validate_config(header["config"], origin="audit header")
    except (ConfigError, RecursionError) as exc:
        raise AuditError(f"audit header: configuration does not load: {exc}") from None
    if config_hash(config) != header["config_hash"]:
        raise AuditError(
            f"audit header: configuration hashes to {config_hash(config)[:16]}, the header "
            f"records {str(header['config_hash'])[:16]}"
        )
    latency = header["latency"]
    try:
        params = StoppingParams.from_config(
            config,
            perception_latency_s=float(latency["perception_latency_s"]),
            latency_source=str(latency["latency_source"]),
        )
        return config, Governor.from_config(config, params)
    except (ArithmeticError, SafecaseError, ValueError) as exc:
        raise AuditError(f"audit header: latency bound unusable: {exc}") from None


def _compare(
    report: ReplayReport, number: int, record: dict[str, Any], replayed: dict[str, Any]
) -> None:
    before = len(report.mismatches)
    for key, value in replayed.items():
        if record.get(key) != value:
            report.mismatches.append(
                ReplayMismatch(number, record["seq"], key, record.get(key), value)
            )
    if len(report.mismatches) == before:
        report.n_reproduced += 1


def replay(
    path: Path | str,
    *,
    trusted_key: Ed25519PublicKey | None = None,
    require_anchor: bool = True,
) -> ReplayReport:
    """Verify the log at ``path``, then recompute every recorded decision (SR-AUD-2)."""
    verification = verify_log(path, trusted_key=trusted_key, require_anchor=require_anchor)
    report = ReplayReport(verification)
    if verification.status is AuditStatus.TAMPERED:
        report.refused = f"not replayed: the log is tampered ({verification.describe()})"
        return report
    if verification.header is None:
        report.refused = "not replayed: the log has no header (not an audit log)"
        return report
    config, governor = governor_for(verification.header)
    for number, record in iter_records(path, verification.n_records):
        if record["kind"] != "cycle":
            continue
        report.n_cycles += 1
        try:
            observation = Observation.from_dict(record["observation"])
            inputs = (
                None
                if record["governor_inputs"] is None
                else GovernorInputs.from_dict(record["governor_inputs"])
            )
            stage = [
                MonitorVerdict.from_dict(v)
                for v in record["verdicts"]
                if v["monitor"] not in _MONITOR_NAMES
            ]
        except (KeyError, TypeError, ValueError, ArithmeticError) as exc:
            # A key missing, a list where a mapping was recorded or the other way round: no
            # runtime wrote it.
            report.mismatches.append(
                ReplayMismatch(number, record["seq"], "inputs", "undecodable", repr(exc)[:200])
            )
            continue
        try:
            decision = decide(governor, inputs, observation, config.monitors, stage)
        except (TypeError, ValueError, ArithmeticError, SafecaseError) as exc:
            # Recorded values of the right shape that no runtime cycle can have produced.
            report.mismatches.append(
                ReplayMismatch(number, record["seq"], "decision", "recorded", repr(exc)[:200])
            )
            continue
        gov = decision.governor_command
        _compare(
            report,
            number,
            record,
            {
                "governor_command": None if gov is None else command_to_dict(gov),
                "verdicts": [v.to_dict() for v in decision.verdicts],
                "command": command_to_dict(decision.command),
            },
        )
    return report
