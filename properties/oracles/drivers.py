"""Reference decoders for the serial-driver properties (SR-DRV-2, SR-DRV-5).

Written from the protocol documents independently of the vectorised runtime code: plain
Python, one byte or character at a time, no numpy. They are slow on purpose (they are the
"obviously right" reading) and serve as the oracle of the fuzz properties and the reference
of the decode benchmarks.
"""

from __future__ import annotations

__all__ = [
    "checked_capsule_distances",
    "checked_capsules",
    "checked_node_windows",
    "checked_scip_lines",
    "scip_values",
    "standard_nodes",
]


def standard_nodes(data: bytes) -> list[tuple[bool, int, int, int]]:
    """Aligned standard nodes ``(start, quality, angle_q6, distance_q2)``; stops at the
    first node that fails its start-flag pair or check bit."""
    out = []
    for i in range(0, len(data) - 4, 5):
        b0, b1, b2, b3, b4 = data[i : i + 5]
        start, inverse = b0 & 1, (b0 >> 1) & 1
        if start == inverse or not b1 & 1:
            break
        out.append((bool(start), b0 >> 2, (b1 >> 1) | (b2 << 7), b3 | (b4 << 8)))
    return out


def checked_node_windows(data: bytes) -> set[tuple[int, int, int]]:
    """``(quality, angle_q6, distance_q2)`` of every 5-byte window, at any offset, that
    passes the start-flag pair and check bit: everything a standard-scan decoder may ever
    legitimately emit from ``data``."""
    out = set()
    for i in range(len(data) - 4):
        b0, b1, b2, b3, b4 = data[i : i + 5]
        if (b0 & 1) != ((b0 >> 1) & 1) and b1 & 1:
            out.add((b0 >> 2, (b1 >> 1) | (b2 << 7), b3 | (b4 << 8)))
    return out


def checked_capsules(data: bytes, size: int = 84) -> set[bytes]:
    """Every ``size``-byte window, at any offset, that passes the sync nibbles and XOR
    checksum of an express capsule."""
    out = set()
    for i in range(len(data) - size + 1):
        if data[i] >> 4 != 0xA or data[i + 1] >> 4 != 0x5:
            continue
        checksum = 0
        for byte in data[i + 2 : i + size]:
            checksum ^= byte
        if checksum == (data[i] & 0xF) | ((data[i + 1] & 0xF) << 4):
            out.add(bytes(data[i : i + size]))
    return out


def checked_capsule_distances(data: bytes, size: int = 84) -> set[int]:
    """Distances (mm) of every node of every checked capsule window (:func:`checked_capsules`)."""
    out = set()
    for capsule in checked_capsules(data, size):
        for c in range(16):
            cab = capsule[4 + 5 * c : 9 + 5 * c]
            out.add((cab[0] | (cab[1] << 8)) >> 2)
            out.add((cab[2] | (cab[3] << 8)) >> 2)
    return out


def checked_scip_lines(data: bytes) -> set[bytes]:
    """Every LF-terminated line of ``data`` that passes the SCIP checks of a data line: at
    least one payload character, all in 0x30..0x6F, and the 6-bit sum checksum."""
    out = set()
    for line in data.split(b"\n")[:-1]:
        if len(line) >= 2 and scip_values([line], 1) is not None:
            out.add(line)
    return out


def scip_values(lines: list[bytes], width: int) -> list[int] | None:
    """Values of checksummed SCIP data lines (payload + checksum each), or None when any
    line fails its checksum or holds a character outside 0x30..0x6F."""
    text = bytearray()
    for line in lines:
        payload, stated = line[:-1], line[-1]
        total = 0
        for char in payload:
            if not 0x30 <= char <= 0x6F:
                return None
            total += char
        if (total & 0x3F) + 0x30 != stated:
            return None
        text += payload
    if len(text) % width:
        return None
    values = []
    for i in range(0, len(text), width):
        value = 0
        for char in text[i : i + width]:
            value = (value << 6) | (char - 0x30)
        values.append(value)
    return values
