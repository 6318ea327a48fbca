"""The person floor's cost in availability: ``safecase run --compare`` figures, floor off and on.

For each scenario and seed, :func:`safety.availability.compare` (ours, the oracle, the Nav2-style
baseline, and the shadow oracle that judges nuisance STOPs) runs twice: with the person floor
switched off (``pipeline.predict.person_compatible`` replaced, for that run only, by a predicate
that holds for no track, in our chain and the oracle's alike) and as configured. SR-CLS-8;
the figures are in docs/findings/classification.md.

    .venv/bin/python -m properties.person_floor_cost crossing_pedestrian pallet_jack_slow --seeds 0
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

import pipeline.predict as predict_module
from pipeline.classify.model import Classifier
from pipeline.config import PredictSection, SafecaseConfig, default_config
from pipeline.types import BoolArray, TrackFeatures
from safety.availability import Comparison, compare

__all__ = ["floor_switched_off", "main", "row"]


def _never(features: TrackFeatures, predict: PredictSection) -> BoolArray:
    compatible: BoolArray = np.zeros(features.values.shape[0], dtype=np.bool_)
    return compatible


@contextmanager
def floor_switched_off() -> Iterator[None]:
    """Within the block no track is person-compatible (the floor never applies)."""
    kept = predict_module.person_compatible
    predict_module.person_compatible = _never
    try:
        yield
    finally:
        predict_module.person_compatible = kept


def row(name: str, seed: int, floor: str, c: Comparison) -> list[str]:
    """One table row: scenario, seed, floor, progress share, our and the oracle's progress,
    nuisance STOP cycles (share of time), our STOP cycles, contacts while moving."""
    m = c.metrics()
    ours, oracle = m["ours"], m["oracle"]
    return [
        name,
        str(seed),
        floor,
        f"{c.progress_share():.1%}",
        f"{ours.progress_m:.2f} m",
        f"{oracle.progress_m:.2f} m",
        f"{c.nuisance_cycles} ({c.nuisance_share:.1%})",
        str(ours.actions.get("STOP", 0)),
        str(ours.moving_contacts),
    ]


def measure(
    config: SafecaseConfig, scenarios: list[str], seeds: list[int], duration_s: float
) -> Iterator[list[str]]:
    """Rows of :func:`row`, floor off then on, per scenario and seed."""
    model = Classifier.from_config(config.classify)
    for name in scenarios:
        for seed in seeds:
            with floor_switched_off():
                off = compare(config, name, seed, duration_s, classifier=model)
            yield row(name, seed, "off", off)
            on = compare(config, name, seed, duration_s, classifier=model)
            yield row(name, seed, "on", on)


def main() -> None:
    """Print a Markdown table of the figures (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenarios", nargs="+")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument("--duration", type=float, default=15.0)
    args = parser.parse_args()
    head = [
        "scenario",
        "seed",
        "floor",
        "progress vs oracle",
        "ours",
        "oracle",
        "nuisance STOP cycles",
        "our STOP cycles",
        "contacts while moving",
    ]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for cells in measure(default_config(), args.scenarios, args.seeds, args.duration):
        print("| " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
