"""``tug_overtaking``: a baggage tug overtakes the robot from behind and turns across its lane
(SR-LID-4), the scenario a second, rear-facing scanner is for.

On the apron's service road (:func:`~pipeline.sources.sim.layouts.apron_stand`, the road along
x at y = 0) the robot drives along y = -1.2 towards +x. A tug starts 7-10 m behind it in the
other lane (y = 1.2) at 2.5-3.0 m/s, overtakes, and 3.5-5 m ahead of the robot turns right
through 90 deg at 1 rad/s, crossing the robot's lane towards the stands. A scanner facing
forward over 270 deg first sees the tug when it is about level with the robot (its blind wedge
is the 90 deg behind); a rear scanner sees it from the start.
"""

from __future__ import annotations

import math

import numpy as np

from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import Route
from pipeline.sources.sim.layouts import apron_stand
from pipeline.sources.sim.objects import baggage_tug
from pipeline.sources.sim.world import SimObject, World

__all__ = ["LANE_Y_M", "tug_overtaking"]

# The robot's lane and the other lane of the service road [m].
LANE_Y_M = -1.2
_OTHER_LANE_Y_M = 1.2
# The robot's nominal speed on the road [m/s] (``sim.ego_speed_mps``'s default), for timing
# the tug's turn.
_ROBOT_SPEED_MPS = 1.0


def tug_overtaking(rng: np.random.Generator, duration_s: float) -> tuple[World, Route]:
    """The world and the robot's route of ``tug_overtaking`` (module docstring)."""
    behind_m = float(rng.uniform(7.0, 10.0))
    speed = float(rng.uniform(2.5, 3.0))
    ahead_m = float(rng.uniform(3.5, 5.0))
    # The tug's nose passes ahead_m in front of the robot's centre when the turn starts.
    turn_s = (behind_m + ahead_m) / (speed - _ROBOT_SPEED_MPS)
    motion = mo.turning(speed, turn_s, -math.pi / 2, 1.0)
    trajectory = mo.integrate(motion, -behind_m, _OTHER_LANE_Y_M, 0.0, duration_s + 0.5)
    tug = SimObject(1, "tug_overtaking", baggage_tug(), trajectory, motion)
    layout = apron_stand()
    world = World(
        "tug_overtaking", layout.structure, (tug,), layout.bounds_m, "apron", layout.decor
    )
    return world, Route(np.array([[0.0, LANE_Y_M], [40.0, LANE_Y_M]]))
