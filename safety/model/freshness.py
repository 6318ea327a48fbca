"""The freshness guard: is a stamped reading recent enough to use? (SR-FUS-1, SR-FUS-2)

:func:`is_fresh` is the ONE definition of "recent enough to use", written with ``-``, ``<=``
and ``&`` only, so the same function evaluates with floats, numpy arrays and z3 terms
(``properties/test_staleness.py`` proves the z3 reading). A reading stamped ``stamp_s`` on a
sensor clock that may differ from the decision clock by at most ``skew_s`` is used at decision
time ``now_s`` only when its reported age ``a = now_s - stamp_s`` satisfies

    ``-skew_s <= a <= max_age_s - skew_s - guard_s``.

Then its true age (decision time minus true capture time) is at most ``max_age_s``: the
stamp is off by at most ``skew_s``. ``guard_s`` (1 ns at run time) absorbs float rounding: near
the threshold the age is at most ``max_age_s <= 10 s`` (the configured bound), so each of the
three rounded operations errs by at most half an ulp of 16 s (1.8e-15 s), far below 1 ns; with
stamps on a common epoch (Unix seconds) ``now_s - stamp_s`` is even exact (Sterbenz). NaN and
infinite stamps compare false and are never fresh.

Who reads it: the scan-freshness monitor (:mod:`safety.model.monitors`) and fusion, which is
given it (:class:`pipeline.fusion.GatedFusion`, built by :class:`safety.runtime.Runtime`) to
decide which thermal and radar detections may still be fused.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FRESHNESS_GUARD_S", "is_fresh"]

# Time held back from every maximum age [s]: absorbs float rounding (see the module docstring).
FRESHNESS_GUARD_S = 1e-9


def is_fresh(
    now_s: Any, stamp_s: Any, max_age_s: Any, skew_s: Any, guard_s: Any = FRESHNESS_GUARD_S
) -> Any:
    """True where a reading stamped ``stamp_s`` may be used at ``now_s`` (SR-FUS-1, SR-FUS-2).

    One definition, every reading (float, numpy, z3): the reported age must lie in
    ``[-skew_s, max_age_s - skew_s - guard_s]`` [s]. With ``|stamp - true capture| <= skew_s``
    this bounds the true age by ``max_age_s``; stamps further in the future than the skew
    allows are refused too (the skew assumption is broken, so nothing can be concluded).
    """
    age_s = now_s - stamp_s
    return (age_s >= -skew_s) & (age_s <= max_age_s - skew_s - guard_s)
