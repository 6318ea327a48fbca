"""The seeded fuzz campaign over the serial stream decoders and its judge (SR-DRV-2, SR-DRV-3).

:func:`run_campaign` mutates copies of clean batches (:mod:`properties.fuzz_cases`), decodes
them with the driver's stream decoders and judges every emitted beam against the truth:

* *wrong angle*: its distance was sent, at another angle (or a no-return where none was);
* *never sent*: no beam with its value was sent at all (a corrupted value).

A wrong beam is *explained* when the protocol cannot tell it from a sent one: it comes from a
5-byte window of the received bytes that passes a standard node's check bits, or the stream
holds an express capsule or SCIP line that passes its checksum but was never sent (a forged
frame), or two SCIP lines were swapped (:data:`UNDETECTABLE`). Anything else is a decoder
defect and is counted as *unexplained*.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, fields

import numpy as np
import numpy.typing as npt
from numpy.lib.stride_tricks import sliding_window_view

from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial.rplidar_capsule import CAPSULE_BYTES, capsule_validity
from pipeline.types import Scan
from properties.fuzz_cases import (
    MUTATIONS,
    MUTATIONS_PER_REVOLUTION,
    Batch,
    Mutation,
    Protocol,
    decode_stream,
    make_batch,
    mutate,
)
from properties.oracles.drivers import checked_scip_lines

__all__ = [
    "SILENT_LOSS",
    "UNDETECTABLE",
    "BeamJudgement",
    "ClassFigures",
    "judge_scans",
    "run_campaign",
    "run_sharded",
]

I64Array = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

# Mutations after which a protocol cannot always tell wrong data from sent data, by its
# design. A standard node has three check bits and no checksum: a flipped bit can pass them,
# and after any rejection (or inserted bytes) the stream may realign onto windows that pass
# them; a dropped node leaves no trace at all. SCIP 2.0 lines carry no sequence number: two
# swapped lines of equal length keep every count, length and checksum. Express capsules:
# only a forged capsule (sync nibbles and 8-bit XOR passing by chance) could.
UNDETECTABLE: dict[Protocol, tuple[Mutation, ...]] = {
    "rplidar-standard": MUTATIONS,
    "rplidar-express": (),
    "scip": (Mutation.SWAP,),
}
# Mutations that may leave a scan marked complete yet short of beams: a dropped standard
# node, and the standard-node realignments above (a forged start flag cuts a revolution).
SILENT_LOSS: dict[Protocol, tuple[Mutation, ...]] = {
    "rplidar-standard": MUTATIONS,
    "rplidar-express": (),
    "scip": (),
}


@dataclass(frozen=True, slots=True)
class BeamJudgement:
    """Every emitted beam judged against the truth: how many there were, how many sit at an
    angle they were not sent at, how many hold a value never sent, how many of those two
    lie in scans marked complete, how many scans hold any, how many complete scans have
    fewer beams than a revolution, how many beams repeat one of the same scan, and the
    largest angle error (degrees) of a beam recognised by its distance."""

    beams: int = 0
    wrong_angle: int = 0
    never_sent: int = 0
    wrong_in_complete: int = 0
    scans_with_wrong: int = 0
    complete_missing: int = 0
    repeated: int = 0
    max_angle_error_deg: float = 0.0


def _keys(batch: Batch, scan: Scan) -> tuple[I64Array, I64Array, I64Array]:
    """Angle key, value key and identity of each beam of ``scan``."""
    if batch.protocol == "scip":
        assert batch.params is not None
        angle = np.rint(scan.angles_rad / batch.params.step_rad).astype(np.int64)
        angle += batch.params.afrt
        mm = np.rint(np.nan_to_num(scan.ranges_m, nan=0.0) * 1000.0).astype(np.int64)
        return angle, mm, mm
    angle = np.mod(np.rint(-np.rad2deg(scan.angles_rad) * 64.0).astype(np.int64), rp.Q6_PER_TURN)
    q2 = np.rint(np.nan_to_num(scan.ranges_m, nan=0.0) * 4000.0).astype(np.int64)
    if batch.protocol == "rplidar-standard":
        assert scan.intensities is not None
        return angle, (q2 << 6) | scan.intensities.astype(np.int64), q2
    return angle, q2, q2


def _member(sorted_keys: I64Array, keys: I64Array) -> tuple[BoolArray, I64Array]:
    if sorted_keys.shape[0] == 0:
        return np.zeros(keys.shape, dtype=np.bool_), np.zeros(keys.shape, dtype=np.int64)
    at = np.minimum(np.searchsorted(sorted_keys, keys), sorted_keys.shape[0] - 1)
    found: BoolArray = sorted_keys[at] == keys
    return found, at


def _wrong_beams(
    batch: Batch, angle: I64Array, value: I64Array, ident: I64Array, owner: I64Array
) -> tuple[BoolArray, BoolArray, float]:
    """Per beam (given by its keys and the index of its scan): at a wrong angle, holding a
    value never sent; and the largest angle error (degrees) of a moved beam.

    A beam is *moved* when its distance was sent in the revolution its scan mostly holds,
    at another angle. A distance sent in another revolution counts as never sent here: a
    corrupted value may coincide with one, and no revolution sent it at this angle."""
    truth = batch.truth
    sent, _ = _member(truth.pairs, (angle << 32) | value)
    none = np.zeros(angle.shape, dtype=np.bool_)
    if bool(np.all(sent)):
        return none, none, 0.0
    known, at = _member(truth.idents, ident)
    known &= ident > 0
    revolution = truth.ident_revolutions[at]
    votes = np.zeros((int(owner.max()) + 1, int(truth.ident_revolutions.max()) + 1), np.int64)
    np.add.at(votes, (owner[known & sent], revolution[known & sent]), 1)
    own = np.where(votes.sum(axis=1) > 0, np.argmax(votes, axis=1), -1)[owner]
    true_angle = truth.ident_angles[at]
    moved = known & ~sent & (revolution == own) & (true_angle != angle)
    # A no-return where nothing was sent at that angle is a beam at a wrong angle too.
    stray = ~sent & (ident == 0) & ~_member(truth.angles, angle)[0]
    wrong = moved | stray
    worst = 0.0
    if bool(np.any(moved)):
        error = np.abs(angle[moved] - true_angle[moved]) % truth.turn
        worst = float(np.max(np.minimum(error, truth.turn - error))) * truth.unit_deg
    return wrong, ~sent & ~wrong, worst


def judge_scans(batch: Batch, scans: Sequence[Scan]) -> BeamJudgement:
    """Judge every beam of ``scans`` against ``batch``'s truth (SR-DRV-2)."""
    if not scans:
        return BeamJudgement()
    keys = [_keys(batch, scan) for scan in scans]
    angle, value, ident = (np.concatenate([k[i] for k in keys]) for i in range(3))
    sizes = np.array([scan.n_beams for scan in scans], dtype=np.int64)
    owner = np.repeat(np.arange(len(scans), dtype=np.int64), sizes)
    complete = np.array([scan.complete for scan in scans], dtype=np.bool_)
    wrong, never, worst = _wrong_beams(batch, angle, value, ident, owner)
    bad_per_scan = np.bincount(owner[wrong | never], minlength=len(scans))
    # A beam repeated within one scan: its (scan, angle, value) occurs twice.
    tagged = (owner << 48) | (angle << 32) | value
    return BeamJudgement(
        beams=int(sizes.sum()),
        wrong_angle=int(np.count_nonzero(wrong)),
        never_sent=int(np.count_nonzero(never)),
        wrong_in_complete=int(bad_per_scan[complete].sum()),
        scans_with_wrong=int(np.count_nonzero(bad_per_scan)),
        complete_missing=int(np.count_nonzero(complete & (sizes < batch.beams_per_revolution))),
        repeated=int(tagged.shape[0] - np.unique(tagged).shape[0]),
        max_angle_error_deg=worst,
    )


