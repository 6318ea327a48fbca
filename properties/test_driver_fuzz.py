"""The fuzz campaign over the serial stream decoders, as evidence (SR-DRV-2, SR-DRV-3).

One seeded campaign per protocol (RPLIDAR standard nodes, RPLIDAR express capsules, SCIP 2.0
MD/GD): single-frame mutations (bit flip, truncation, dropped, duplicated and swapped frames,
garbage) of clean device streams, decoded by the driver's stream decoders, every emitted beam
judged against what was encoded (:mod:`properties.fuzz_campaign`). ``certify-full`` runs
:data:`FULL_MUTATIONS` mutated frames per protocol, ``certify`` :data:`CERTIFY_MUTATIONS`,
``ci`` :data:`CI_MUTATIONS`.
Reproduce: ``MPLBACKEND=Agg .venv/bin/python -m pytest -q -p no:cacheprovider
--hypothesis-profile=certify-full properties/test_driver_fuzz.py``.
"""

from __future__ import annotations

import os
import time

import pytest

from evidence.profiles import active_profile, by_profile
from evidence.record import Recorder
from pipeline.sources.serial.rplidar_stream import RplidarStream
from properties.fuzz_campaign import SILENT_LOSS, UNDETECTABLE, ClassFigures, run_sharded
from properties.fuzz_cases import (
    MUTATIONS,
    MUTATIONS_PER_REVOLUTION,
    PROTOCOLS,
    Mutation,
    Protocol,
)

CODE = [
    "pipeline/sources/serial/rplidar_stream.py",
    "pipeline/sources/serial/scip_stream.py",
    "pipeline/sources/serial/assembly.py",
    "pipeline/sources/serial/rplidar_capsule.py",
    "pipeline/sources/serial/scip.py",
]
FULL_MUTATIONS = 1_000_000  # mutated frames per protocol
CERTIFY_MUTATIONS = 250_000
CI_MUTATIONS = 6_000
SHARDS = 8  # independent seeded sub-campaigns: the figures depend on this, not on WORKERS
WORKERS = max(1, min(SHARDS, os.cpu_count() or 1))
SEEDS: dict[Protocol, int] = {"rplidar-standard": 6101, "rplidar-express": 6102, "scip": 6103}
COLUMNS = [
    "mutation",
    "mutations",
    "frames decoded",
    "scans emitted / clean",
    "marked incomplete",
    "revolutions rejected",
    "frames rejected",
    "wrong-angle beams",
    "never-sent beams",
    "wrong beams in complete scans",
    "wrong beams per mutation",
    "scans with wrong data per mutation",
    "complete scans missing beams",
    "beams repeated in a scan",
    "wrong beams the protocol could have rejected",
    "wrong beams from a forged frame (streams)",
    "max angle error deg",
    "decoder frames/s",
]


def _row(mutation: str, f: ClassFigures) -> list[object]:
    return [
        mutation,
        f.mutations,
        f.frames,
        f"{f.scans_emitted} / {f.scans_clean}",
        f.scans_incomplete,
        f.revolutions_rejected,
        f.frames_rejected,
        f.wrong_angle,
        f.never_sent,
        f.wrong_in_complete,
        f"{(f.wrong_angle + f.never_sent) / max(1, f.mutations):.2e}",
        f"{f.scans_with_wrong / max(1, f.mutations):.2e}",
        f.complete_missing,
        f.repeated,
        f.unexplained,
        f"{f.forged_wrong} ({f.forged_streams})",
        round(f.max_angle_error_deg, 3),
        round(f.frames / max(f.decode_s, 1e-9)),
    ]


