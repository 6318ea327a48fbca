"""Incremental SCIP 2.0 stream decoding: MD/MS/GD/GS answers in, one :class:`Scan` per
revolution out (requirement SR-DRV-2).

:meth:`ScipStream.feed` never raises. A scan answer is recognised by its echo-back (the
command the driver sent; for MD/MS only the remaining-scans field may differ), then a status
line ``99`` (or ``00`` for GD/GS), a timestamp line and data lines up to an empty line. Each
checksummed line counts as one frame. The command fixes how many data lines follow and how
long each is: when the count and every length add up, a line that fails its checksum or
alphabet loses exactly the values it carries, and the scan is emitted incomplete with the
values of the good lines (policy ``"mark"``) or withheld (``"drop"``). When they do not add
up (a line lost, repeated, merged or split, an empty line spliced in), no line's position is
certain: the revolution is rejected and counted, never placed by guesswork. Lines that belong
to no recognisable answer are rejected and counted; an echo-back arriving before the empty
line closes the answer in progress.

Two data lines of equal length swapped on the wire keep every count, length and checksum:
SCIP 2.0 has nothing to detect it (a limit of the protocol, measured by the fuzz campaign).
"""

from __future__ import annotations

import enum

import numpy as np

from pipeline.sources.serial.assembly import IncompletePolicy, LinkCounters
from pipeline.sources.serial.scip import (
    ScipCommand,
    ScipParams,
    decode_data_lines,
    encoded_line_ok,
    values_to_scan,
)
from pipeline.types import Scan

__all__ = ["ScipStream"]

MAX_LINE_BYTES = 256  # no SCIP line is longer; a longer run without LF is garbage
_ECHO_PREFIX = 13  # "MDsssseeeeccs": everything but the remaining-scans count


class _State(enum.Enum):
    IDLE = 0
    STATUS = 1
    TIMESTAMP = 2
    DATA = 3
    SKIP = 4  # an answer we do not use: wait for its empty line


