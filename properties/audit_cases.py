"""Random audit logs and single edits of them (SR-AUD-1, SR-AUD-2).

:func:`write_random_log` writes a log of synthetic cycles: random monitor observations (stale
and fresh scans, clock jumps, deadline misses, driver states, caps overflowing), random governor
inputs (including NaN and negative values the governor must refuse) and failed stages, each
decided by :func:`safety.model.decision.decide` like the runtime does. :class:`Edit` applies one
tampering edit to the log's bytes and says which line :func:`safety.audit.verify.verify_log`
must name.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from pipeline.config import SafecaseConfig
from pipeline.types import DriverState
from safety.audit.log import AuditWriter, CycleRecord, canonical_json, record_hash, summarize
from safety.model.decision import GovernorInputs, decide
from safety.model.governor import Governor
from safety.model.monitors import MonitorVerdict, Observation

__all__ = ["EDIT_KINDS", "Edit", "random_cycle", "write_random_log"]

EDIT_KINDS = ("flip", "reformat", "delete", "duplicate", "swap", "forge", "truncate", "append")


def random_cycle(
    rng: np.random.Generator,
    governor: Governor,
    config: SafecaseConfig,
    now_s: float,
    previous_now_s: float | None,
) -> CycleRecord:
    """One synthetic cycle decided like the runtime decides (random inputs, some bad)."""
    m = config.monitors
    n = int(rng.integers(0, 6))
    distance = rng.uniform(0.0, 6.0, n)
    if n and rng.random() < 0.1:
        distance[int(rng.integers(n))] = rng.choice([np.nan, -1.0, np.inf])
    inputs = GovernorInputs(
        stamp_s=now_s,
        free_distance_m=distance,
        closing_speed_mps=rng.uniform(0.0, 2.0, n) if rng.random() < 0.7 else None,
        confidence=rng.uniform(0.0, 1.0, n) if rng.random() < 0.7 else None,
        near_reversal=rng.random(n) < 0.2 if rng.random() < 0.5 else None,
    )
    stage: list[MonitorVerdict] = []
    if rng.random() < 0.05:
        stage.append(MonitorVerdict.stop("stage:track", "TrackerError: clock ran backwards"))
        inputs_or_none: GovernorInputs | None = None
    else:
        inputs_or_none = inputs
    states = [None, *(s.value for s in DriverState)]
    observation = Observation(
        now_s=now_s,
        previous_now_s=previous_now_s,
        scan_stamp_s=now_s - float(rng.uniform(0.0, 2.0 * m.scan_max_age_s)),
        previous_scan_stamp_s=None if previous_now_s is None else previous_now_s - 0.1,
        scan_complete=bool(rng.random() < 0.9),
        n_beams=1080,
        n_below_min=int(rng.integers(0, 700)),
        driver_state=states[int(rng.integers(len(states)))],
        driver_age_s=float(rng.uniform(0.0, 1.0)),
        cycle_duration_s=float(rng.uniform(0.0, 2.0 * m.cycle_deadline_s)),
        over_cap=(("cluster.max_clusters", int(rng.random() < 0.05)),),
    )
    decision = decide(governor, inputs_or_none, observation, m, stage)
    timings = {"points": float(rng.uniform(0, 1e-3)), "cluster": float(rng.uniform(0, 2e-3))}
    summary = summarize(scan_seq=int(rng.integers(0, 10**6)), n_tracks=n)
    return CycleRecord(observation, decision, inputs_or_none, summary, timings)


def write_random_log(
    path: Path,
    config: SafecaseConfig,
    rng: np.random.Generator,
    n_cycles: int,
    *,
    model_hash: str | None = None,
    key: Ed25519PrivateKey | None = None,
    fsync_every: int = 3,
    close: bool = True,
) -> AuditWriter:
    """Write ``n_cycles`` random cycles to a new log at ``path``; close it unless told not to
    (an unclosed writer is what a crash leaves: its file descriptor is closed, nothing else)."""
    governor = Governor.from_config(config)
    writer = AuditWriter(
        path,
        config,
        model_hash=model_hash,
        signing_key=key,
        fsync_every=fsync_every,
        created_utc="2025-01-01T00:00:00+00:00",
    )
    now, previous = float(rng.uniform(0.0, 1e4)), None
    for _ in range(n_cycles):
        # Mostly forward; now and then the clock runs back.
        now_next = now + float(rng.uniform(-0.05, 0.2))
        writer.append(random_cycle(rng, governor, config, now_next, previous))
        previous = now_next if previous is None else max(previous, now_next)
        now = now_next
    if close:
        writer.close()
    return writer


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")[:-1]  # complete lines of a log that ends with a newline


def _join(lines: list[bytes]) -> bytes:
    return b"".join(line + b"\n" for line in lines)


@dataclass(frozen=True, slots=True)
class Edit:
    """One tampering edit of a closed log's bytes; ``a``/``b`` pick lines or bytes."""

    kind: str
    a: int
    b: int
    value: int

    def apply(self, data: bytes) -> tuple[bytes, set[int]]:
        """The edited bytes and the line numbers verify may name as the first bad one."""
        lines = _lines(data)
        n = len(lines)
        if self.kind == "flip":
            pos = self.a % len(data)
            new = bytes([(data[pos] + 1 + self.value % 255) % 256])
            line = data[:pos].count(b"\n") + 1
            return data[:pos] + new + data[pos + 1 :], {line}
        if self.kind == "reformat":
            # Same content, other bytes (spacing, key order, escapes): still an edit.
            i = self.a % n
            record = json.loads(lines[i])
            style = self.value % 3
            text = json.dumps(
                record,
                sort_keys=style != 0,
                separators=(", ", ": ") if style != 1 else (",", ":"),
                ensure_ascii=style != 2,
            )
            if style == 1:
                text = " " + text
            reformatted = list(lines)
            reformatted[i] = text.encode("utf-8")
            return _join(reformatted), {i + 1}
        if self.kind == "delete":
            i = self.a % n
            return _join(lines[:i] + lines[i + 1 :]), {i + 1}
        if self.kind == "duplicate":
            j, i = self.a % n, self.b % (n + 1)  # copy line j+1, insert it as line i+1
            inserted = [*lines[:i], lines[j], *lines[i:]]
            # A copy placed right before its original is indistinguishable from it.
            return _join(inserted), {i + 1, i + 2} if i == j else {i + 1}
        if self.kind == "swap":
            i, j = sorted((self.a % n, self.b % n))
            if i == j:
                j = (i + 1) % n
                i, j = sorted((i, j))
            swapped = list(lines)
            swapped[i], swapped[j] = swapped[j], swapped[i]
            return _join(swapped), {i + 1}
        if self.kind == "forge":
            i = self.a % n
            record = json.loads(lines[i])
            body = {k: v for k, v in record.items() if k != "hash"}
            body["forged"] = self.value  # any change of content, hash recomputed
            forged = list(lines)
            forged[i] = canonical_json({**body, "hash": record_hash(body["prev"], body)})
            return _join(forged), {i + 1}
        if self.kind == "truncate":
            cut = self.a % len(data)
            return data[:cut], {data[:cut].count(b"\n") + 1}
        if self.kind == "append":
            junk = [b"{}", lines[self.a % n], b"garbage"][self.value % 3]
            terminated = self.b % 2 == 0
            return data + junk + (b"\n" if terminated else b""), {n + 1}
        raise ValueError(f"unknown edit kind {self.kind!r}")
