"""Speed governor: free distance along the path -> PROCEED / SLOW(v) / STOP (SR-STOP-2).

For each obstacle ahead the caller gives the free distance along the robot's path to the
obstacle's predicted zone [m], how fast it may close in [m/s] (from its class) and, when known,
its classification confidence and near-reversal flag (which select its margin tier and the
tier's speed cap). The commanded speed is the smallest over obstacles of
:func:`governed_speed_mps`, which is the stopping model's
:func:`safety.model.stopping.safe_speed_mps` (the same function that sets the tier caps) evaluated
at the worst-case parameters, capped by the robot's maximum speed and, once the obstacle's margin
band reaches the path, by its tier's speed cap, and set to 0 below
``governor.min_moving_speed_mps``. z3 proves about this very function that a moving command needs at
most the free distance to stop, for every distance ``d >= 0`` and every parameter in its configured
range, and that it is monotone in ``d``.

The runtime path never raises: non-finite or negative inputs, mismatched shapes or anything
unexpected give STOP with the reason recorded in the :class:`~pipeline.types.Command`.
"""

from __future__ import annotations

import math
from fractions import Fraction
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.config import GovernorSection, SafecaseConfig
from pipeline.types import Action, Command, FloatArray
from safety.model.readings import Real, is_symbolic, minimum, select
from safety.model.stopping import StoppingParams, safe_speed_mps

__all__ = ["FLOAT_GUARD_M", "Governor", "governed_speed_mps"]

# Distance held back from every free distance [m]: it absorbs float rounding of the closed form
# (a few ulp of metres), so the float runtime stays inside what the real-arithmetic proof covers.
# It is part of the one definition, so the proofs see it too.
FLOAT_GUARD_M = Fraction(1, 10**9)

_MAX_LISTED = 5


def governed_speed_mps(
    free_distance_m: Real,
    closing_mps: Real,
    margin_m: Real,
    tier_cap_mps: Real,
    params: StoppingParams,
    min_moving_mps: Real,
) -> Real:
    """Commanded speed limit [m/s] for one obstacle (SR-STOP-2): one definition, every reading.

    The largest speed that stops within ``free_distance_m`` under the worst case (reaction
    latency ``T``, acceleration ``A`` during it, braking ``b_min``, obstacle closing at
    ``closing_mps``), at most the robot's maximum speed, and at most the tier's speed cap once
    the obstacle's margin band reaches the path (``free_distance_m <= margin_m``); 0 (STOP) when
    that is below ``min_moving_mps``.
    """
    exact = isinstance(free_distance_m, Fraction) or is_symbolic(free_distance_m)
    guard = FLOAT_GUARD_M if exact else float(FLOAT_GUARD_M)
    reachable = safe_speed_mps(
        free_distance_m - guard,
        params.reaction_s,
        params.accel_max_mps2,
        params.decel_min_mps2,
        closing_mps,
    )
    capped = minimum(reachable, params.robot_max_speed_mps)
    speed = select(free_distance_m <= margin_m, minimum(capped, tier_cap_mps), capped)
    return select(speed >= min_moving_mps, speed, 0 * speed)


