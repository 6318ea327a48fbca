"""Hokuyo SCIP 2.0 codec: commands, echo-back, status, data lines, character encoding
(requirements SR-DRV-1, SR-DRV-2). Pure functions; no I/O.

Protocol facts (Hokuyo's public SCIP 2.0 specification): every message is a line ending in
LF. A response repeats the command line (echo-back), then a status line (two characters and
a checksum character), then data lines, each ending in its checksum character, then an empty
line. The checksum of a line is the sum of its bytes, low 6 bits, plus 0x30. Numbers are sent
6 bits per character (character = value + 0x30) in 2, 3 or 4 characters, most significant
first; distance data are split into lines of 64 characters and a value may straddle two
lines. Info lines (``PP``, ``VV``, ``II``) read ``KEY:value;`` + checksum, the checksum
covering ``KEY:value`` (readers accept one that also covers the ``;``, as some firmware sends).

Angles: step ``s`` lies at ``(s - AFRT) * 2 pi / ARES`` radians, counter-clockwise, which is
the :class:`~pipeline.types.Scan` frame; a clustered value takes the angle of its first step.
Distances are millimetres; values below DMIN are error codes and above DMAX out of range:
both become NaN (no return).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from pipeline.compat import StrEnum
from pipeline.sources.serial.errors import ChecksumError, EncodeError, FrameError, ProtocolError
from pipeline.types import Scan

__all__ = [
    "DATA_LINE_CHARS",
    "NO_RETURN_CODE",
    "ScipCommand",
    "ScipParams",
    "checksum",
    "data_line_lengths",
    "decode_data_lines",
    "decode_info_lines",
    "decode_values",
    "encode_data_lines",
    "encode_info_lines",
    "encode_response",
    "encode_values",
    "info_response",
    "line_ok",
    "scan_to_values",
    "values_to_scan",
]

LF = b"\n"
CHAR_MIN = 0x30
CHAR_MAX = 0x6F
DATA_LINE_CHARS = 64
NO_RETURN_CODE = 1  # an error code below every model's DMIN: "no echo"
STATUS_OK = "00"
STATUS_STREAMING = "99"

I64Array = npt.NDArray[np.int64]


def checksum(data: bytes) -> int:
    """The SCIP checksum character of ``data`` (sum of bytes, low 6 bits, + 0x30)."""
    return (sum(data) & 0x3F) + 0x30


def with_checksum(payload: bytes) -> bytes:
    """``payload`` + its checksum character + LF."""
    return payload + bytes((checksum(payload),)) + LF


def encode_values(values: npt.ArrayLike, width: int) -> bytes:
    """Encode non-negative integers in ``width`` (2, 3 or 4) characters each (vectorised)."""
    if width not in (2, 3, 4):
        raise EncodeError(f"scip: width {width} is not 2, 3 or 4")
    arr = np.asarray(values, dtype=np.int64).ravel()
    bad = (arr < 0) | (arr >= 1 << (6 * width))
    if np.any(bad):
        index = int(np.argmax(bad))
        raise EncodeError(
            f"scip: value {arr[index]} does not fit in {width} characters "
            f"(0..{(1 << (6 * width)) - 1})",
            index,
        )
    shifts = 6 * np.arange(width - 1, -1, -1, dtype=np.int64)
    chars = ((arr[:, None] >> shifts[None, :]) & 0x3F) + CHAR_MIN
    return chars.astype(np.uint8).tobytes()


def decode_values(data: bytes | npt.NDArray[np.uint8], width: int, offset: int = 0) -> I64Array:
    """Decode characters in groups of ``width``; raises :class:`FrameError` on a character
    outside ``0x30..0x6F`` or a length that is not a multiple of ``width``."""
    if width not in (2, 3, 4):
        raise FrameError(f"scip: width {width} is not 2, 3 or 4", offset)
    raw = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes | bytearray) else data
    if raw.shape[0] % width:
        raise FrameError(f"scip: {raw.shape[0]} characters is not a multiple of {width}", offset)
    bad = (raw < CHAR_MIN) | (raw > CHAR_MAX)
    if np.any(bad):
        index = int(np.argmax(bad))
        raise FrameError(
            f"scip: character 0x{raw[index]:02X} outside the encoding alphabet 0x30..0x6F",
            offset + index,
        )
    digits = (raw.astype(np.int64) - CHAR_MIN).reshape(-1, width)
    shifts = 6 * np.arange(width - 1, -1, -1, dtype=np.int64)
    values: I64Array = np.bitwise_or.reduce(digits << shifts[None, :], axis=1)
    return values


# ------------------------------------------------------------------------------ commands
class Name(StrEnum):
    """The SCIP 2.0 commands this codec knows."""

    SCIP20 = "SCIP2.0"
    VV = "VV"
    PP = "PP"
    II = "II"
    BM = "BM"
    QT = "QT"
    RS = "RS"
    MD = "MD"
    MS = "MS"
    GD = "GD"
    GS = "GS"


_SIMPLE = {Name.SCIP20, Name.VV, Name.PP, Name.II, Name.BM, Name.QT, Name.RS}


@dataclass(frozen=True, slots=True)
class ScipCommand:
    """One SCIP 2.0 command. For MD/MS/GD/GS: steps ``start..end``, ``cluster`` steps per
    value (1..99); for MD/MS also ``interval`` (scans skipped, 0..9) and ``scans`` (0..99,
    0 = until QT). ``scans`` is also the remaining-count field of an MD/MS echo-back."""

    name: Name
    start: int = 0
    end: int = 0
    cluster: int = 1
    interval: int = 0
    scans: int = 0

    @property
    def width(self) -> int:
        """Characters per distance value: 3 for MD/GD, 2 for MS/GS."""
        return 2 if self.name in (Name.MS, Name.GS) else 3

    @property
    def n_values(self) -> int:
        """How many distance values a scan answering this command carries."""
        return (self.end - self.start) // self.cluster + 1

    def line(self) -> bytes:
        """The command line without its LF (also the echo-back)."""
        if self.name in _SIMPLE:
            return self.name.value.encode()
        if not (0 <= self.start <= self.end <= 9999 and 1 <= self.cluster <= 99):
            raise EncodeError(
                f"scip {self.name}: steps {self.start}..{self.end} cluster {self.cluster} "
                "invalid (0 <= start <= end <= 9999, 1 <= cluster <= 99)"
            )
        text = f"{self.name}{self.start:04d}{self.end:04d}{self.cluster:02d}"
        if self.name in (Name.MD, Name.MS):
            if not (0 <= self.interval <= 9 and 0 <= self.scans <= 99):
                raise EncodeError(
                    f"scip {self.name}: interval {self.interval} (0..9) or scans "
                    f"{self.scans} (0..99) invalid"
                )
            text += f"{self.interval:01d}{self.scans:02d}"
        return text.encode()

    def encode(self) -> bytes:
        """The command as sent: its line and LF."""
        return self.line() + LF

    @classmethod
    def parse(cls, line: bytes) -> ScipCommand:
        """Parse a command line (without LF); raises :class:`ProtocolError` when unknown."""
        text = line.rstrip(b"\r").decode("ascii", errors="replace")
        for name in _SIMPLE:
            if text == name.value:
                return cls(name)
        head, digits = text[:2], text[2:]
        if head in ("MD", "MS") and len(digits) == 13 and digits.isdigit():
            return cls(
                Name(head),
                int(digits[0:4]),
                int(digits[4:8]),
                max(1, int(digits[8:10])),
                int(digits[10]),
                int(digits[11:13]),
            )
        if head in ("GD", "GS") and len(digits) == 10 and digits.isdigit():
            return cls(Name(head), int(digits[0:4]), int(digits[4:8]), max(1, int(digits[8:10])))
        raise ProtocolError(f"scip: unknown or malformed command {text[:32]!r}")


# ----------------------------------------------------------------------------- responses
def encode_response(echo: bytes, status: str, lines: list[bytes] | tuple[bytes, ...] = ()) -> bytes:
    """A whole response: echo-back, status with checksum, data lines (checksummed here),
    terminating empty line. ``lines`` are payloads without checksum or LF."""
    if len(status) != 2:
        raise EncodeError(f"scip: status {status!r} must be two characters")
    body = echo + LF + with_checksum(status.encode())
    return body + b"".join(with_checksum(line) for line in lines) + LF


def line_ok(line: bytes) -> bool:
    """A received line (payload + checksum, no LF) passes its checksum."""
    return len(line) >= 2 and line[-1] == checksum(line[:-1])


def encoded_line_ok(line: bytes) -> bool:
    """A line of encoded characters passes its checksum and stays in the alphabet.

    The 6-bit checksum cannot see a flipped bit 6 or 7; such a flip always leaves the
    alphabet ``0x30..0x6F``, so the two checks together catch every single bit flip.
    """
    return line_ok(line) and all(CHAR_MIN <= c <= CHAR_MAX for c in line[:-1])


def encode_data_lines(values: npt.ArrayLike, width: int, timestamp_ms: int | None) -> list[bytes]:
    """Payloads of the data part of a scan response: optional timestamp line, then the
    encoded values in lines of 64 characters."""
    text = encode_values(values, width)
    lines = [text[i : i + DATA_LINE_CHARS] for i in range(0, len(text), DATA_LINE_CHARS)]
    if timestamp_ms is not None:
        lines.insert(0, encode_values([timestamp_ms % (1 << 24)], 4))
    return lines


def data_line_lengths(width: int, n_values: int) -> I64Array:
    """The length (payload + checksum character, no LF) of each data line of a scan answer
    carrying ``n_values`` values of ``width`` characters: 65, the last one the remainder."""
    total = n_values * width
    expected = -(-total // DATA_LINE_CHARS)
    want = np.full(expected, DATA_LINE_CHARS + 1, dtype=np.int64)
    if expected:
        want[-1] = total - DATA_LINE_CHARS * (expected - 1) + 1
    return want


def decode_data_lines(
    lines: list[bytes], width: int, n_values: int, offset: int = 0
) -> tuple[I64Array, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
    """Values of a scan's data lines (each payload + checksum, no LF; no timestamp line).

    Returns ``(values, valid, lines_ok)``. The command fixes how many data lines an answer
    has and how long each is (:func:`data_line_lengths`); only when both add up is a line's
    position certain, and a line is then good when it passes its checksum and alphabet. A
    value is valid only when all its characters lie in good lines; values of a failing line
    are never guessed. When the count or any length does not add up (a lost, extra, merged,
    split or repeated line), no line can be placed without guessing: nothing is valid and
    the caller rejects the revolution (SR-DRV-2).
    """
    want = data_line_lengths(width, n_values)
    expected = want.shape[0]
    total = n_values * width
    lines_ok = np.zeros(len(lines), dtype=np.bool_)
    lengths = np.fromiter(map(len, lines), dtype=np.int64, count=len(lines))
    if len(lines) != expected or not np.array_equal(lengths, want):
        return np.zeros(n_values, dtype=np.int64), np.zeros(n_values, dtype=np.bool_), lines_ok
    # Every line has its place: check and decode all lines at once.
    raw = np.frombuffer(b"".join(lines), dtype=np.uint8)
    ends = np.cumsum(want)
    payload_mask = np.ones(raw.shape[0], dtype=np.bool_)
    payload_mask[ends - 1] = False
    line_of = np.repeat(np.arange(expected), want)
    in_alphabet = (raw >= CHAR_MIN) & (raw <= CHAR_MAX)
    sums = np.bincount(line_of[payload_mask], weights=raw[payload_mask], minlength=expected)
    ok = ((sums.astype(np.int64) & 0x3F) + CHAR_MIN) == raw[ends - 1]
    ok &= np.bincount(line_of, weights=~in_alphabet, minlength=expected) == 0
    lines_ok[:] = ok
    good = np.repeat(ok, want - 1)
    chars = np.where(good, raw[payload_mask], CHAR_MIN).astype(np.uint8)
    values = decode_values(chars[:total], width, offset)
    valid = np.all(good[:total].reshape(-1, width), axis=1)
    return values, valid, lines_ok


# ------------------------------------------------------------------------ info responses
def encode_info_lines(items: dict[str, str]) -> list[bytes]:
    """The ``KEY:value`` payloads of an info answer, before the ``;`` and the checksum
    that :func:`info_response` appends to each."""
    return [f"{key}:{value}".encode() for key, value in items.items()]


def info_response(echo: bytes, items: dict[str, str]) -> bytes:
    """A PP/VV/II response: each line ``KEY:value;c`` with ``c`` the checksum of
    ``KEY:value``."""
    body = echo + LF + with_checksum(STATUS_OK.encode())
    for payload in encode_info_lines(items):
        body += payload + b";" + bytes((checksum(payload),)) + LF
    return body + LF


def decode_info_lines(lines: list[bytes], offset: int = 0) -> dict[str, str]:
    """Parse ``KEY:value;c`` lines; raises :class:`ChecksumError` / :class:`FrameError`."""
    items: dict[str, str] = {}
    for line in lines:
        if len(line) < 3 or b":" not in line or line[-2:-1] != b";":
            raise FrameError(f"scip info line {line[:40]!r}: expected KEY:value;c", offset)
        if line[-1] not in (checksum(line[:-2]), checksum(line[:-1])):
            raise ChecksumError(f"scip info line {line[:40]!r}: checksum mismatch", offset)
        key, _, value = line[:-2].decode("ascii", errors="replace").partition(":")
        items[key] = value
    return items


@dataclass(frozen=True, slots=True)
class ScipParams:
    """The ``PP`` answer: model, distance limits (mm), angular resolution (steps per turn),
    first/last/front step, motor speed (rpm)."""

    model: str = "UTM-30LX(Hokuyo Automatic Co.,Ltd.)"
    dmin_mm: int = 23
    dmax_mm: int = 60000
    ares: int = 1440
    amin: int = 0
    amax: int = 1080
    afrt: int = 540
    scan_rpm: int = 2400
    extra: dict[str, str] = field(default_factory=dict)

    def items(self) -> dict[str, str]:
        """The PP lines as key/value text."""
        return {
            "MODL": self.model,
            "DMIN": str(self.dmin_mm),
            "DMAX": str(self.dmax_mm),
            "ARES": str(self.ares),
            "AMIN": str(self.amin),
            "AMAX": str(self.amax),
            "AFRT": str(self.afrt),
            "SCAN": str(self.scan_rpm),
            **self.extra,
        }

    @classmethod
    def from_items(cls, items: dict[str, str]) -> ScipParams:
        """Parse the PP lines; raises :class:`ProtocolError` on a missing or bad key."""
        try:
            params = cls(
                model=items["MODL"],
                dmin_mm=int(items["DMIN"]),
                dmax_mm=int(items["DMAX"]),
                ares=int(items["ARES"]),
                amin=int(items["AMIN"]),
                amax=int(items["AMAX"]),
                afrt=int(items["AFRT"]),
                scan_rpm=int(items["SCAN"]),
            )
        except (KeyError, ValueError) as exc:
            raise ProtocolError(f"scip PP: missing or non-numeric parameter: {exc}") from None
        if not (
            params.ares > 0 and params.amin <= params.afrt <= params.amax and params.scan_rpm > 0
        ):
            raise ProtocolError(f"scip PP: inconsistent parameters {params.items()}")
        return params

    @property
    def scan_period_s(self) -> float:
        """Seconds per revolution."""
        return 60.0 / self.scan_rpm

    @property
    def step_rad(self) -> float:
        """Radians per step."""
        return 2.0 * np.pi / self.ares


# --------------------------------------------------------------------- scan <-> values
def values_to_scan(
    values: I64Array,
    valid: npt.NDArray[np.bool_],
    params: ScipParams,
    command: ScipCommand,
    *,
    stamp_s: float,
    seq: int = 0,
    source: str = "scip",
) -> Scan:
    """A :class:`Scan` of the values that passed their checks (SR-DRV-2): failed values
    are absent (``complete`` False), error codes and out-of-range values are NaN."""
    index = np.flatnonzero(valid)
    steps = command.start + index * command.cluster
    mm = values[index]
    ranges = mm.astype(np.float64) / 1000.0
    ranges[(mm < params.dmin_mm) | (mm > params.dmax_mm)] = np.nan
    return Scan(
        stamp_s=stamp_s,
        angles_rad=(steps - params.afrt).astype(np.float64) * params.step_rad,
        ranges_m=ranges,
        beam_period_s=params.scan_period_s / params.ares * command.cluster,
        seq=seq,
        source=source,
        complete=bool(np.all(valid)),
    )


def scan_to_values(scan: Scan, params: ScipParams, command: ScipCommand) -> I64Array:
    """The values a device answering ``command`` reports for ``scan`` (SR-DRV-1).

    Each beam goes to its nearest step; a cluster reports the nearest of its beams, as the
    device does; a value with no beam, a NaN range, or a range outside DMIN..DMAX (or above
    4095 mm in 2-character mode) reports :data:`NO_RETURN_CODE`.
    """
    n = command.n_values
    step = np.rint(scan.angles_rad / params.step_rad).astype(np.int64) + params.afrt
    group = (step - command.start) // command.cluster
    mm = np.rint(np.nan_to_num(scan.ranges_m, nan=-1.0, posinf=-1.0, neginf=-1.0) * 1000.0)
    limit = min(params.dmax_mm, (1 << (6 * command.width)) - 1)
    usable = (
        (step >= command.start) & (step <= command.end) & (mm >= params.dmin_mm) & (mm <= limit)
    )
    out = np.full(n, np.iinfo(np.int64).max, dtype=np.int64)
    np.minimum.at(out, group[usable], mm[usable].astype(np.int64))
    out[out == np.iinfo(np.int64).max] = NO_RETURN_CODE
    return out
