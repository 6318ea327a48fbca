"""What a rear scanner buys on ``tug_overtaking`` (SR-LID-4): the same seeds run in closed loop
by a robot with one forward scanner over 270 deg and by the same robot with a second one facing
backwards (``scan2``), and compared.

Per run: when the overtaking tug first has a confirmed track within :data:`SEEN_GATE_M` of its
true centre (the simulated clock [s], and where the tug then was along the road relative to
the robot's centre [m]: negative is behind), contacts while moving, the closest approach and the
progress. ``python -m properties.second_lidar_study [--seeds N]`` prints the table that
docs/findings/second-lidar.md shows.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import SafecaseConfig, default_config, overridden
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import BOUNDED
from pipeline.types import TrackStatus
from safety.cycle import CycleInput, CycleOutput
from safety.run import contact_speeds, run_simulation
from safety.runtime import Runtime

__all__ = ["HEADER", "SEEN_GATE_M", "OvertakeRun", "front_rear_config", "overtaking_run", "table"]

SEEN_GATE_M = 1.5
"""How near a confirmed track's position must be to the tug's true centre to count as it [m]
(the tug is 2.6 m long: a cluster of its visible side lies within this of its centre)."""

# The robot of the study: a forward scanner over 270 deg at its front edge; the rear one, when
# enabled, at its back edge facing backwards (the scan2 defaults).
_FRONT = {"sim": {"fov_deg": 270.0, "mount_x_m": 0.45}, "scan": {"mount_x_m": 0.45}}


def front_rear_config(base: SafecaseConfig, rear: bool) -> SafecaseConfig:
    """``base`` on the study's robot, with or without the rear scanner."""
    return overridden(base, {**_FRONT, "scan2": {"enabled": rear}})


@dataclass(frozen=True, slots=True)
class OvertakeRun:
    """One closed-loop run of ``tug_overtaking`` (module docstring)."""

    seed: int
    rear: bool
    seen_s: float
    seen_along_m: float
    moving_contacts: int
    closest_m: float
    progress_m: float
    cycles: int
    second_left_out: int


def overtaking_run(
    base: SafecaseConfig, seed: int, rear: bool, duration_s: float = 14.0
) -> OvertakeRun:
    """Run seed ``seed`` of ``tug_overtaking`` on the study's robot (module docstring)."""
    config = front_rear_config(base, rear)
    sim = make_simulation(config, "tug_overtaking", seed, duration_s, retention=BOUNDED)
    tug = sim.world.objects[0].trajectory
    seen = [math.inf, math.nan]
    left_out = [0]

    def observe(inp: CycleInput, out: CycleOutput) -> None:
        detail = out.detail
        perceived = None if detail is None else detail.perceived
        if perceived is None or inp.scan is None:
            return
        second = perceived.tracked.second
        if second is not None and not second.merged:
            left_out[0] += 1
        if math.isfinite(seen[0]):
            return
        t = inp.scan.stamp_s
        at = tug.at(np.array([t]))
        tracks = perceived.fused.tracks
        confirmed = tracks.status == int(TrackStatus.CONFIRMED)
        dx = tracks.state[confirmed, 0] - at["x_m"][0]
        dy = tracks.state[confirmed, 1] - at["y_m"][0]
        if np.any(np.hypot(dx, dy) <= SEEN_GATE_M):
            seen[0] = t
            seen[1] = float(at["x_m"][0] - inp.robot_pose[0])

    summary = run_simulation(config, sim, runtime=Runtime(config), observe=observe)
    result = summary.sim
    assert result is not None  # run_simulation sets it
    speeds = contact_speeds(result)
    return OvertakeRun(
        seed,
        rear,
        seen[0],
        seen[1],
        int(np.count_nonzero(speeds > 0.0)),
        float(np.min(result.min_separation_m, initial=math.inf)),
        float(result.ego_log["arc_m"][-1]),
        summary.cycles,
        left_out[0],
    )


HEADER = [
    "seed",
    "tug tracked at [s] (front / +rear)",
    "tug then along the road [m]",
    "contacts moving",
    "closest [m]",
    "progress [m]",
]


def table(runs: list[OvertakeRun]) -> list[list[str]]:
    """One row per seed (columns :data:`HEADER`): front only / front + rear."""
    by = {(r.seed, r.rear): r for r in runs}
    rows = []
    for seed in sorted({r.seed for r in runs}):
        f, b = by[(seed, False)], by[(seed, True)]
        rows.append(
            [
                str(seed),
                f"{f.seen_s:.1f} / {b.seen_s:.1f}",
                f"{f.seen_along_m:+.1f} / {b.seen_along_m:+.1f}",
                f"{f.moving_contacts} / {b.moving_contacts}",
                f"{f.closest_m:.2f} / {b.closest_m:.2f}",
                f"{f.progress_m:.1f} / {b.progress_m:.1f}",
            ]
        )
    return rows


def main() -> None:
    """Print the study's table for seeds 0..N-1."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10)
    args = parser.parse_args()
    base = default_config()
    runs = [overtaking_run(base, s, rear) for s in range(args.seeds) for rear in (False, True)]
    print("| " + " | ".join(HEADER) + " |")
    print("|" + "---:|" * len(HEADER))
    for row in table(runs):
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
