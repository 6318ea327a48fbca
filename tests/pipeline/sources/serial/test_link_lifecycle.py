"""The serial link over its life: a device that never answers is an error naming it; one that
answered and went away is retried with back-off for as long as the run lasts (SR-DRV-3)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from pipeline.config import DriverSection
from pipeline.sources.serial.devices import RplidarDevice
from pipeline.sources.serial.emulator import Emulator
from pipeline.sources.serial.errors import LinkError
from pipeline.sources.serial.source import SerialSource
from pipeline.sources.serial.synthetic import rplidar_angles, synthetic_scans
from pipeline.sources.serial.transport import Driver
from pipeline.types import DriverState, Frame

TRANSPORT = ["pipeline/sources/serial/transport.py", "pipeline/sources/serial/source.py"]


@pytest.mark.requirement("SR-DRV-3", code=TRANSPORT)
def test_a_scanner_gone_for_two_seconds_is_retried_with_back_off_and_comes_back() -> None:
    rng = np.random.default_rng(5)
    emu = Emulator(
        RplidarDevice(), synthetic_scans(rng, rplidar_angles(360)), realtime=True, rate_hz=20.0
    )
    # Two reconnects 0.05 s apart would be spent within 0.1 s of a 2 s outage.
    config = DriverSection(
        protocol="rplidar",
        silent_timeout_s=0.3,
        reconnect_backoff_s=0.05,
        reconnect_backoff_max_s=0.4,
        max_reconnects=2,
    )
    with emu, Driver(config.model_copy(update={"port_url": emu.path})) as driver:
        deadline = time.monotonic() + 5.0
        while not driver.poll() and time.monotonic() < deadline:
            pass
        emu.disconnect(2.0)
        states, waits = set(), []
        deadline = time.monotonic() + 8.0
        back = False
        while time.monotonic() < deadline:
            got = driver.poll()
            health = driver.health()
            states.add(health.state)
            waits.append(driver.backoff_s())
            if got and time.monotonic() > deadline - 5.5:
                back = True
                break
    assert DriverState.FAILED not in states
    assert DriverState.STALE in states or DriverState.DISCONNECTED in states
    assert back, "the driver reconnects once the device is back"
    assert max(waits) == pytest.approx(0.4)  # doubled from 0.05 s up to the cap
    assert health.reconnects >= 3


@pytest.mark.requirement("SR-DRV-3", code=TRANSPORT)
@pytest.mark.parametrize("url", ["/dev/nonexistent", "bogus://x", "regular-file"])
def test_a_device_that_cannot_be_opened_is_an_error_naming_it(tmp_path: Path, url: str) -> None:
    if url == "regular-file":
        path = tmp_path / "not-a-tty"
        path.write_bytes(b"\x00" * 64)
        url = str(path)
    config = DriverSection(
        protocol="rplidar", port_url=url, max_reconnects=2, reconnect_backoff_s=0.01
    )
    frames: list[Frame] = []
    source = SerialSource(config, 0.02).frames()
    with pytest.raises(LinkError) as caught:
        frames.extend(source)
    assert url in str(caught.value)
    assert "no scanner after 3 attempts" in str(caught.value)
    assert frames
    assert all(f.scan is None for f in frames)
    assert frames[-1].health is not None
    assert frames[-1].health.state is DriverState.FAILED
