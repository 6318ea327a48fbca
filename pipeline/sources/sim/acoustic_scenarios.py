"""An apron scenario with a reversing beeper, and a simulator source that hears it (SR-ACU-3,
SR-ACU-5).

:func:`reversing_tug_beeping` builds ``reversing_beeper`` (:data:`ACOUSTIC_SCENARIOS`): on the
apron stand (the robot at (2, -1.2) facing +x along the service road, at rest), a baggage tug
parked nose away from the road 10-14 m ahead and 4.5 m to the left backs towards the road at
0.8 m/s for 2 s, starting 1-2 s into the run, beeping while it reverses (1.25 kHz, 0.8 s period,
duty 0.5). It stops short of the robot's lane.

:class:`HearingSimSource` wraps a :class:`~pipeline.sources.sim.source.SimSource`: every
``hop_s`` of simulated time it renders the last window of audio the configured array hears (the
beeper at its source level and 1 / r, gated by the tug's reversing, over apron noise at the
DESIGN #23 levels; the geometry frozen at the window's end), runs the detector
(:class:`pipeline.sensors.acoustic.AcousticDetector`) and puts the newest alert into each frame's
``acoustic`` field. The runtime's cautious mode then shows in the commands. Randomness through
the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import replace

import numpy as np

from pipeline.config import AcousticSection, SafecaseConfig
from pipeline.sensors.acoustic import AcousticDetector
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.acoustic import ApronNoise, Beeper, apron_noise, level_pa, source_signal
from pipeline.sources.sim.airside_scenarios import AIRSIDE_SCENARIOS
from pipeline.sources.sim.objects import baggage_tug
from pipeline.sources.sim.scenarios import ScenarioError, ScenarioSpec, place, simulation_for_spec
from pipeline.sources.sim.source import SimSource, SimSourceBeside
from pipeline.sources.sim.world import SimObject
from pipeline.types import Frame
from pipeline.types.acoustic import AcousticAlert, AudioClip

__all__ = [
    "ACOUSTIC_SCENARIOS",
    "BEEPER_NAME",
    "HearingSimSource",
    "hearing_simulation",
    "reversing_tug_beeping",
]

# The name of the beeping vehicle in the scenario's world.
BEEPER_NAME = "tug_reversing"


def reversing_tug_beeping(rng: np.random.Generator, duration: float) -> ScenarioSpec:
    """The ``reversing_beeper`` scenario (module docstring)."""
    base = AIRSIDE_SCENARIOS["tug_behind_stand"][1](rng, duration)
    start = float(rng.uniform(1.0, 2.0))
    knots = [0.0, start, start + 0.5, start + 2.0, start + 2.5]
    speeds = [0.0, 0.0, -0.8, -0.8, 0.0]
    motion = mo.Motion(np.array(knots), np.array(speeds), np.zeros(1), np.zeros(1), "backing")
    x = float(rng.uniform(12.0, 16.0))
    tug = place(1, BEEPER_NAME, baggage_tug(), motion, (x, 4.5, math.pi / 2), duration)
    world = replace(base.world, name="reversing_beeper", objects=(tug,))
    return replace(base, world=world)


ACOUSTIC_SCENARIOS: dict[str, tuple[str, Callable[[np.random.Generator, float], ScenarioSpec]]] = {
    "reversing_beeper": (
        "Apron: a baggage tug ahead and to the left backs towards the service road, beeping; "
        "the microphone array hears it and the governor is cautious while the alert is fresh.",
        reversing_tug_beeping,
    ),
}


class HearingSimSource(SimSourceBeside):
    """A closed-loop simulator source whose frames carry the microphone array's newest alert
    (module docstring). ``source_db`` is the beeper's level at 1 m [dB SPL] (reversing alarms:
    97-112 dB at 1.2 m)."""

    def __init__(
        self,
        inner: SimSource,
        section: AcousticSection,
        rng: np.random.Generator,
        *,
        beeper: Beeper | None = None,
        source_db: float = 107.0,
        noise: ApronNoise | None = None,
        window_s: float = 3.0,
        hop_s: float = 0.5,
    ) -> None:
        super().__init__(inner)
        self.section = section
        self.rng = rng
        self.beeper = beeper if beeper is not None else Beeper(0.0, 0.0)
        self.source_db = source_db
        self.noise = noise if noise is not None else ApronNoise()
        self.window_s = window_s
        self.hop_s = hop_s
        self.detector = AcousticDetector(section)
        self.vehicle = _named(inner.sim.world.objects, BEEPER_NAME)
        self.alerts: list[AcousticAlert] = []
        self._next_s = window_s
        self._alert: AcousticAlert | None = None

    def summary(self) -> str:
        """One line for a run's report: the alerts heard, the first one's stamp and bearing."""
        if not self.alerts:
            return "acoustic: no alert heard"
        first = self.alerts[0]
        kinds = ", ".join(sorted({a.kind.value for a in self.alerts}))
        return (
            f"acoustic: {len(self.alerts)} alert(s) heard ({kinds}), the first at "
            f"{first.stamp_s:.1f} s from {math.degrees(first.bearing_rad):.0f} deg (robot frame); "
            "a fresh alert caps the speed, it never places an obstacle"
        )

    def frames(self) -> Iterator[Frame]:
        """The inner source's frames, each with the newest alert heard by its stamp."""
        for frame in self.upstream.frames():
            now = frame.stamp_s
            if now >= self._next_s and frame.pose is not None:
                self._next_s = now + self.hop_s
                alert = self.detector.detect(self.heard(now, frame.pose)).alert
                if alert is not None:
                    self._alert = alert
                    self.alerts.append(alert)
            yield replace(frame, acoustic=self._alert)

    def heard(self, end_s: float, pose: tuple[float, float, float]) -> AudioClip:
        """The last ``window_s`` of audio before ``end_s`` [s] at the robot's ``pose``."""
        s = self.section
        fs, c = s.sample_rate_hz, s.speed_of_sound_mps
        n = round(self.window_s * fs)
        start_s = end_s - (n - 1) / fs
        state = self.vehicle.trajectory.at(np.array([end_s]))
        dx, dy = float(state["x_m"][0]) - pose[0], float(state["y_m"][0]) - pose[1]
        cos, sin = math.cos(pose[2]), math.sin(pose[2])
        at = replace(self.beeper, x_m=cos * dx + sin * dy, y_m=-sin * dx + cos * dy)
        mics = self.detector.mic_xy_m
        signal, sounding = source_signal(at, mics, n, fs, c)
        # The pulses' own rms at 1 m is scaled to the source level; silent while not reversing.
        reference = np.sqrt(np.mean(signal[0, sounding] ** 2)) if np.any(sounding) else 1.0
        distance = math.hypot(at.x_m - mics[0, 0], at.y_m - mics[0, 1])
        gain = level_pa(self.source_db) / (reference * max(distance, 1.0))
        times = start_s + np.arange(n) / fs
        backing = self.vehicle.trajectory.at(times)["speed_mps"] < 0.0
        audio = apron_noise(self.noise, mics, n, fs, c, self.rng) + gain * signal * backing
        return AudioClip(audio, fs, start_s, mics)


