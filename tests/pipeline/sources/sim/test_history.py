"""Bounded retention of a run (SR-RUN-5): the same scans, truth and motion bit for bit as a
full run, a record whose size does not grow with the run, exact contacts and minima."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import examples
from pipeline.config import default_config, overridden
from pipeline.sources.sim import motion as mo
from pipeline.sources.sim.ego import ConstantSpeed, Ego, EgoSpec, Route
from pipeline.sources.sim.history import ThinnedRows, interp_window
from pipeline.sources.sim.layouts import warehouse_aisle
from pipeline.sources.sim.objects import cart, person
from pipeline.sources.sim.scenarios import (
    ScenarioSpec,
    make_simulation,
    place,
    simulation_for_spec,
)
from pipeline.sources.sim.simulation import BOUNDED, FULL, Retention, Simulation
from pipeline.sources.sim.source import SimSource
from pipeline.sources.sim.world import World
from safety.run import contact_speeds

SMALL = Retention(frames=False, max_rows=16)  # thins within a few seconds
ROUTE = Route(np.array([[0.0, 0.0], [30.0, 0.0]]))


def _scan_bytes(sim: Simulation) -> list[bytes]:
    out = []
    sim.command(1.0)
    while (frame := sim.next_frame()) is not None:
        truth = frame.truth
        out.append(
            frame.scan.ranges_m.tobytes()
            + truth.beams.true_range_m.tobytes()
            + truth.x_m.tobytes()
            + truth.ego_pose.tobytes()
            + np.float64(truth.ego_speed_mps).tobytes()
            + sim.ego.poses_at(np.array([frame.scan.stamp_s])).tobytes()
        )
    return out


@pytest.mark.requirement(
    "SR-RUN-5",
    "SR-SIM-2",
    kind="example",
    code=["pipeline/sources/sim/simulation.py", "pipeline/sources/sim/history.py"],
)
@pytest.mark.parametrize("name", ["reversing_forklift_aisle", "dolly_train_turn"])
def test_bounded_retention_gives_the_same_bits_as_full(name: str) -> None:
    cfg = overridden(default_config(), {"sim": {"beams": 180}})
    full = make_simulation(cfg, name, 4, 6.0)
    bounded = make_simulation(cfg, name, 4, 6.0, retention=SMALL)
    assert _scan_bytes(full) == _scan_bytes(bounded)
    a, b = full.result(), bounded.result()
    assert len(a.frames) == 60
    assert b.frames == ()
    for key in ("min_separation_m", "min_separation_time_s", "contact_time_s"):
        assert getattr(a, key).tobytes() == getattr(b, key).tobytes(), key
    # Every row the bounded record kept is the full record's row at the same time.
    rows = np.searchsorted(a.ego_log["t_s"], b.ego_log["t_s"])
    assert 2 < rows.size <= 16 + 1 + 2 * len(a.world.objects)  # SMALL.max_rows, newest, pins
    for key, values in b.ego_log.items():
        assert values.tobytes() == a.ego_log[key][rows].tobytes(), key
    rows = np.searchsorted(a.separation_t_s, b.separation_t_s)
    assert a.separation_t_s[rows].tobytes() == b.separation_t_s.tobytes()
    assert a.separation_m[rows].tobytes() == b.separation_m.tobytes()
    assert b.ego_log["t_s"][-1] == a.ego_log["t_s"][-1]  # the newest step is always kept


@pytest.mark.requirement(
    "SR-RUN-5",
    kind="example",
    code=["pipeline/sources/sim/simulation.py", "pipeline/sources/sim/history.py"],
)
def test_contact_speeds_are_exact_under_a_thinned_log() -> None:
    """At a constant 1 m/s the default scenario's forklift is hit with the robot moving; the
    speed read from the thinned log is the full log's, bit for bit."""
    cfg = default_config()
    full = make_simulation(cfg, duration_s=15.0).run(ConstantSpeed(1.0))
    thin = make_simulation(cfg, duration_s=15.0, retention=SMALL).run(ConstantSpeed(1.0))
    assert full.contact
    assert thin.contact
    assert contact_speeds(full).tobytes() == contact_speeds(thin).tobytes()
    assert contact_speeds(full).max() > 0.5
    assert thin.ego_log["t_s"].size < full.ego_log["t_s"].size // 20


@pytest.mark.requirement(
    "SR-RUN-5",
    kind="example",
    code=["pipeline/sources/sim/simulation.py", "pipeline/sources/sim/history.py"],
)
def test_every_contact_after_the_first_is_exact_too() -> None:
    """Without stopping at the first contact: the robot runs into a parked cart and halts, and
    a walker later walks into it (the second contact is recorded with the robot halted); each
    contact's speed read from the thinned log is the full log's."""
    cfg = overridden(default_config(), {"sim": {"beams": 32}})
    layout = warehouse_aisle(np.random.default_rng(0))
    objects = (
        place(1, "cart_parked", cart(), mo.stationary(), (6.0, 0.0, 0.0), 20.0),
        place(2, "walker", person(), mo.constant(1.0), (20.0, 0.0, np.pi), 20.0),
    )
    spec = ScenarioSpec(World("two_contacts", layout.structure, objects, layout.bounds_m), ROUTE)
    base = simulation_for_spec(cfg, spec, "two_contacts", 0, 20.0)
    results = []
    for retention in (FULL, SMALL):
        sim = Simulation(
            base.world,
            base.ego_spec,
            base.lidar.spec,
            rng=np.random.default_rng(1),
            duration_s=20.0,
            step_s=cfg.sim.step_s,
            rules=base.rules,
            stop_at_contact=False,
            retention=retention,
        )
        results.append(sim.run(ConstantSpeed(1.0)))
    full, thin = results
    assert np.isfinite(full.contact_time_s).all(), full.contact_time_s
    assert full.contact_time_s.tobytes() == thin.contact_time_s.tobytes()
    speeds = contact_speeds(full)
    assert speeds[0] > 0.5
    assert speeds[1] == 0.0
    assert speeds.tobytes() == contact_speeds(thin).tobytes()


