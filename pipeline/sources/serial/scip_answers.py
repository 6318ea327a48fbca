"""Splitting received SCIP 2.0 bytes into whole answers, for the handshake (SR-DRV-2).

An answer is an echo-back line, a status line (two characters and their checksum), any
number of lines and an empty line. :func:`parse_answers` never raises: a line that starts no
answer (garbage, the rest of an answer whose head was lost, an unknown echo) is skipped and
counted, an echo without a valid status line is skipped, and every valid answer is kept, in
order, whatever lies between them (as seqsense/urg_stamped's resynchronisation expects).
:func:`answer_to` picks the first valid answer to one command. Pure functions; no I/O.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from pipeline.sources.serial.errors import DriverError
from pipeline.sources.serial.scip import ScipCommand, encoded_line_ok

__all__ = ["ParsedAnswers", "ScipAnswer", "answer_to", "parse_answers"]


@dataclass(frozen=True, slots=True)
class ScipAnswer:
    """One whole answer: the echoed command line and the two status characters (both
    without checksum or LF), the lines after the status (each without LF, checksum kept),
    the byte offset of the echo in the parsed buffer and the offset just past the answer's
    empty line."""

    echo: bytes
    status: bytes
    lines: tuple[bytes, ...]
    offset: int
    end: int


@dataclass(frozen=True, slots=True)
class ParsedAnswers:
    """What :func:`parse_answers` found: the valid answers in order, how many lines belonged
    to none, and how many leading bytes are settled (the rest starts an unfinished answer
    or line and should be parsed again with more bytes)."""

    answers: tuple[ScipAnswer, ...]
    rejected_lines: int
    consumed: int


def _is_command(line: bytes, echoes: Collection[bytes] | None) -> bool:
    if echoes is not None:
        return line in echoes
    try:
        ScipCommand.parse(line)
    except DriverError:
        return False
    return True


def _is_status(line: bytes) -> bool:
    return len(line) == 3 and encoded_line_ok(line)


def parse_answers(buf: bytes, echoes: Collection[bytes] | None = None) -> ParsedAnswers:
    """Every whole, valid answer in ``buf`` (SR-DRV-2); never raises.

    ``echoes`` lists the command lines (without LF) that may start an answer; None accepts
    any command line :class:`ScipCommand` parses. A CR before an LF is ignored. An answer
    ends at its empty line; an echo of ``echoes`` followed by a valid status inside an
    answer means that answer lost its empty line: it is dropped and the new one starts.
    """
    lines = buf.split(b"\n")
    tail = len(lines) - 1  # the last piece has no LF yet
    answers: list[ScipAnswer] = []
    rejected = 0
    consumed = 0
    offsets = [0] * len(lines)
    at = 0
    for index, line in enumerate(lines):
        offsets[index] = at
        at += len(line) + 1
    clean = [line.rstrip(b"\r") for line in lines]
    index = 0
    while index < tail:
        line = clean[index]
        if not line:
            index += 1
            consumed = offsets[index]
            continue
        if not _is_command(line, echoes):
            rejected += 1
            index += 1
            consumed = offsets[index]
            continue
        if index + 1 >= tail:
            break  # the status line has not arrived yet
        if not _is_status(clean[index + 1]):
            rejected += 1  # an echo without a valid status: look again from the next line
            index += 1
            consumed = offsets[index]
            continue
        body = index + 2
        end = body
        restart = -1
        while end < tail and clean[end]:
            if _is_command(clean[end], echoes) and end + 1 < tail and _is_status(clean[end + 1]):
                restart = end
                break
            end += 1
        if restart >= 0:
            rejected += restart - index
            index = restart
            consumed = offsets[index]
            continue
        if end >= tail:
            break  # the empty line has not arrived yet
        status = clean[index + 1][:2]
        begin = offsets[index]
        index = end + 1
        consumed = offsets[index]
        answers.append(ScipAnswer(line, status, tuple(clean[body:end]), begin, consumed))
    return ParsedAnswers(tuple(answers), rejected, consumed)


def answer_to(buf: bytes, command: ScipCommand) -> tuple[ScipAnswer | None, int]:
    """The first whole valid answer to ``command`` in ``buf`` and the offset just past its
    empty line, or ``(None, 0)`` while none has arrived; answers to other commands and
    garbage before it are skipped (SR-DRV-2). Never raises."""
    parsed = parse_answers(buf, (command.line(),))
    if not parsed.answers:
        return None, 0
    return parsed.answers[0], parsed.answers[0].end