def _named(objects: tuple[SimObject, ...], name: str) -> SimObject:
    for obj in objects:
        if obj.name == name:
            return obj
    raise ValueError(f"HearingSimSource: the world has no object named {name!r}")


def hearing_simulation(
    config: SafecaseConfig, name: str, seed: int, duration_s: float
) -> HearingSimSource:
    """The acoustic scenario ``name`` (:data:`ACOUSTIC_SCENARIOS`) ready to run in closed loop
    (``safecase run --scenario reversing_beeper``): its layout drawn from ``seed`` as
    :func:`~pipeline.sources.sim.scenarios.build_scenario` draws a named scenario's, the
    scanner and braking streams as :func:`simulation_for_spec` draws them, and the apron's noise
    from a stream of its own."""
    if name not in ACOUSTIC_SCENARIOS:
        raise ScenarioError(
            f"unknown acoustic scenario {name!r}; known: {', '.join(ACOUSTIC_SCENARIOS)}"
        )
    layout, _, _, audio = np.random.SeedSequence(seed).spawn(4)
    spec = ACOUSTIC_SCENARIOS[name][1](np.random.default_rng(layout), duration_s)
    sim = simulation_for_spec(config, spec, name, seed, duration_s)
    return HearingSimSource(SimSource(sim), config.acoustic, np.random.default_rng(audio))
