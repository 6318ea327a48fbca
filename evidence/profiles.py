"""Hypothesis profiles: ``dev``, ``ci`` (``make test``), ``certify`` (``make certify``) and
``certify-full`` (``make certify-full``) (SR-EVD-3).

Registered when the evidence plugin is imported, i.e. before pytest parses
``--hypothesis-profile``. ``ci`` and the two certify profiles are derandomized and keep no
example database, so two machines run the same examples; the certify profiles run three times
as many and print the reproduce blob of any failure. :func:`examples` scales a property's own
budget by profile for the few properties that need more (fuzzers) or fewer (expensive oracles)
than the default.

``certify-full`` is ``certify`` with the long campaigns at their full size (a million fuzzed
frames per protocol, an hour-long soak, 300 closed-loop encounters, every availability
comparison): the figures that take more than the half hour ``make certify`` is given on two
cores. :func:`certifying` is true under both; :func:`by_profile` picks a campaign's size.
"""

from __future__ import annotations

from typing import TypeVar

from hypothesis import HealthCheck, Phase, Verbosity, settings

__all__ = [
    "PROFILES",
    "active_profile",
    "by_profile",
    "certifying",
    "examples",
    "register_profiles",
]

PROFILES: dict[str, dict[str, object]] = {
    "dev": {"max_examples": 50, "deadline": None, "print_blob": True},
    "ci": {
        "max_examples": 100,
        "deadline": None,
        "derandomize": True,
        "database": None,
        "print_blob": True,
        "suppress_health_check": [HealthCheck.too_slow],
    },
    "certify": {
        "max_examples": 300,
        "deadline": None,
        "derandomize": True,
        "database": None,
        "print_blob": True,
        "verbosity": Verbosity.normal,
        "phases": [Phase.explicit, Phase.reuse, Phase.generate, Phase.target, Phase.shrink],
        "suppress_health_check": [HealthCheck.too_slow],
    },
}
PROFILES["certify-full"] = dict(PROFILES["certify"])

# How much each profile multiplies a property's own example budget (docs/findings/README.md has
# where certify's time goes).
_SCALE = {"dev": 0.5, "ci": 1.0, "certify": 3.0, "certify-full": 3.0}

_active = "default"

T = TypeVar("T")


def register_profiles() -> None:
    """Register the three profiles with Hypothesis (idempotent)."""
    for name, options in PROFILES.items():
        settings.register_profile(name, **options)  # type: ignore[arg-type]


def set_active_profile(name: str) -> None:
    """Remember which profile this session loaded (the plugin calls this)."""
    global _active
    _active = name


def active_profile() -> str:
    """The profile name this session runs under (``default`` when none was chosen)."""
    return _active


def examples(ci: int) -> int:
    """A property's example budget under the active profile, given its budget under ``ci``.

    ``dev`` halves it, ``certify`` multiplies it by three; ``default`` keeps it.
    """
    if ci < 1:
        raise ValueError(f"examples: ci budget must be >= 1, got {ci}")
    return max(1, int(ci * _SCALE.get(_active, 1.0)))


def certifying() -> bool:
    """Whether this session certifies (``certify`` or ``certify-full``)."""
    return _active in ("certify", "certify-full")


def by_profile(ci: T, certify: T, full: T | None = None) -> T:
    """What a campaign runs under the active profile: ``full`` under certify-full (``certify``
    when not given), ``certify`` under certify, else ``ci`` (a number of seeds, a duration in
    seconds, a tuple of cases)."""
    if _active == "certify-full" and full is not None:
        return full
    return certify if certifying() else ci