def _node_keys(quality: I64Array, angle: I64Array, q2: I64Array) -> I64Array:
    return (quality << 40) | (angle << 16) | q2


def _checked_node_keys(data: bytes) -> I64Array:
    """Sorted keys of every 5-byte window of ``data``, at any offset, that passes the node
    checks: everything a standard-node decoder may ever emit from ``data``."""
    raw = sliding_window_view(np.frombuffer(data, dtype=np.uint8), rp.NODE_BYTES)
    nodes = rp.fields_of(raw[rp.node_validity(raw)])
    return np.unique(_node_keys(nodes.quality, nodes.angle_q6, nodes.distance_q2))


def _unexplained(
    batch: Batch, mutation: Mutation, data: bytes, scans: Sequence[Scan]
) -> tuple[int, int]:
    """Wrong beams of ``scans`` (decoded from ``data``) the protocol could have detected, and
    wrong beams explained only by a forged frame in ``data`` (an express capsule or SCIP line
    that passes every check but was never sent: the checksum's limit, not the decoder's)."""
    if batch.protocol == "scip" and mutation in UNDETECTABLE["scip"]:
        return 0, 0
    total = 0
    forged_wrong = 0
    checked: I64Array | None = None
    forged: int | None = None
    for scan in scans:
        angle, value, q2 = _keys(batch, scan)
        owner = np.zeros(angle.shape, dtype=np.int64)
        wrong, never, _ = _wrong_beams(batch, angle, value, q2, owner)
        bad = wrong | never
        if not bool(np.any(bad)):
            continue
        if batch.protocol == "rplidar-standard":
            # Each emitted beam must be a window of the received bytes that passes the node
            # checks: the framing allows no more (SR-DRV-2).
            checked = _checked_node_keys(data) if checked is None else checked
            assert scan.intensities is not None
            keys = _node_keys(scan.intensities.astype(np.int64)[bad], angle[bad], q2[bad])
            total += int(np.count_nonzero(~_member(checked, keys)[0]))
            continue
        forged = _forged_frames(batch, data) if forged is None else forged
        if forged:
            forged_wrong += int(np.count_nonzero(bad))
        else:
            total += int(np.count_nonzero(bad))
    return total, forged_wrong