def _limits(protocol: Protocol, figures: dict[str, ClassFigures]) -> str:
    """The protocol's limits as measured: which undetectable mutations left wrong data or a
    complete scan short of beams, per mutation."""
    parts = []
    for name, f in figures.items():
        wrong = f.wrong_angle + f.never_sent
        if wrong or f.complete_missing:
            parts.append(
                f"{name}: {wrong} wrong beams in {f.mutations} mutations "
                f"({wrong / f.mutations:.2e} per mutation; {f.wrong_angle} at a wrong angle, "
                f"{f.never_sent} with a value never sent, {f.wrong_in_complete} in scans marked "
                f"complete; {f.scans_with_wrong} scans affected, "
                f"{f.scans_with_wrong / f.mutations:.2e} per mutation); "
                f"{f.complete_missing} complete scans short of beams "
                f"({f.complete_missing / f.mutations:.2e} per mutation)"
                + (
                    f"; {f.forged_wrong} of the wrong beams in {f.forged_streams} streams "
                    "holding a frame forged by chance (every check passing)"
                    if f.forged_wrong
                    else ""
                )
            )
    if not parts:
        return f"{protocol}: no mutation left a wrong beam or a silently short scan"
    return f"{protocol} limits (undetectable by the protocol): " + "; ".join(parts)


@pytest.mark.requirement("SR-DRV-2", "SR-DRV-3", kind="campaign", code=CODE)
@pytest.mark.parametrize("protocol", PROTOCOLS)
def test_fuzz_campaign_emits_no_beam_the_protocol_could_reject(
    protocol: Protocol, evidence: Recorder
) -> None:
    total = by_profile(ci=CI_MUTATIONS, certify=CERTIFY_MUTATIONS, full=FULL_MUTATIONS)
    started = time.perf_counter()
    figures = run_sharded(
        protocol, -(-total // len(MUTATIONS)), SEEDS[protocol], shards=SHARDS, workers=WORKERS
    )
    wall_s = time.perf_counter() - started
    summed = sum(figures.values(), ClassFigures())
    named = {m.value: f for m, f in figures.items()}
    evidence.table(
        f"fuzz campaign {protocol}",
        COLUMNS,
        [_row(name, f) for name, f in named.items()],
        caption=f"seed {SEEDS[protocol]} in {SHARDS} shards, profile {active_profile()}: "
        f"{summed.mutations} single-frame mutations, {MUTATIONS_PER_REVOLUTION[protocol]} "
        f"per revolution's frames, in {wall_s:.1f} s on {WORKERS} processes "
        f"({summed.mutations / wall_s:.0f} mutations/s; one decoder "
        f"{summed.frames / summed.decode_s:.0f} frames/s). A beam is recognised by its "
        "distance, unique per batch; a corrupted value equal to another sent distance counts "
        "as a wrong angle, so the angle error bounds a misplacement only where one flipped "
        "bit cannot turn one sent distance into another (bit flips).",
    )
    evidence.counts(
        f"fuzz {protocol}",
        {
            "mutated frames": summed.mutations,
            "frames decoded": summed.frames,
            "scans emitted": summed.scans_emitted,
            "scans marked incomplete": summed.scans_incomplete,
            "revolutions rejected": summed.revolutions_rejected,
            "wrong-angle beams": summed.wrong_angle,
            "never-sent beams": summed.never_sent,
            "wrong beams the protocol could have rejected": summed.unexplained,
            "wrong beams from a forged frame": summed.forged_wrong,
            "streams with a forged frame and wrong beams": summed.forged_streams,
            "wall s": round(wall_s, 1),
        },
    )
    evidence.note(_limits(protocol, named))
    max_step_deg = RplidarStream().max_step_q6 / 64
    for mutation, f in figures.items():
        # Every wrong beam comes from what the protocol cannot detect: a check-passing
        # standard-node window, a forged frame, or two swapped SCIP lines.
        assert f.unexplained == 0, (protocol, mutation)
        assert f.repeated == 0, (protocol, mutation)
        if mutation not in UNDETECTABLE[protocol]:
            # Only a frame forged by chance (every check passing, never sent) may carry
            # wrong data: the checksum's limit, counted and stated with its rate.
            assert f.wrong_angle + f.never_sent == f.forged_wrong, (protocol, mutation)
        if mutation not in SILENT_LOSS[protocol]:
            assert f.complete_missing == 0, (protocol, mutation)
        if protocol == "rplidar-standard" and mutation is Mutation.BIT_FLIP:
            # A flipped angle bit passes only within the step check: never further off.
            assert f.max_angle_error_deg <= max_step_deg, mutation
