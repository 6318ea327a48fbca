"""A third-party RPLIDAR client (rplidar-roboticia, module ``rplidar``) reads our emulator.

The client opens the pty with pyserial, asks GET_INFO and GET_HEALTH, starts a standard
scan and yields revolutions as ``(quality, angle_deg, distance_mm)``. It must get exactly
what we put in, quantised as the protocol quantises (1/64 degree, 1/4 mm). Requirement
SR-DRV-4.

Shim (one line, below): the client switches the A1's motor with pyserial's ``setDTR``; a
pseudo-terminal has no modem lines, so that ioctl fails (ENOTTY) and we replace the call by a
no-op on the client's port object. Nothing else of the client is touched.
"""

from __future__ import annotations

import numpy as np
import pytest

from evidence.record import current
from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial.devices import RplidarDevice
from pipeline.sources.serial.emulator import Emulator
from pipeline.sources.serial.synthetic import rplidar_angles, synthetic_scans

rplidar_client = pytest.importorskip("rplidar", reason="rplidar-roboticia (dev extra) is missing")


@pytest.mark.requirement(
    "SR-DRV-4",
    kind="cross-check",
    code=["pipeline/sources/serial/rplidar.py", "pipeline/sources/serial/devices.py"],
)
def test_rplidar_roboticia_reads_exactly_what_the_emulator_sends() -> None:
    rng = np.random.default_rng(21)
    sent = list(
        synthetic_scans(rng, rplidar_angles(360), count=8, with_intensities=True, max_range_m=16)
    )
    info = rp.DeviceInfo(0x18, 1, 29, 7, bytes(range(16)))
    with Emulator(RplidarDevice(info=info), sent, realtime=True, rate_hz=20.0) as emu:
        lidar = rplidar_client.RPLidar(emu.path, timeout=2)
        lidar._serial.setDTR = lambda *args, **kwargs: None  # the shim: no modem lines on a pty
        try:
            client_info = lidar.get_info()
            status, error_code = lidar.get_health()
            got = []
            for scan in lidar.iter_scans(max_buf_meas=False, min_len=0):
                got.append(scan)
                if len(got) == 5:
                    break
        finally:
            lidar.stop()
            lidar.disconnect()
    assert emu.error is None
    assert client_info["model"] == 0x18
    assert client_info["firmware"] == (1, 29)  # (major, minor)
    assert client_info["serialnumber"] == bytes(range(16)).hex().upper()
    assert (status, error_code) == ("Good", 0)
    compared = 0
    # iter_scans yields a revolution when the next one starts: got[i] is sent[i], returns only.
    for scan, measures in zip(sent[: len(got)], got, strict=True):
        nodes = rp.scan_to_nodes(scan)
        order = np.argsort(nodes.angle_q6, kind="stable")
        keep = nodes.distance_q2[order] > 0
        expected = list(
            zip(
                nodes.quality[order][keep].tolist(),
                (nodes.angle_q6[order][keep] / 64.0).tolist(),
                (nodes.distance_q2[order][keep] / 4.0).tolist(),
                strict=True,
            )
        )
        assert measures == expected
        compared += len(expected)
    current().counts("rplidar-roboticia", {"revolutions": len(got), "measures equal": compared})