@pytest.mark.requirement(
    "SR-RUN-5",
    kind="example",
    code=["pipeline/sources/sim/simulation.py", "pipeline/sources/sim/history.py"],
)
def test_the_record_stays_bounded_over_a_long_run() -> None:
    """A bounded run of 2,000 scans keeps no frames, at most ``max_rows`` thinned rows (plus
    the newest) of the log and separations, and a fixed-size ego window."""
    cfg = overridden(default_config(), {"sim": {"beams": 32, "ego_speed_mps": 0.0}})
    sim = make_simulation(cfg, "pallet_jack_slow", 0, 200.0, retention=SMALL)
    sim.command(0.0)
    sizes = set()
    while (frame := sim.next_frame()) is not None:
        sizes.add(sim.ego._t.size)
        assert frame.scan.seq < 2000
    result = sim.result()
    assert result.frames == ()
    assert result.ego_log["t_s"].size <= 17
    assert result.separation_t_s.size <= 17
    assert sizes == {2 * (4 * sim.steps_per_scan + 1)}
    assert result.ego_log["t_s"][-1] == pytest.approx(200.0)
    spaced = np.diff(result.ego_log["t_s"][:-1])
    assert np.allclose(spaced, spaced[0])  # evenly thinned over the whole run


def test_a_bounded_ego_refuses_times_and_rewinds_it_no_longer_holds() -> None:
    spec = EgoSpec(Route(np.array([[0.0, 0.0], [100.0, 0.0]])), 0.9, 0.6, 0.5, 2.0, 0.05, 1.5, 1.0)
    ego = Ego(spec, 0.01, 1000, window_steps=10, log_rows=8)
    for _ in range(50):
        ego.step()
    ego.commit()
    with pytest.raises(ValueError, match="before the steps kept"):
        ego.poses_at(np.array([0.1]))
    with pytest.raises(ValueError, match="rewind"):
        ego.rewind(45)
    assert ego.poses_at(np.array([0.45])).shape == (1, 3)


def test_sim_source_bounds_its_simulation_unless_told_otherwise() -> None:
    cfg = default_config()
    assert SimSource(make_simulation(cfg, duration_s=1.0)).sim.retention == BOUNDED
    kept = SimSource(make_simulation(cfg, duration_s=1.0), retention=None)
    assert kept.sim.retention == FULL
    started = make_simulation(cfg, duration_s=1.0)
    started.next_frame()
    with pytest.raises(ValueError, match="started"):
        SimSource(started)


@pytest.mark.requirement("SR-RUN-5", kind="property", code=["pipeline/sources/sim/history.py"])
@settings(max_examples=examples(60), deadline=None)
@given(
    n=st.integers(1, 300),
    capacity=st.sampled_from([2, 4, 8, 64]),
    pins=st.lists(st.integers(0, 299), max_size=5),
)
def test_thinned_rows_keep_evenly_spaced_rows_the_pins_and_the_newest(
    n: int, capacity: int, pins: list[int]
) -> None:
    rows = ThinnedRows(2, capacity)
    for i in range(n):
        for p in pins:
            if p == i:
                rows.pin(p)  # pinned on arrival, as the simulator does
        rows.append(np.array([i, -i]))
    index, values = rows.rows()
    assert np.array_equal(values[:, 0], index)
    assert np.array_equal(values[:, 1], -index)
    assert np.all(np.diff(index) > 0)
    thinned = index[index % rows.stride == 0]
    assert thinned.size <= capacity
    assert np.array_equal(thinned, np.arange(0, n, rows.stride)[: thinned.size])
    assert {p for p in pins if p < n} | {n - 1} <= set(index.tolist())
    assert index.size <= capacity + len(pins) + 1


@pytest.mark.requirement("SR-RUN-5", kind="property", code=["pipeline/sources/sim/history.py"])
@settings(max_examples=examples(200), deadline=None)
@given(
    n=st.integers(1, 200),
    m=st.integers(1, 400),
    seed=st.integers(0, 2**32 - 1),
)
def test_windowed_interpolation_is_bit_identical(n: int, m: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    grid = np.cumsum(rng.uniform(1e-3, 1.0, n))
    values = rng.standard_normal(n) * 1e3
    grid.setflags(write=False)
    values.setflags(write=False)
    lo, hi = sorted(rng.uniform(grid[0] - 1.0, grid[-1] + 1.0, 2))
    t = rng.uniform(lo, lo + (hi - lo) * rng.uniform(0.0, 1.0), m)
    t[: min(m, n) // 2] = grid[rng.integers(0, n, min(m, n) // 2)]  # exact grid hits
    assert interp_window(t, grid, values).tobytes() == np.interp(t, grid, values).tobytes()
