"""``safecase run`` on every kind of source, through the one loop (SR-RUN-*, SR-TRK-5)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from pipeline.config import default_config
from properties.cli_runner import SAFECASE, run_safecase
from properties.log_cases import drive, write_carmen, write_ros2_bag

DATA = Path(__file__).resolve().parents[1] / "data"
CODE = [
    "evidence/cli/run.py",
    "evidence/cli/loops.py",
    "safety/run.py",
    "pipeline/sources/logs/source.py",
]


def _replays(log: Path, cwd: Path, cycles: int) -> None:
    done = run_safecase("audit", "replay", str(log), cwd=cwd)
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"replayed {cycles} of {cycles} cycles exactly" in done.stdout


@pytest.mark.requirement("SR-RUN-4", kind="example", code=CODE)
def test_run_log_replays_a_ros1_bag(tmp_path: Path) -> None:
    audit = tmp_path / "ros1.jsonl"
    bag = DATA / "leg_tracker" / "positive_2_extracted.bag"
    done = run_safecase("run", "--log", str(bag), "--audit", str(audit), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "cycles" in done.stdout
    assert "83" in done.stdout
    assert "stamps" in done.stdout
    assert "as recorded" in done.stdout
    _replays(audit, tmp_path, 83)


@pytest.mark.requirement("SR-RUN-4", kind="example", code=CODE)
def test_run_log_replays_a_ros2_bag_with_odometry_written_by_rosbags(tmp_path: Path) -> None:
    driven = drive(default_config(), "crossing_pedestrian", 4, 3.0)
    bag = write_ros2_bag(tmp_path / "walk", driven.scans, driven.odometry, storage="mcap")
    audit = tmp_path / "ros2.jsonl"
    done = run_safecase(
        "run", "--log", str(bag), "--odom-topic", "/odom", "--audit", str(audit), cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert "outside the odometry 1" in done.stdout  # the first scan precedes the odometry
    _replays(audit, tmp_path, len(driven.scans) - 1)
    wrong = run_safecase("run", "--log", str(bag), "--odom-topic", "/nope", cwd=tmp_path)
    assert wrong.returncode == 2
    assert "no Odometry topic '/nope'; found ['/odom']" in wrong.stderr


@pytest.mark.requirement("SR-RUN-4", kind="example", code=CODE)
def test_run_log_follows_tf_odometry_found_by_type(tmp_path: Path) -> None:
    driven = drive(default_config(), "crossing_pedestrian", 4, 2.0)
    bag = write_ros2_bag(
        tmp_path / "tf", driven.scans, driven.odometry, odom_topic="/tf", odometry_as="tf"
    )
    audit = tmp_path / "tf.jsonl"
    done = run_safecase("run", "--log", str(bag), "--audit", str(audit), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert "odometry" in done.stdout
    assert "/tf" in done.stdout
    assert "outside the odometry 1" in done.stdout
    _replays(audit, tmp_path, len(driven.scans) - 1)


@pytest.mark.requirement("SR-RUN-4", kind="example", code=CODE)
def test_run_log_replays_a_carmen_log_and_refuses_bad_stamps_unless_restamped(
    tmp_path: Path,
) -> None:
    driven = drive(default_config(), "pallet_jack_slow", 1, 2.0)
    scans = list(driven.scans)
    scans[7] = scans[6]  # a stamp recorded twice
    log = write_carmen(tmp_path / "aisle.log", scans, driven.poses_at_scans)
    refused = run_safecase("run", "--log", str(log), cwd=tmp_path)
    assert refused.returncode == 2
    assert "aisle.log: scan 7 is stamped 1000.6, the same as scan 6" in refused.stderr
    assert "Traceback" not in refused.stderr
    audit = tmp_path / "carmen.jsonl"
    done = run_safecase(
        "run", "--log", str(log), "--restamp", "10", "--audit", str(audit), cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert "re-stamped at 10 Hz" in done.stdout
    _replays(audit, tmp_path, len(scans))


def test_run_refuses_two_sources_and_log_options_without_a_log(tmp_path: Path) -> None:
    done = run_safecase("run", "--log", "a.bag", "--emulate", "scip", cwd=tmp_path)
    assert done.returncode == 2
    assert "--emulate and --log: choose one source" in done.stderr
    done = run_safecase("run", "--odom-topic", "/odom", cwd=tmp_path)
    assert done.returncode == 2
    assert "apply to --log only" in done.stderr
    done = run_safecase("run", "--log", str(tmp_path / "none.bag"), cwd=tmp_path)
    assert done.returncode == 2
    assert "none.bag: no such file or folder" in done.stderr


@pytest.mark.requirement(
    "SR-RUN-4", kind="example", code=["evidence/cli/run.py", "evidence/cli/loops.py"]
)
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_stopped_run_closes_its_audit_log(tmp_path: Path, signum: int) -> None:
    """SIGTERM (a service manager) and Ctrl-C both close the log: verify says INTACT."""
    audit = tmp_path / "stopped.jsonl"
    env = dict(os.environ, MPLBACKEND="Agg", COLUMNS="200")
    command = [*SAFECASE, "run", "--emulate", "rplidar", "--scans", "500", "--audit", str(audit)]
    with subprocess.Popen(
        command, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    ) as proc:
        assert proc.stdout is not None
        for line in proc.stdout:  # wait until cycles run
            if line.strip().startswith("5 "):
                break
        proc.send_signal(signum)
        rest, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    assert "stopped on request" in rest
    assert "cycles:" in rest
    verified = run_safecase("audit", "verify", str(audit), cwd=tmp_path)
    assert verified.returncode == 0, verified.stdout + verified.stderr
    assert "INTACT" in verified.stdout


@pytest.mark.requirement("SR-DRV-3", kind="example", code=["evidence/cli/run.py"])
def test_run_device_that_cannot_be_opened_exits_2_naming_it(tmp_path: Path) -> None:
    config = tmp_path / "fast.toml"
    config.write_text("[driver]\nmax_reconnects = 2\nreconnect_backoff_s = 0.05\n")
    done = run_safecase(
        "run", "--device", "/dev/nonexistent", "--scans", "3", "--config", str(config),
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 2
    assert "/dev/nonexistent: no scanner after 3 attempts" in done.stderr
    assert "cannot open serial port '/dev/nonexistent'" in done.stderr
    cycles = [ln for ln in done.stdout.splitlines() if ln.strip()[:1].isdigit()]
    assert cycles
    assert all("STOP" in ln and "scanner link" in ln for ln in cycles), cycles


def test_a_log_that_cannot_be_replayed_leaves_no_audit_log(tmp_path: Path) -> None:
    audit = tmp_path / "none.jsonl"
    bag = DATA / "leg_tracker" / "negative_2.bag"  # three LaserScan topics: name one
    done = run_safecase("run", "--log", str(bag), "--audit", str(audit), cwd=tmp_path)
    assert done.returncode == 2
    assert "3 LaserScan topics" in done.stderr
    assert not audit.exists()
    done = run_safecase(
        "run", "--log", str(bag), "--scan-topic", "/left_scan", "--scans", "5",
        "--audit", str(audit), cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert audit.exists()


class _SignalsWhenCollected:
    """Sends this process SIGINT from its finaliser, where a raised exception is dropped."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGINT)


@pytest.mark.requirement("SR-RUN-4", kind="example", code=["evidence/cli/loops.py"])
# The dropped KeyboardInterrupt is reported as unraisable: that is the case under test.
@pytest.mark.filterwarnings("ignore::pytest.PytestUnraisableExceptionWarning")
def test_a_stop_request_survives_a_finaliser_that_drops_the_interrupt() -> None:
    from evidence.cli import loops

    with loops.stop_on_signals():
        try:
            _SignalsWhenCollected()  # collected at once: the signal arrives in __del__
            time.sleep(0.05)
        except KeyboardInterrupt:
            pass  # delivered after the finaliser returned: the loop would see it directly
        with pytest.raises(KeyboardInterrupt, match="stop requested"):
            loops.stop_requested()
    loops._STOP.clear()
