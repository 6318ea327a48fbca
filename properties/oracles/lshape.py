"""Brute-force L-shape fit: the criteria of Zhang et al. (IEEE IV 2017), written out point by
point in plain Python for one cluster (test-only oracle of SR-TRK-7).

This follows the paper's Algorithm 1 to 4 literally, with no shortcut: for every angle of the
grid it projects the points, picks each axis' nearer edge by the Euclidean norm of the two
distance vectors (``argmin_{v in {c_max - C, C - c_min}} ||v||``; both when they tie within
rounding), and evaluates the criterion with ``math``. The fast fit
(:mod:`pipeline.shape.lshape`) centres the points and reduces the norm comparison algebraically,
so agreement is a check of that algebra too.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["brute_force_lshape"]


def _variance(values: Sequence[float]) -> float:
    if not values:
        return 0.0
    mean = math.fsum(values) / len(values)
    return math.fsum((v - mean) ** 2 for v in values) / len(values)


def _near_tie(a: float, b: float) -> bool:
    return abs(a - b) <= 1e-9 * max(a, b, 1e-300)


def _scores(c1: list[float], c2: list[float], criterion: str, floor_m: float) -> list[float]:
    """The criterion's value at one angle: one value, or one per choice of edge where the two
    edges of an axis tie by norm (within rounding, e.g. a symmetric cluster): the paper's
    argmin is then decided by rounding, and each choice is a legitimate evaluation."""
    hi1, lo1, hi2, lo2 = max(c1), min(c1), max(c2), min(c2)
    if criterion == "area":
        return [-(hi1 - lo1) * (hi2 - lo2)]

    def norm(vec: list[float]) -> float:
        return math.sqrt(math.fsum(v * v for v in vec))

    choices = []
    for c, hi, lo in ((c1, hi1, lo1), (c2, hi2, lo2)):
        to_hi = [hi - v for v in c]
        to_lo = [v - lo for v in c]
        n_hi, n_lo = norm(to_hi), norm(to_lo)
        if _near_tie(n_hi, n_lo):
            choices.append([to_hi, to_lo])
        else:
            choices.append([to_hi if n_hi <= n_lo else to_lo])
    out = []
    for d1 in choices[0]:
        for d2 in choices[1]:
            if criterion == "closeness":
                out.append(
                    math.fsum(1.0 / max(min(a, b), floor_m) for a, b in zip(d1, d2, strict=True))
                )
            else:
                e1 = [a for a, b in zip(d1, d2, strict=True) if a < b]
                e2 = [b for a, b in zip(d1, d2, strict=True) if b < a]
                out.append(-_variance(e1) - _variance(e2))
    return out


def brute_force_lshape(
    x_m: Sequence[float],
    y_m: Sequence[float],
    angles_rad: Sequence[float],
    criterion: str,
    floor_m: float,
) -> list[list[float]]:
    """The criterion's value(s) at every angle of ``angles_rad`` for one cluster's points
    (module docstring): the best angle is the first maximum of these values."""
    values = []
    for theta in angles_rad:
        c, s = math.cos(theta), math.sin(theta)
        c1 = [c * x + s * y for x, y in zip(x_m, y_m, strict=True)]
        c2 = [-s * x + c * y for x, y in zip(x_m, y_m, strict=True)]
        values.append(_scores(c1, c2, criterion, floor_m))
    return values
