"""The one error hierarchy of safecase.

Every error that safecase raises on purpose derives from :class:`SafecaseError`, so a caller
(the runtime loop, the CLI, a property) can catch "anything we anticipated" in one clause and
let genuine bugs propagate. Messages name the bad argument, its value and what was expected.
"""

from __future__ import annotations


class SafecaseError(Exception):
    """Base class of every anticipated safecase error."""


class ConfigError(SafecaseError, ValueError):
    """An invalid configuration file or value (requirement SR-CFG-1).

    ``lines`` holds one human-readable line per problem, each naming the key, the value and
    what is allowed; ``str(error)`` joins them.
    """

    def __init__(self, lines: list[str]) -> None:
        self.lines = list(lines)
        super().__init__("\n".join(self.lines))


class EvidenceError(SafecaseError):
    """An evidence bundle that is malformed, tampered with or wrongly signed."""


class RequirementsError(SafecaseError):
    """A malformed requirements catalogue or a reference to an unknown requirement ID."""


class GeometryError(SafecaseError, ValueError):
    """Geometry that cannot be checked safely (SR-SAT-4): never a silent "no collision"."""


class NonFiniteGeometryError(GeometryError):
    """A NaN or infinite coordinate or pose, or one beyond the supported range."""


class DegeneratePolygonError(GeometryError):
    """Fewer than 3 distinct points, or all points collinear: no area to check against."""