def _forged_frames(batch: Batch, data: bytes) -> int:
    """Frames of ``data`` that pass every check of their protocol but were never sent."""
    if batch.protocol == "scip":
        return len(checked_scip_lines(data) - checked_scip_lines(b"".join(batch.frames)))
    view = np.frombuffer(data, dtype=np.uint8)
    if view.shape[0] < CAPSULE_BYTES:
        return 0
    windows = sliding_window_view(view, CAPSULE_BYTES)
    sent = set(batch.frames)
    return sum(bytes(w) not in sent for w in windows[capsule_validity(windows)])


@dataclass(frozen=True, slots=True)
class ClassFigures:
    """What one mutation class did to one protocol, summed over a campaign: mutations,
    frames decoded, scans the clean streams gave and the mutated ones emitted, of those
    incomplete, revolutions rejected (withheld) and frames rejected beyond the clean
    streams', the beam judgement, wrong beams the protocol could have detected
    (``unexplained``, a decoder defect), wrong beams explained only by a forged frame and the
    mutated streams holding them (the checksum's limit), decoder seconds and wall seconds."""

    mutations: int = 0
    frames: int = 0
    scans_clean: int = 0
    scans_emitted: int = 0
    scans_incomplete: int = 0
    revolutions_rejected: int = 0
    frames_rejected: int = 0
    beams: int = 0
    wrong_angle: int = 0
    never_sent: int = 0
    wrong_in_complete: int = 0
    scans_with_wrong: int = 0
    complete_missing: int = 0
    repeated: int = 0
    unexplained: int = 0
    forged_wrong: int = 0
    forged_streams: int = 0
    max_angle_error_deg: float = 0.0
    decode_s: float = 0.0
    wall_s: float = 0.0

    def __add__(self, other: ClassFigures) -> ClassFigures:
        values = {
            f.name: (
                max(getattr(self, f.name), getattr(other, f.name))
                if f.name == "max_angle_error_deg"
                else getattr(self, f.name) + getattr(other, f.name)
            )
            for f in fields(self)
        }
        return ClassFigures(**values)