class Governor:
    """The run-time governor for one configuration (SR-STOP-2).

    ``params`` overrides the stopping parameters (e.g. a measured latency bound fed in by the
    timing work through :meth:`StoppingParams.from_config`).
    """

    def __init__(self, section: GovernorSection, params: StoppingParams) -> None:
        self.params = params
        self.min_moving_mps = float(section.min_moving_speed_mps)
        self.max_speed_mps = float(self.params.robot_max_speed_mps)

    @classmethod
    def from_config(cls, config: SafecaseConfig, params: StoppingParams | None = None) -> Governor:
        """The governor of ``config`` (its stopping parameters unless ``params`` is given)."""
        stopping = params if params is not None else StoppingParams.from_config(config)
        return cls(config.governor, stopping)

    def speed_limits_mps(
        self,
        free_distance_m: FloatArray,
        closing_mps: FloatArray,
        margin_m: FloatArray,
        tier_cap_mps: FloatArray,
    ) -> FloatArray:
        """Per-obstacle speed limits [m/s] (vectorised; inputs already validated)."""
        limits: FloatArray = governed_speed_mps(
            free_distance_m, closing_mps, margin_m, tier_cap_mps, self.params, self.min_moving_mps
        )
        return limits

    def command(
        self,
        stamp_s: float,
        free_distance_m: npt.ArrayLike,
        closing_speed_mps: npt.ArrayLike | None = None,
        confidence: npt.ArrayLike | None = None,
        near_reversal: npt.ArrayLike | None = None,
    ) -> Command:
        """The command for this cycle. Never raises: bad input gives STOP with the reason.

        ``closing_speed_mps`` defaults to the worst class's closing speed; ``confidence``
        (in [0, 1]) defaults to "unknown", which takes the near-reversal tier (the most
        cautious); ``near_reversal`` defaults to False.
        """
        try:
            return self._command(
                stamp_s, free_distance_m, closing_speed_mps, confidence, near_reversal
            )
        except Exception as exc:  # the runtime path must fail safe, whatever went wrong
            return _stop(stamp_s, [f"governor error ({type(exc).__name__}): {exc}"])

    def _command(
        self,
        stamp_s: float,
        free_distance_m: npt.ArrayLike,
        closing_speed_mps: npt.ArrayLike | None,
        confidence: npt.ArrayLike | None,
        near_reversal: npt.ArrayLike | None,
    ) -> Command:
        problems: list[str] = []
        if not isinstance(stamp_s, float | int) or not math.isfinite(stamp_s):
            problems.append(f"stamp_s = {stamp_s!r}: expected a finite time in seconds")
        worst = float(self.params.worst_closing_speed_mps)
        inputs: dict[str, FloatArray] = {}
        for name, raw, default in (
            ("free_distance_m", free_distance_m, None),
            ("closing_speed_mps", closing_speed_mps, worst),
            ("confidence", confidence, -1.0),
        ):
            array = _as_float_array(name, raw if raw is not None else default, problems)
            if array is not None:
                inputs[name] = array
        flags = _as_bool_array(near_reversal, problems)
        if problems:
            return _stop(stamp_s, problems)
        try:
            distance, closing, conf, reversal = (
                np.atleast_1d(a)
                for a in np.broadcast_arrays(
                    inputs["free_distance_m"],
                    inputs["closing_speed_mps"],
                    inputs["confidence"],
                    flags,
                )
            )
        except ValueError:
            shapes = ", ".join(f"{k} {v.shape}" for k, v in inputs.items())
            return _stop(
                stamp_s, [f"input shapes do not match: {shapes}, near_reversal {flags.shape}"]
            )
        _check_range("free_distance_m", distance, 0.0, math.inf, problems)
        _check_range("closing_speed_mps", closing, 0.0, math.inf, problems)
        if confidence is not None:
            _check_range("confidence", conf, 0.0, 1.0, problems)
        if problems:
            return _stop(stamp_s, problems)
        if distance.size == 0:
            return Command(Action.PROCEED, self.max_speed_mps, float(stamp_s))
        # Unknown confidence (-1) falls below every threshold: the near-reversal tier applies.
        flags = reversal.astype(bool)
        margins = np.asarray(self.params.margin_for(conf, flags), dtype=np.float64)
        caps = np.asarray(self.params.cap_for(conf, flags), dtype=np.float64)
        limits = self.speed_limits_mps(distance, closing, margins, caps)
        binding = int(np.argmin(limits))
        speed = float(limits[binding])
        if speed >= self.max_speed_mps:
            return Command(Action.PROCEED, self.max_speed_mps, float(stamp_s))
        why = (
            f"obstacle {binding}: free distance {distance[binding]:.3f} m, closing "
            f"{closing[binding]:.2f} m/s, margin {margins[binding]:.2f} m, "
            f"tier cap {caps[binding]:.3f} m/s"
        )
        if speed == 0.0:
            return Command(
                Action.STOP,
                0.0,
                float(stamp_s),
                (f"{why}: no speed >= {self.min_moving_mps} m/s can stop within it",),
            )
        return Command(Action.SLOW, speed, float(stamp_s), (f"{why}: limit {speed:.3f} m/s",))


def _stop(stamp_s: Any, reasons: list[str]) -> Command:
    try:
        stamp = float(stamp_s)
    except (TypeError, ValueError):
        stamp = math.nan
    return Command(Action.STOP, 0.0, stamp, tuple(reasons))


def _as_float_array(name: str, raw: Any, problems: list[str]) -> FloatArray | None:
    if raw is None:
        problems.append(f"{name} is missing: expected distances in metres")
        return None
    try:
        array = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        problems.append(f"{name} = {raw!r}: expected numbers ({exc})")
        return None
    if array.ndim > 1:
        problems.append(f"{name}: expected one value per obstacle, got shape {array.shape}")
        return None
    return array


def _as_bool_array(raw: Any, problems: list[str]) -> npt.NDArray[np.bool_]:
    if raw is None:
        return np.zeros((), dtype=bool)
    array = np.asarray(raw)
    if array.dtype != np.bool_:
        problems.append(f"near_reversal = {raw!r}: expected booleans")
        return np.zeros((), dtype=bool)
    return array


def _check_range(
    name: str, values: FloatArray, low: float, high: float, problems: list[str]
) -> None:
    bad = ~(np.isfinite(values) & (values >= low) & (values <= high))
    if np.any(bad):
        where = np.flatnonzero(bad)
        listed = ", ".join(f"[{i}] = {float(values[i])!r}" for i in where[:_MAX_LISTED])
        more = f" (+{where.size - _MAX_LISTED} more)" if where.size > _MAX_LISTED else ""
        problems.append(
            f"{name} {listed}{more}: expected finite values >= {low}"
            + ("" if math.isinf(high) else f" and <= {high}")
        )
