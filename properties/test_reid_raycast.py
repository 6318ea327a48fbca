"""Re-identification on ray-cast occlusion scenarios (SR-TRK-9): ID switches with it on and
off, and how often a dormant track is given to the wrong object."""

from __future__ import annotations

import numpy as np
import pytest

from evidence.profiles import by_profile, certifying
from evidence.record import Recorder
from pipeline.config import SafecaseConfig, overridden
from properties.ahead import ahead
from properties.airside_runs import airside_frames, motmetrics_counts, score_chain

CODE = ["pipeline/track/tracker.py", "pipeline/track/lifecycle.py"]
OCCLUSIONS = ("walker_behind_carts", "tug_behind_stand", "walker_crowd")


@pytest.mark.requirement("SR-TRK-9", kind="campaign", code=CODE)
@ahead
def test_reidentification_on_ray_cast_occlusions(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    """A walker behind parked carts (another walker steps out where it is expected), a tug
    behind parked passenger stairs (another tug parked where it comes out), and a crowd of
    walkers crossing: the same frames tracked with re-identification on and off; counts
    checked against py-motmetrics. A re-identification is false when the track's object
    (majority owner of its cluster's returns) is not the one it followed before."""
    certify = certifying()
    seeds = range(by_profile(ci=2, certify=10, full=20))
    duration = 15.0 if certify else 10.0
    rows = []
    totals = {"on": np.zeros(3), "off": np.zeros(3)}
    for name in OCCLUSIONS:
        sums = {"on": np.zeros(7), "off": np.zeros(7)}
        for seed in seeds:
            frames = airside_frames(safecase_config, name, seed, duration)
            for label, enabled in (("on", True), ("off", False)):
                cfg = overridden(safecase_config, {"track": {"reid_enabled": enabled}})
                score = score_chain(cfg, frames)
                q = score.quality
                ref = motmetrics_counts(score.truths, score.hypotheses)
                assert ref["num_switches"] == q.id_switches
                assert ref["num_fragmentations"] == q.fragmentations
                assert ref["mota"] == pytest.approx(q.mota, abs=1e-12)
                sums[label] += [
                    q.id_switches,
                    q.fragmentations,
                    q.n_misses + q.n_false_positives + q.id_switches,
                    q.n_truth,
                    q.n_hypothesis_ids,
                    score.reids,
                    score.false_reids,
                ]
        for label in ("on", "off"):
            s = sums[label]
            totals[label] += [s[0], s[5], s[6]]
            rate = f"{s[6] / s[5]:.0%}" if s[5] else "-"
            rows.append(
                [
                    name,
                    label,
                    int(s[0]),
                    int(s[1]),
                    f"{1.0 - s[2] / s[3]:.3f}",
                    int(s[4]),
                    int(s[5]),
                    int(s[6]),
                    rate,
                ]
            )
    evidence.table(
        "re-identification on vs off, ray-cast occlusions",
        [
            "scenario",
            "re-identification",
            "ID switches",
            "fragmentations",
            "MOTA",
            "track IDs",
            "re-identifications",
            "false (another object)",
            "false rate",
        ],
        rows,
        caption=f"{len(seeds)} seed(s) x {duration:.0f} s per scenario, robot standing; a "
        "person's two legs are often two clusters and two tracks, each counted",
    )
    on, off = totals["on"], totals["off"]
    evidence.counts(
        "all scenarios",
        {
            "ID switches, re-identification on": int(on[0]),
            "ID switches, re-identification off": int(off[0]),
            "re-identifications": int(on[1]),
            "false re-identifications": int(on[2]),
        },
    )
    assert on[1] > 0, "no re-identification happened: nothing was measured"
    assert off[1] == 0
