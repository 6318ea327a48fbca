"""Reference for the stopping model: integrate the motion numerically with scipy (SR-STOP-1).

Independent of :mod:`safety.model.stopping`'s closed form: the robot's state (position, speed) and
the obstacle's travel are integrated by scipy's adaptive Runge-Kutta solver (``solve_ivp``, RK45),
first for the reaction latency at the latency acceleration, then braking until an event finds the
moment the speed reaches zero. What the closed form and the integration share is only the physical
set-up (constant acceleration, then constant braking, obstacle at constant speed).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from pipeline.types import FloatArray
from safety.model.readings import Real
from safety.model.stopping import StoppingParams, stopping_time_s

__all__ = ["SimulatedStop", "check_against_simulation", "simulate_stop"]

_RTOL = 1e-11
_ATOL = 1e-13


@dataclass(frozen=True, slots=True)
class SimulatedStop:
    """Outcome of one simulated stop: robot travel, obstacle travel and time to standstill."""

    robot_travel_m: float
    obstacle_travel_m: float
    stop_time_s: float

    @property
    def separation_m(self) -> float:
        """Gap consumed by both: robot travel plus the obstacle's approach [m]."""
        return self.robot_travel_m + self.obstacle_travel_m


def _motion(accel_mps2: float, closing_mps: float) -> Callable[[float, FloatArray], list[float]]:
    def rhs(_t: float, y: FloatArray) -> list[float]:
        return [y[1], accel_mps2, closing_mps]

    return rhs


def simulate_stop(
    v_mps: float, reaction_s: float, accel_mps2: float, decel_mps2: float, closing_mps: float
) -> SimulatedStop:
    """Integrate latency (accelerating at ``accel_mps2``), then braking at ``decel_mps2``."""
    state = np.array([0.0, v_mps, 0.0])
    if reaction_s > 0.0:
        latency = solve_ivp(
            _motion(accel_mps2, closing_mps),
            (0.0, reaction_s),
            state,
            method="RK45",
            rtol=_RTOL,
            atol=_ATOL,
        )
        state = latency.y[:, -1]
    if state[1] <= 0.0:
        return SimulatedStop(float(state[0]), float(state[2]), reaction_s)

    def stopped(_t: float, y: FloatArray) -> float:
        return float(y[1])

    stopped.terminal = True  # type: ignore[attr-defined]
    stopped.direction = -1  # type: ignore[attr-defined]
    # Braking ends at v / decel; integrate well past it and let the event find the instant.
    horizon = reaction_s + 2.0 * float(state[1]) / decel_mps2 + 1.0
    braking = solve_ivp(
        _motion(-decel_mps2, closing_mps),
        (reaction_s, horizon),
        state,
        method="RK45",
        rtol=_RTOL,
        atol=_ATOL,
        events=stopped,
        dense_output=True,
    )
    if braking.t_events[0].size == 0:
        raise RuntimeError("simulate_stop: the robot never reached standstill")
    t_stop = float(braking.t_events[0][0])
    final = braking.y_events[0][0]
    return SimulatedStop(float(final[0]), float(final[2]), t_stop)


def check_against_simulation(
    model: Callable[[Real, Real, Real, Real, Real], Real], p: StoppingParams, u: tuple[float, ...]
) -> None:
    """The closed form ``model`` agrees with the numerical integration at one random point."""
    v_max = max(float(p.robot_max_speed_mps), *(float(c) for c in p.caps_mps))
    v = u[0] * v_max
    t = u[1] * float(p.reaction_s)
    a = u[2] * float(p.accel_max_mps2)
    b = float(p.decel_min_mps2) + u[3] * float(p.decel_max_mps2 - p.decel_min_mps2)
    c = u[4] * float(p.worst_closing_speed_mps)
    simulated = simulate_stop(v, t, a, b, c)
    closed = model(v, t, a, b, c)
    assert abs(closed - simulated.separation_m) <= 1e-8 * (1.0 + simulated.separation_m), (
        f"closed form {closed} m vs integrated {simulated.separation_m} m at v={v}, T={t}, "
        f"A={a}, b={b}, V={c}"
    )
    assert abs(stopping_time_s(v, t, a, b) - simulated.stop_time_s) <= 1e-8 * (
        1.0 + simulated.stop_time_s
    )