def run_campaign(
    protocol: Protocol,
    mutations_per_class: int,
    rng: np.random.Generator,
    *,
    draws_per_batch: int = 8,
    revolutions: int = 8,
) -> dict[Mutation, ClassFigures]:
    """Mutate, decode and judge until every class has ``mutations_per_class`` mutations,
    :data:`~properties.fuzz_cases.MUTATIONS_PER_REVOLUTION` of them per revolution's worth
    of frames (SR-DRV-2, SR-DRV-3).

    Each batch is reused for ``draws_per_batch`` mutated streams per class. Raises
    ``AssertionError`` when a clean batch does not decode to exactly its truth (the
    campaign's own machinery would be wrong)."""
    totals = {m: ClassFigures() for m in MUTATIONS}
    while min(t.mutations for t in totals.values()) < mutations_per_class:
        batch = make_batch(protocol, rng, revolutions)
        clean, clean_counters, _ = decode_stream(batch, batch.prefix + b"".join(batch.frames), rng)
        verdict = judge_scans(batch, clean)
        assert verdict.wrong_angle == verdict.never_sent == verdict.complete_missing == 0
        assert verdict.repeated == 0
        assert clean_counters.frames_rejected == 0
        window = batch.frames_per_revolution // MUTATIONS_PER_REVOLUTION[protocol]
        for mutation in MUTATIONS:
            for _ in range(draws_per_batch):
                if totals[mutation].mutations >= mutations_per_class:
                    break
                started = time.perf_counter()
                frames, count = mutate(batch.frames, mutation, rng, window)
                data = batch.prefix + b"".join(frames)
                got, counters, decode_s = decode_stream(batch, data, rng)
                j = judge_scans(batch, got)
                unexplained, forged_wrong = (
                    _unexplained(batch, mutation, data, got)
                    if j.wrong_angle + j.never_sent
                    else (0, 0)
                )
                totals[mutation] += ClassFigures(
                    mutations=count,
                    frames=len(frames),
                    scans_clean=len(clean),
                    scans_emitted=len(got),
                    scans_incomplete=sum(not s.complete for s in got),
                    revolutions_rejected=counters.scans_dropped - clean_counters.scans_dropped,
                    frames_rejected=counters.frames_rejected - clean_counters.frames_rejected,
                    beams=j.beams,
                    wrong_angle=j.wrong_angle,
                    never_sent=j.never_sent,
                    wrong_in_complete=j.wrong_in_complete,
                    scans_with_wrong=j.scans_with_wrong,
                    complete_missing=j.complete_missing,
                    repeated=j.repeated,
                    unexplained=unexplained,
                    forged_wrong=forged_wrong,
                    forged_streams=int(forged_wrong > 0),
                    max_angle_error_deg=j.max_angle_error_deg,
                    decode_s=decode_s,
                    wall_s=time.perf_counter() - started,
                )
    return totals


def _shard(args: tuple[Protocol, int, np.random.SeedSequence]) -> dict[Mutation, ClassFigures]:
    protocol, per_class, seed = args
    return run_campaign(protocol, per_class, np.random.default_rng(seed))


def run_sharded(
    protocol: Protocol, mutations_per_class: int, seed: int, *, shards: int, workers: int
) -> dict[Mutation, ClassFigures]:
    """:func:`run_campaign` split into ``shards`` independent campaigns, each seeded by its
    own child of ``SeedSequence(seed)``, run on ``workers`` processes and summed. The result
    depends on ``seed`` and ``shards`` only, never on ``workers`` or scheduling, so a
    campaign reproduces on any machine (SR-DRV-2, SR-DRV-3)."""
    per_shard = -(-mutations_per_class // shards)
    jobs = [(protocol, per_shard, child) for child in np.random.SeedSequence(seed).spawn(shards)]
    totals = {m: ClassFigures() for m in MUTATIONS}
    with ProcessPoolExecutor(max_workers=workers) if workers > 1 else nullcontext() as pool:
        for part in pool.map(_shard, jobs) if pool else map(_shard, jobs):
            for mutation, figures in part.items():
                totals[mutation] += figures
    return totals
