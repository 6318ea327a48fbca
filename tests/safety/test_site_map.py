"""The site map from the command line (SR-AVL-8): a scenario's map written as Nav2 files, a run
given it through ``map.file``, and a map file that cannot be used refused with exit code 2."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from pipeline.config import default_config, overridden
from pipeline.errors import ConfigError
from pipeline.sources.sim.scenarios import make_simulation
from pipeline.sources.sim.simulation import Simulation
from pipeline.static_map import StaticMap, map_from_config
from properties.cli_runner import run_safecase
from safety.bodies import OnMapMemory
from safety.run import site_map


def test_a_written_map_is_the_simulated_world_s_and_a_run_reads_it(tmp_path: Path) -> None:
    target = tmp_path / "maps" / "crossing.yaml"
    done = run_safecase("sim", "map", "crossing_pedestrian", "--out", str(target), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert target.with_suffix(".pgm").is_file()
    config = default_config()
    read = site_map(overridden(config, {"map": {"file": str(target)}}), _sim())
    world = site_map(config, _sim())
    assert read is not None
    assert world is not None
    assert np.array_equal(read.covered, world.covered)
    cfg = tmp_path / "map.toml"
    cfg.write_text(f'[map]\nfile = "{target}"\n')
    run = _run(cfg, tmp_path)
    assert run.returncode == 0, run.stderr


def test_no_map_is_used_when_none_is_configured_or_the_world_is_switched_off() -> None:
    config = default_config()
    assert map_from_config(config) is None
    off = overridden(config, {"map": {"simulated_world": False}})
    assert site_map(off, _sim()) is None


def test_an_unusable_map_file_is_refused_with_exit_2(tmp_path: Path) -> None:
    cfg = tmp_path / "map.toml"
    cfg.write_text(f'[map]\nfile = "{tmp_path / "gone.yaml"}"\n')
    run = _run(cfg, tmp_path)
    assert run.returncode == 2
    assert "map.file: no such map file" in run.stderr
    assert "gone.yaml" in run.stderr


def test_a_map_whose_reach_could_cover_a_person_is_refused(tmp_path: Path) -> None:
    coarse = StaticMap.from_parts([np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])], 0.2, 0.05)
    path = coarse.write_nav2(tmp_path / "coarse.yaml")
    config = overridden(default_config(), {"map": {"file": str(path), "tolerance_m": 0.05}})
    with pytest.raises(ConfigError, match=r"coarse.yaml: tolerance 0.05 m .* must be below"):
        map_from_config(config)


def _run(cfg: Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    """``safecase run`` of one second of crossing_pedestrian with the configuration ``cfg``."""
    return run_safecase(
        "run", "--scenario", "crossing_pedestrian", "--duration", "1", "--no-plot",
        "--config", str(cfg), cwd=cwd,
    )  # fmt: skip


def _sim() -> Simulation:
    return make_simulation(default_config(), "crossing_pedestrian", 0, 1.0)


def test_a_track_coasting_since_it_was_seen_on_the_map_stays_the_structure() -> None:
    memory = OnMapMemory()
    ids = np.array([1, 2, 3])
    seen = memory.update(ids, np.array([0, 1, -1]), np.array([True, False, False]))
    assert seen.tolist() == [True, False, False]  # track 3 is new and unseen: not on the map
    seen = memory.update(ids, np.array([-1, -1, 2]), np.array([False, False, True]))
    assert seen.tolist() == [True, False, True]  # 1 coasts; 3 is seen on the map
    seen = memory.update(ids, np.array([0, -1, 1]), np.array([False, False, True]))
    assert seen.tolist() == [False, False, True]  # 1 is seen off the map
    seen = memory.update(np.array([2, 4]), np.array([-1, -1]), np.array([True, True]))
    assert seen.tolist() == [False, False]  # coasting: the flag passed in is not read
