"""Named scenarios, the dataset file and ``safecase sim`` (examples)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.sources.sim.dataset import DATASET_VERSION, DatasetError, load_dataset, write_dataset
from pipeline.sources.sim.objects import ObjectKind
from pipeline.sources.sim.scenarios import SCENARIOS, ScenarioError, build_scenario, make_simulation
from pipeline.sources.sim.truth import CLASS_NAMES, ObjectClass
from properties.cli_runner import run_safecase


def test_the_issue_s_scenarios_and_models_are_all_there() -> None:
    wanted = {
        "reversing_forklift_aisle",
        "crossing_pedestrian",
        "pallet_jack_slow",
        "occlusion_behind_cart",
        "forklift_pass_by",
        "dolly_train_turn",
        "tug_overtaking",
        "random_encounter",
    }
    assert wanted == set(SCENARIOS)
    assert default_config().sim.scenario == "reversing_forklift_aisle"
    kinds = {
        o.model.kind
        for name in SCENARIOS
        if name != "random_encounter"
        for o in build_scenario(name, 0, 5.0).world.objects
    }
    assert kinds == set(ObjectKind)  # every object model appears in some named scenario
    with pytest.raises(ScenarioError, match="unknown scenario 'nope'; known: reversing"):
        build_scenario("nope", 0, 1.0)


def test_the_reversing_forklift_passes_through_all_three_states() -> None:
    cfg = overridden(default_config(), {"sim": {"beams": 90}})
    result = make_simulation(cfg, "reversing_forklift_aisle", 3, 12.0).run(lambda obs: 0.0)
    labels = [int(f.truth.label[0]) for f in result.frames]
    # Forward, near reversal around the stop, reversing (moving), near reversal again as it
    # comes to rest, then at rest.
    seen = [c for i, c in enumerate(labels) if i == 0 or c != labels[i - 1]]
    assert seen == [
        ObjectClass.FORKLIFT_MOVING,
        ObjectClass.FORKLIFT_NEAR_REVERSAL,
        ObjectClass.FORKLIFT_MOVING,
        ObjectClass.FORKLIFT_NEAR_REVERSAL,
        ObjectClass.FORKLIFT_STATIONARY,
    ]
    near = labels.count(ObjectClass.FORKLIFT_NEAR_REVERSAL)
    assert 6 <= near <= 30
    assert not result.contact  # the robot stood still from the start


def test_random_encounters_differ_by_seed_and_keep_their_clearances() -> None:
    names = {
        tuple(o.name for o in build_scenario("random_encounter", s, 20.0).world.objects)
        for s in range(8)
    }
    assert len(names) > 4
    envs = {build_scenario("random_encounter", s, 20.0).world.environment for s in range(12)}
    assert envs == {"warehouse", "apron"}


def test_dataset_round_trip(tmp_path: Path) -> None:
    cfg = overridden(default_config(), {"sim": {"beams": 120}})
    path = tmp_path / "d.npz"
    meta = write_dataset(path, cfg, ["pallet_jack_slow", "reversing_forklift_aisle"], [0, 1], 2.0)
    meta2, arrays = load_dataset(path)
    assert meta == meta2
    assert meta["class_names"] == list(CLASS_NAMES)
    f = arrays["frame_run"].shape[0]
    assert f == 4 * 20
    assert arrays["ranges_m"].shape == (f, 120)
    assert arrays["obj_frame"].max() == f - 1
    # Scanner-frame positions agree with the world ones through the scanner pose.
    i = 5
    fr = arrays["obj_frame"][i]
    sx, _sy, yaw = arrays["scanner_pose"][fr]
    wx = sx + np.cos(yaw) * arrays["obj_sx_m"][i] - np.sin(yaw) * arrays["obj_sy_m"][i]
    assert wx == pytest.approx(arrays["obj_x_m"][i])
    # Returns counted per object equal the per-beam owners of the returned beams.
    owner = arrays["beam_owner"][fr]
    ret = np.isfinite(arrays["ranges_m"][fr])
    assert arrays["obj_n_returns"][i] == np.sum(owner[ret] == arrays["obj_id"][i])
    bad = tmp_path / "bad.npz"
    np.savez(bad, format=np.array("safecase-sim-dataset"), version=np.array(DATASET_VERSION + 1))
    with pytest.raises(DatasetError, match="version"):
        load_dataset(bad)
    with pytest.raises(DatasetError, match="cannot read"):
        load_dataset(tmp_path / "missing.npz")


def test_cli_list_show_and_dataset(tmp_path: Path) -> None:
    listed = run_safecase("sim", "list", cwd=tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert "dolly_train_turn" in listed.stdout
    png = tmp_path / "rev.png"
    cfg = tmp_path / "fast.toml"
    cfg.write_text("[sim]\nbeams = 180\n")
    shown = run_safecase(
        "sim",
        "show",
        "reversing_forklift_aisle",
        "--out",
        str(png),
        "--duration",
        "6",
        "--config",
        str(cfg),
        cwd=tmp_path,
    )
    assert shown.returncode == 0, shown.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "reversing_forklift_aisle seed 0" in shown.stdout
    outs = []
    for k in range(2):  # two processes, same seed: the same data bit for bit
        out = tmp_path / f"d{k}.npz"
        done = run_safecase(
            "sim",
            "dataset",
            "--scenarios",
            "crossing_pedestrian,random_encounter",
            "--seeds",
            "2",
            "--duration",
            "1.5",
            "--out",
            str(out),
            "--config",
            str(cfg),
            cwd=tmp_path,
        )
        assert done.returncode == 0, done.stderr
        outs.append(load_dataset(out))
    for key in outs[0][1]:
        assert np.array_equal(
            outs[0][1][key], outs[1][1][key], equal_nan=outs[0][1][key].dtype.kind == "f"
        ), key


def test_cli_rejects_bad_input_with_exit_2(tmp_path: Path) -> None:
    unknown = run_safecase("sim", "show", "nope", cwd=tmp_path)
    assert unknown.returncode == 2
    assert "unknown scenario(s) nope" in unknown.stderr
    bad_cfg = tmp_path / "bad.toml"
    bad_cfg.write_text("[sim]\nmax_range_m = -1.0\n")
    rejected = run_safecase(
        "sim", "dataset", "--out", str(tmp_path / "x.npz"), "--config", str(bad_cfg), cwd=tmp_path
    )
    assert rejected.returncode == 2
    assert "sim.max_range_m" in rejected.stderr
    neg = run_safecase("sim", "show", "pallet_jack_slow", "--duration", "-1", cwd=tmp_path)
    assert neg.returncode == 2
    assert "--duration" in neg.stderr
