"""The team's braking formula (what the example certifies)."""


def stopping_distance_m(speed_mps: float, decel_mps2: float) -> float:
    """Distance to stop from ``speed_mps`` braking at ``decel_mps2``."""
    return speed_mps * speed_mps / (2.0 * decel_mps2)
