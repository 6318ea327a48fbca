"""What a cycle's fusion did with the radar, from the raw returns on (SR-FUS-9).

The perception chain runs the radar's front-end (:class:`pipeline.sensors.radar.RadarFrontEnd`)
before fusion; :class:`RadarFusionCounts` is the cycle's :class:`~pipeline.types.FusionCounts`
with the front-end's account added, and is what the audit log records as the cycle's fusion
part when the frame had radar.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

from pipeline.sensors.radar import RadarCounts
from pipeline.types import FusionCounts

__all__ = ["RadarFusionCounts"]


@dataclass(frozen=True, slots=True)
class RadarFusionCounts(FusionCounts):
    """:class:`FusionCounts` of a frame whose radar went through the front-end (SR-FUS-9), so
    that the audit log says what became of every raw return: each of ``n_radar_returns`` is
    dropped by the front-end (``n_radar_dropped_invalid``, ``n_radar_low_rcs``,
    ``n_radar_low_snr``, ``n_radar_clutter``, ``n_radar_ghost``) or kept, and the kept ones are
    fusion's ``n_radar``; with the scan's LiDAR degradation index, the position weight the
    front-end gave the kept returns (0: their Doppler only, or none kept) and how many radar-
    refined tracks were written back into the tracker's filter (``radar.write_back``)."""

    n_radar_returns: int = 0
    n_radar_dropped_invalid: int = 0
    n_radar_low_rcs: int = 0
    n_radar_low_snr: int = 0
    n_radar_clutter: int = 0
    n_radar_ghost: int = 0
    radar_degradation: float = 0.0
    radar_position_weight: float = 0.0
    n_radar_written_back: int = 0

    def __post_init__(self) -> None:
        FusionCounts.__post_init__(self)  # slots: no zero-argument super()
        dropped = (
            self.n_radar_dropped_invalid, self.n_radar_low_rcs, self.n_radar_low_snr,
            self.n_radar_clutter, self.n_radar_ghost,
        )  # fmt: skip
        if not 0 <= self.n_radar_written_back <= self.n_radar_matched:
            raise ValueError(
                f"RadarFusionCounts: {self.n_radar_written_back} written back of "
                f"{self.n_radar_matched} matched"
            )
        if min(dropped) < 0 or sum(dropped) + self.n_radar != self.n_radar_returns:
            raise ValueError(
                f"RadarFusionCounts: dropped {dropped} and kept {self.n_radar} must sum to "
                f"{self.n_radar_returns}"
            )

    @staticmethod
    def of(
        counts: FusionCounts,
        front: RadarCounts,
        degradation: float,
        weight: float,
        written_back: int = 0,
    ) -> RadarFusionCounts:
        """``counts`` with the front-end's ``front`` counts, index, weight and write-backs."""
        return RadarFusionCounts(
            **{f.name: getattr(counts, f.name) for f in fields(FusionCounts)},
            n_radar_returns=front.n_returns,
            n_radar_dropped_invalid=front.n_invalid,
            n_radar_low_rcs=front.n_low_rcs,
            n_radar_low_snr=front.n_low_snr,
            n_radar_clutter=front.n_clutter,
            n_radar_ghost=front.n_ghost,
            radar_degradation=degradation,
            radar_position_weight=weight,
            n_radar_written_back=written_back,
        )