class ScipStream:
    """Decodes the answers to one distance command (``command``) of a device with
    parameters ``params``. Bounded memory: one line of unconsumed bytes and one answer."""

    def __init__(
        self,
        params: ScipParams,
        command: ScipCommand,
        *,
        counters: LinkCounters | None = None,
        policy: IncompletePolicy = "mark",
        source: str = "scip",
    ) -> None:
        self.params = params
        self.command = command
        self.counters = counters if counters is not None else LinkCounters()
        self.policy = policy
        self.source = source
        self._echo = command.line()
        self._streaming = command.name.value in ("MD", "MS")
        self._expected_lines = -(-command.n_values * command.width // 64)
        self._buf = b""
        self._state = _State.IDLE
        self._lines: list[bytes] = []
        self._broken = False
        self._stamp_s = 0.0
        self._seq = 0

    def reset(self) -> None:
        """Start afresh (after a reconnect)."""
        self.counters.bytes_discarded += len(self._buf)
        self._buf = b""
        self._state = _State.IDLE
        self._lines = []
        self._broken = False

    def _is_echo(self, line: bytes) -> bool:
        if not self._streaming:
            return line == self._echo
        return (
            len(line) == len(self._echo)
            and line[:_ECHO_PREFIX] == self._echo[:_ECHO_PREFIX]
            and line[_ECHO_PREFIX:].isdigit()
        )

    def feed(self, data: bytes, now_s: float) -> list[Scan]:
        """Consume ``data`` read at host time ``now_s``; return the completed scans.

        Never raises; the work is linear in ``len(data)`` (SR-DRV-2, SR-DRV-6)."""
        parts = (self._buf + data).split(b"\n")
        rest = parts.pop()
        out: list[Scan] = []
        index = 0
        while index < len(parts):
            if self._state is _State.DATA:
                index = self._data_lines(parts, index, out)
            else:
                self._line(parts[index].rstrip(b"\r"), now_s, out)
                index += 1
        if len(rest) > MAX_LINE_BYTES:
            self.counters.bytes_discarded += len(rest)
            self.counters.frames_rejected += 1
            self._broken = True
            rest = b""
        self._buf = rest
        return out

    def _data_lines(self, parts: list[bytes], index: int, out: list[Scan]) -> int:
        """Take data lines in bulk up to the empty line (the hot path of a scan)."""
        try:
            end = parts.index(b"", index)
        except ValueError:
            end = len(parts)
        chunk = parts[index:end]
        echo_len = len(self._echo)
        for offset, line in enumerate(chunk):
            if len(line) == echo_len and self._is_echo(line):
                end = index + offset  # a lost terminator: the next answer starts here
                chunk = chunk[:offset]
                break
        self._lines.extend(chunk)
        if len(self._lines) > self._expected_lines:
            # More data lines than the command asks for: the answer cannot be placed.
            self._broken = True
            self._finish(out)
            self._state = _State.IDLE
        elif end < len(parts):
            self._finish(out)
            self._state = _State.IDLE
            if parts[end] == b"":
                end += 1
        return end

    def _line(self, line: bytes, now_s: float, out: list[Scan]) -> None:
        state = self._state
        if self._is_echo(line):
            if state is _State.DATA:
                self._finish(out)
            elif state is not _State.IDLE:
                self._reject_answer()
            self._state = _State.STATUS
            self._lines = []
            self._broken = False
            # The answer follows a whole revolution's measurement: date the first beam one
            # revolution before the echo arrived (never later than it was measured).
            self._stamp_s = now_s - self.params.scan_period_s
            return
        if state is _State.IDLE:
            if line:
                self._reject_line(line)
            return
        if state is _State.SKIP:
            if not line:
                self._state = _State.IDLE
            return
        if state is _State.STATUS:
            self._status(line)
            return
        if state is _State.TIMESTAMP:
            if not line:
                self._reject_answer()
                self._state = _State.IDLE
                return
            # A timestamp line of the wrong length (a lost or extra LF) also shifts the data
            # lines; their count and lengths then do not add up and the answer is rejected.
            if len(line) == 5 and encoded_line_ok(line):
                self.counters.frames_ok += 1
            else:
                self._reject_line(line)
                self._broken = True
            self._state = _State.DATA
            return
        self._lines.append(line)  # DATA lines are normally taken by _data_lines

    def _status(self, line: bytes) -> None:
        if len(line) != 3 or not encoded_line_ok(line):
            self._reject_line(line)
            self._state = _State.SKIP
            if self._streaming:
                self.counters.scans_dropped += 1  # the answer of a revolution is lost
            return
        self.counters.frames_ok += 1
        status = line[:2]
        if status == b"99" or (status == b"00" and not self._streaming):
            self._state = _State.TIMESTAMP
        else:
            # "00" acknowledges MD/MS without data; anything else is a device error status,
            # and while streaming it costs a revolution: count it so the monitors see it.
            if self._streaming and status != b"00":
                self.counters.scans_dropped += 1
            self._state = _State.SKIP

    def _reject_line(self, line: bytes) -> None:
        self.counters.frames_rejected += 1
        self.counters.bytes_discarded += len(line) + 1

    def _reject_answer(self) -> None:
        self.counters.frames_rejected += 1
        self.counters.scans_dropped += 1

    def _finish(self, out: list[Scan]) -> None:
        lines = self._lines
        self._lines = []
        values, valid, lines_ok = decode_data_lines(
            lines, self.command.width, self.command.n_values
        )
        good_lines = int(np.count_nonzero(lines_ok))
        bad_lines = len(lines) - good_lines
        self.counters.frames_ok += good_lines
        self.counters.frames_rejected += bad_lines
        if len(lines) < self._expected_lines:
            self.counters.frames_rejected += 1  # lines missing altogether
        incomplete = not bool(np.all(valid)) or bad_lines > 0 or self._broken
        if not bool(np.any(valid)) or (incomplete and self.policy == "drop"):
            self.counters.scans_dropped += 1
            return
        scan = values_to_scan(
            values,
            valid,
            self.params,
            self.command,
            stamp_s=self._stamp_s,
            seq=self._seq,
            source=self.source,
        )
        if incomplete and scan.complete:
            scan = Scan(
                stamp_s=scan.stamp_s,
                angles_rad=scan.angles_rad,
                ranges_m=scan.ranges_m,
                beam_period_s=scan.beam_period_s,
                seq=scan.seq,
                source=scan.source,
                complete=False,
            )
        self._seq += 1
        self.counters.scans_emitted += 1
        self.counters.scans_incomplete += int(not scan.complete)
        out.append(scan)
