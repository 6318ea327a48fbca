"""Building device byte streams and judging what a decoder made of them (SR-DRV-1..3).

Shared by the driver properties and the example tests: device-like scan strategies, the
frames the device models send for a list of scans, the decoders for each link kind, and
:func:`judge`, which classifies one fault as harmless, detected or undetected by comparing
the decoder's output on the faulty stream with its output on the clean one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from hypothesis import strategies as st

from pipeline.sources.serial import rplidar as rp
from pipeline.sources.serial import scip
from pipeline.sources.serial.assembly import LinkCounters
from pipeline.sources.serial.devices import RplidarDevice, ScipDevice
from pipeline.sources.serial.rplidar_stream import RplidarStream
from pipeline.sources.serial.scip_stream import ScipStream
from pipeline.types import Scan
from properties.oracles.drivers import checked_capsules, checked_scip_lines

__all__ = [
    "LINKS",
    "DecodeVerdict",
    "Link",
    "decode",
    "device_frames",
    "forged_frames",
    "judge",
    "link_scans",
    "wrap_rad",
]

Link = Literal["rplidar-standard", "rplidar-express", "scip-md", "scip-ms"]
LINKS: tuple[Link, ...] = ("rplidar-standard", "rplidar-express", "scip-md", "scip-ms")
DecodeVerdict = Literal["harmless", "detected", "undetected"]

UTM_30LX = scip.ScipParams()
URG_04LX = scip.ScipParams(
    model="URG-04LX(Hokuyo Automatic Co.,Ltd.)",
    dmin_mm=20,
    dmax_mm=5600,
    ares=1024,
    amin=44,
    amax=725,
    afrt=384,
    scan_rpm=600,
)


def wrap_rad(angle: np.ndarray) -> np.ndarray:
    """Angles folded into [-pi, pi)."""
    return np.asarray(np.mod(angle + np.pi, 2 * np.pi) - np.pi, dtype=np.float64)


@st.composite
def link_scans(draw: st.DrawFn, link: Link, count: int = 3) -> list[Scan]:
    """``count`` device-like scans for ``link``: full turns of evenly spaced beams (with a
    little jitter) for RPLIDAR, one beam per step for SCIP; NaN marks no return."""
    seed = draw(st.integers(0, 2**32 - 1), label="seed")
    rng = np.random.default_rng(seed)
    scans = []
    if link.startswith("rplidar"):
        n = draw(st.integers(160, 720), label="beams")
        for _ in range(count):
            step = 2 * np.pi / n
            angles = -(np.arange(n) + rng.uniform(-0.05, 0.05, n)).astype(np.float64) * step
            angles[0] = 0.0
            ranges = rng.uniform(0.02, 16.0, n)
            ranges[rng.random(n) < 0.1] = np.nan
            quality = np.where(np.isnan(ranges), 0.0, rng.integers(1, 64, n).astype(float))
            scans.append(Scan(0.0, angles, ranges, quality if link.endswith("standard") else None))
        return scans
    params = draw(st.sampled_from([UTM_30LX, URG_04LX]), label="model")
    limit = min(params.dmax_mm, 4095 if link == "scip-ms" else params.dmax_mm)
    steps = np.arange(params.amin, params.amax + 1)
    for _ in range(count):
        ranges = np.rint(rng.uniform(params.dmin_mm, limit, steps.shape[0])) / 1000.0
        ranges[rng.random(steps.shape[0]) < 0.1] = np.nan
        angles = (steps - params.afrt).astype(np.float64) * params.step_rad
        scans.append(Scan(0.0, angles, ranges))
    return scans


def scip_params_of(scans: Sequence[Scan]) -> scip.ScipParams:
    """Which model :func:`link_scans` drew, recognised from the beam count."""
    n = scans[0].n_beams
    return UTM_30LX if n == UTM_30LX.amax - UTM_30LX.amin + 1 else URG_04LX


@dataclass(frozen=True, slots=True)
class Frames:
    """The bytes a device sends: the start-of-stream answer, one frame per element, and how
    many leading frames carry the given scans (the rest close the last revolution)."""

    prefix: bytes
    frames: list[bytes]
    n_scan_frames: int
    params: scip.ScipParams | None = None
    command: scip.ScipCommand | None = None

    @property
    def data(self) -> bytes:
        """The whole stream."""
        return self.prefix + b"".join(self.frames)


def device_frames(link: Link, scans: Sequence[Scan]) -> Frames:
    """Frames the device model sends for ``scans``, after the start-of-scan answer, followed
    by a closing revolution with no returns so that the last given scan is complete."""
    closing = Scan(0.0, scans[-1].angles_rad, np.full(scans[-1].n_beams, np.nan))
    if link.startswith("rplidar"):
        device = RplidarDevice()
        cmd = rp.Cmd.SCAN if link == "rplidar-standard" else rp.Cmd.EXPRESS_SCAN
        prefix = device.receive(rp.encode_request(cmd, bytes(5) if cmd & 0x80 else b""))
        frames = [f for s in scans for f in device.frames(s)]
        n = len(frames)
        frames += device.frames(closing)
        # Standard: the next start flag (and two more nodes) closes the last revolution;
        # express: the encoder's padding wraps past 360 degrees and closes it.
        frames += device.frames(closing)[:8] if link == "rplidar-standard" else device.finish()
        return Frames(prefix[7:], frames, n)
    params = scip_params_of(scans)
    name = scip.Name.MD if link == "scip-md" else scip.Name.MS
    command = scip.ScipCommand(name, params.amin, params.amax, 1, 0, 0)
    sdevice = ScipDevice(params)
    prefix = sdevice.receive(command.encode())
    frames = [f for s in scans for f in sdevice.frames(s)]
    n = len(frames)
    frames += sdevice.frames(closing) + sdevice.frames(closing)
    return Frames(prefix, frames, n, params, command)


def expected_scans(link: Link, scans: Sequence[Scan]) -> list[Scan]:
    """The revolutions a clean stream yields: an express stream's first revolution is
    withheld (it starts wherever the first capsule does, so it cannot be known whole)."""
    return list(scans[1:]) if link == "rplidar-express" else list(scans)


def decode(
    link: Link, frames: Frames, data: bytes, chunks: Sequence[int] = ()
) -> tuple[list[Scan], LinkCounters]:
    """Run the link's stream decoder over ``data`` fed in pieces of the ``chunks`` sizes."""
    counters = LinkCounters()
    decoder: RplidarStream | ScipStream
    if link.startswith("rplidar"):
        decoder = RplidarStream(
            "standard" if link == "rplidar-standard" else "express", counters=counters
        )
    else:
        assert frames.params is not None
        assert frames.command is not None
        decoder = ScipStream(frames.params, frames.command, counters=counters)
    out: list[Scan] = []
    pos = 0
    sizes = list(chunks) or [len(data) or 1]
    i = 0
    while pos < len(data):
        size = max(1, sizes[i % len(sizes)])
        out += decoder.feed(data[pos : pos + size], float(i))
        pos += size
        i += 1
    return out, counters


def _beam_keys(scan: Scan) -> set[tuple[int, int, int]]:
    ranges = np.where(np.isnan(scan.ranges_m), -1.0, scan.ranges_m)
    quality = scan.intensities if scan.intensities is not None else np.zeros(scan.n_beams)
    return set(
        zip(
            np.rint(wrap_rad(scan.angles_rad) * 1e9).astype(np.int64).tolist(),
            np.rint(ranges * 1e7).astype(np.int64).tolist(),
            np.rint(quality).astype(np.int64).tolist(),
            strict=True,
        )
    )


def same_scan(a: Scan, b: Scan) -> bool:
    """Beam for beam identical (angles, ranges with NaN, intensities, completeness)."""
    return (
        a.n_beams == b.n_beams
        and a.complete == b.complete
        and np.array_equal(a.angles_rad, b.angles_rad)
        and np.array_equal(a.ranges_m, b.ranges_m, equal_nan=True)
        and (
            (a.intensities is None and b.intensities is None)
            or (
                a.intensities is not None
                and b.intensities is not None
                and np.array_equal(a.intensities, b.intensities)
            )
        )
    )


def forged_frames(link: Link, sent: bytes, received: bytes) -> int:
    """Frames of ``received`` that pass every check of the link's protocol (sync and XOR
    checksum of an express capsule, alphabet and 6-bit checksum of a SCIP line) but were
    never sent: checksum collisions no decoder can reject. RPLIDAR standard nodes carry no
    checksum, so this is not defined for them (raises ``ValueError``)."""
    if link == "rplidar-express":
        return len(checked_capsules(received) - checked_capsules(sent))
    if link in ("scip-md", "scip-ms"):
        return len(checked_scip_lines(received) - checked_scip_lines(sent))
    raise ValueError(f"forged_frames: link {link!r} has no frame checksum")


def foreign_beams(clean: Sequence[Scan], faulty: Sequence[Scan]) -> int:
    """Beams in ``faulty`` that no clean revolution holds, plus complete faulty revolutions
    that equal no clean one: data that was never sent (must be 0, SR-DRV-2)."""
    sent: set[tuple[int, int, int]] = set()
    for scan in clean:
        sent |= _beam_keys(scan)
    foreign = sum(len(_beam_keys(scan) - sent) for scan in faulty)
    for scan in faulty:
        if scan.complete and not any(same_scan(scan, c) for c in clean):
            foreign += 1
    return foreign


def judge(
    clean: Sequence[Scan],
    clean_counters: LinkCounters,
    faulty: Sequence[Scan],
    faulty_counters: LinkCounters,
) -> DecodeVerdict:
    """Harmless (same output), detected (the decoder counted a rejection, a discard or a
    dropped or incomplete revolution, and emitted no foreign data) or undetected."""
    if foreign_beams(clean, faulty):
        return "undetected"
    if len(clean) == len(faulty) and all(
        same_scan(a, b) for a, b in zip(clean, faulty, strict=True)
    ):
        return "harmless"
    noticed = (
        faulty_counters.frames_rejected > clean_counters.frames_rejected
        or faulty_counters.bytes_discarded > clean_counters.bytes_discarded
        or faulty_counters.scans_dropped > clean_counters.scans_dropped
        or any(not s.complete for s in faulty)
    )
    return "detected" if noticed else "undetected"
