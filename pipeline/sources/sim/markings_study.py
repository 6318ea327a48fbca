"""Measured figures of the marking detector and its localisation aid (SR-MRK-1..3).

``python -m pipeline.sources.sim.markings_study [--out docs/images] [--scans 40] [--seed 0]``
prints the tables and writes ``markings-detection.png`` and ``markings-drive.png``:

* detection by range band (horizontal distance from the scanner), dry paint and paint that has
  lost 50 % and 80 % of its reflectivity to water: return-level recall (returns whose footprint
  is at least half on paint, kept as marking) and false rate (returns on bare asphalt kept as
  marking), and marking-level recall (of the map's stripes and arcs reaching into a band, the
  share with a fitted line or arc within 0.3 m of one of their centre-line samples, taken every
  0.5 m, in that band; samples inside the innermost ring's ground circle, 3.2 m, which no
  ring reaches, are left out) and false detections (bird's-eye cells explained by a fitted
  line or arc yet farther than 0.3 m from any marking, per scan: what map matching would
  align wrongly; a dashed line fitted as one line across its gaps is no false detection), over
  ``--scans`` robot poses along the service road;
* a drive along the service road (x = 0..90 m at 1.5 m/s, 10 Hz) with odometry drifting by
  2 % in distance and 0.002 rad/s in yaw: the position error of dead reckoning alone and with
  the map-matching correction, dry and wet.

Everything is drawn from ``--seed``: the figures are reproducible bit for bit.
"""

from __future__ import annotations

import argparse
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pipeline.config import MarkingsSection, default_config
from pipeline.frames import to_parent
from pipeline.sensors.localisation import Localiser, compose, match_to_map, relative
from pipeline.sensors.marking_map import MarkingMap
from pipeline.sensors.markings import Markings, detect_markings
from pipeline.sources.sim.apron_markings import apron_markings
from pipeline.sources.sim.markings_source import Drift
from pipeline.sources.sim.rings import Surface, ring_scan
from pipeline.types import FloatArray, IntArray, Pose

__all__ = [
    "BANDS_M",
    "DriveErrors",
    "RangeTable",
    "detection_table",
    "drive_errors",
    "loss_sweep",
    "main",
]

BANDS_M = (0.0, 5.0, 10.0, 15.0, 20.0, 30.0)
LOSSES = (0.0, 0.5, 0.8)
MATCH_M = 0.3
_SAMPLE_M = 0.5


@dataclass(frozen=True)
class RangeTable:
    """Per range band (``BANDS_M``): return recall and false rate, marking-level recall
    (``feature_recall``), false feature cells per scan, and the counts behind them."""

    paint_loss: float
    return_recall: FloatArray
    return_false_rate: FloatArray
    feature_recall: FloatArray
    false_cells_per_scan: FloatArray
    n_paint_returns: FloatArray
    n_asphalt_returns: FloatArray


def _band(distance_m: FloatArray) -> IntArray:
    return np.asarray(np.digitize(distance_m, BANDS_M) - 1, dtype=np.int64)


def fitted_map(found: Markings, pose: Pose, width_m: float) -> MarkingMap | None:
    """The fitted lines and arcs placed in the map frame by ``pose``, as a map (None if none)."""
    seg = np.array([[ln.x0_m, ln.y0_m, ln.x1_m, ln.y1_m] for ln in found.lines]).reshape(-1, 4)
    arc = np.array(
        [[a.cx_m, a.cy_m, a.radius_m, a.start_rad, a.sweep_rad] for a in found.arcs]
    ).reshape(-1, 5)
    if seg.shape[0] + arc.shape[0] == 0:
        return None
    seg[:, 0], seg[:, 1] = to_parent(pose, seg[:, 0], seg[:, 1])
    seg[:, 2], seg[:, 3] = to_parent(pose, seg[:, 2], seg[:, 3])
    arc[:, 0], arc[:, 1] = to_parent(pose, arc[:, 0], arc[:, 1])
    arc[:, 3] += pose[2]
    return MarkingMap(seg, arc, width_m)


def _poses(n: int, rng: np.random.Generator) -> list[Pose]:
    """Robot poses along the service road, heading roughly along it."""
    x = rng.uniform(0.0, 90.0, n)
    y = rng.uniform(-2.0, 2.0, n)
    yaw = rng.uniform(-0.3, 0.3, n) + np.where(rng.random(n) < 0.5, 0.0, math.pi)
    return [(float(a), float(b), float(c)) for a, b, c in zip(x, y, yaw, strict=True)]


def detection_table(
    config: MarkingsSection, paint_loss: float, n_scans: int, seed: int
) -> RangeTable:
    """Detection by range band over ``n_scans`` poses (module docstring)."""
    rng = np.random.default_rng([seed, 1])
    poses = _poses(n_scans, rng)
    truth_map = apron_markings()
    surface = Surface(paint_loss=paint_loss)
    nb = len(BANDS_M) - 1
    tp, paint_n, fp, asphalt_n = (np.zeros(nb) for _ in range(4))
    hit, present, false_cells = np.zeros(nb), np.zeros(nb), np.zeros(nb)
    sx_all, sy_all = truth_map.sample(_SAMPLE_M)
    element = truth_map.nearest(sx_all, sy_all).element
    n_el = truth_map.n_elements
    # Inside this radius no ring reaches the ground: markings there cannot be seen at all.
    blind_m = config.mount_z_m / math.tan(math.radians(-config.elevation_min_deg))
    for pose in poses:
        scan, truth = ring_scan(config, pose, truth_map, surface, rng)
        found = detect_markings(scan, config)
        band = _band(np.hypot(scan.x_m - scan.sensor_xyz_m[0], scan.y_m - scan.sensor_xyz_m[1]))
        ok = (band >= 0) & (band < nb) & found.is_ground
        paint = ok & (truth.paint_fraction >= 0.5)
        bare = ok & (truth.paint_fraction == 0.0)
        tp += np.bincount(band[paint & found.is_marking], minlength=nb)[:nb]
        paint_n += np.bincount(band[paint], minlength=nb)[:nb]
        fp += np.bincount(band[bare & found.is_marking], minlength=nb)[:nb]
        asphalt_n += np.bincount(band[bare], minlength=nb)[:nb]
        sensor = to_parent(pose, scan.sensor_xyz_m[0], scan.sensor_xyz_m[1])
        s_dist = np.hypot(sx_all - sensor[0], sy_all - sensor[1])
        sb = _band(s_dist)
        inside = (sb >= 0) & (sb < nb) & (s_dist >= blind_m)
        # An element counts once per band it reaches into, and as found there when a fitted
        # feature runs along one of its samples in that band.
        cell = sb[inside] * n_el + element[inside]
        present += np.bincount(np.unique(cell) // n_el, minlength=nb)[:nb]
        fitted = fitted_map(found, pose, truth_map.width_m)
        if fitted is None:
            continue
        near = fitted.distance_m(sx_all[inside], sy_all[inside]) <= MATCH_M
        hit += np.bincount(np.unique(cell[near]) // n_el, minlength=nb)[:nb]
        fx, fy = to_parent(pose, *found.feature_points())
        fb = _band(np.hypot(fx - sensor[0], fy - sensor[1]))
        off = truth_map.distance_m(fx, fy) > MATCH_M
        keep = off & (fb >= 0) & (fb < nb)
        false_cells += np.bincount(fb[keep], minlength=nb)[:nb]
    with np.errstate(invalid="ignore", divide="ignore"):
        return RangeTable(
            paint_loss,
            tp / paint_n,
            fp / asphalt_n,
            hit / present,
            false_cells / n_scans,
            paint_n,
            asphalt_n,
        )


def loss_sweep(
    config: MarkingsSection, losses: FloatArray, n_scans: int, seed: int
) -> tuple[FloatArray, FloatArray]:
    """Return-level recall within 15 m and the share of scans whose map matching (at the
    true pose) is accepted, for each paint loss, over ``n_scans`` poses along the road."""
    truth_map = apron_markings()
    recall, accepted = np.zeros(losses.shape[0]), np.zeros(losses.shape[0])
    for k, loss in enumerate(losses):
        rng = np.random.default_rng([seed, 3])
        hits = total = n_ok = 0
        for pose in _poses(n_scans, rng):
            scan, truth = ring_scan(config, pose, truth_map, Surface(paint_loss=float(loss)), rng)
            found = detect_markings(scan, config)
            horiz = np.hypot(scan.x_m - scan.sensor_xyz_m[0], scan.y_m - scan.sensor_xyz_m[1])
            paint = (truth.paint_fraction >= 0.5) & (horiz <= 15.0)
            hits += int((paint & found.is_marking).sum())
            total += int(paint.sum())
            fx, fy = found.feature_points()
            n_ok += match_to_map(fx, fy, pose, truth_map, config).accepted
        recall[k], accepted[k] = hits / max(total, 1), n_ok / n_scans
    return recall, accepted


@dataclass(frozen=True)
class DriveErrors:
    """Position error along the drive [m] at each scan's time [s]: dead reckoning alone and
    with the correction; ``accepted``: the share of scans whose correction was accepted."""

    paint_loss: float
    t_s: FloatArray
    odometry_m: FloatArray
    corrected_m: FloatArray
    accepted: float


def drive_errors(
    config: MarkingsSection,
    paint_loss: float,
    seed: int,
    drift: Drift | None = None,
    distance_m: float = 90.0,
) -> DriveErrors:
    """The drive of the module docstring (its first ``distance_m``), dead reckoning against
    the corrected estimate."""
    rng = np.random.default_rng([seed, 2])
    drift = Drift() if drift is None else drift
    truth_map = apron_markings()
    surface = Surface(paint_loss=paint_loss)
    dt, speed = 1.0 / config.rate_hz, 1.5
    n = int(distance_m / speed / dt)
    t = np.arange(n, dtype=np.float64) * dt
    # A gentle S along the road, so the heading changes as a real drive's would.
    xs = speed * t
    truth = [
        (float(x), -1.2 + 0.8 * math.sin(x / 15.0), math.atan(0.8 / 15.0 * math.cos(x / 15.0)))
        for x in xs
    ]
    odo: Pose = truth[0]
    loc = Localiser(truth[0], truth_map, config)
    err_odo, err_cor, accepted = np.zeros(n), np.zeros(n), 0
    for k in range(n):
        if k:
            delta = drift.increment(relative(truth[k - 1], truth[k]), dt)
            odo = compose(odo, delta)
            loc.predict(delta)
        scan, _ = ring_scan(config, truth[k], truth_map, surface, rng, stamp_s=float(t[k]))
        found = detect_markings(scan, config)
        accepted += loc.update(*found.feature_points()).accepted
        err_odo[k] = math.hypot(odo[0] - truth[k][0], odo[1] - truth[k][1])
        err_cor[k] = math.hypot(loc.pose[0] - truth[k][0], loc.pose[1] - truth[k][1])
    return DriveErrors(paint_loss, t, err_odo, err_cor, accepted / n)


def _figures(
    tables: list[RangeTable],
    sweep: tuple[FloatArray, FloatArray, FloatArray],
    drives: list[DriveErrors],
    out: Path,
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mids = [0.5 * (a + b) for a, b in itertools.pairwise(BANDS_M)]
    fig, axes = plt.subplots(1, 4, figsize=(17, 3.8))
    for tab in tables:
        label = f"paint loss {tab.paint_loss:.0%}"
        axes[0].plot(mids, tab.return_recall, "o-", label=label)
        axes[1].plot(mids, tab.feature_recall, "o-", label=label)
        axes[2].plot(mids, tab.false_cells_per_scan, "o-", label=label)
    losses, recall, accepted = sweep
    axes[3].plot(100 * losses, recall, "o-", label="paint returns kept (within 15 m)")
    axes[3].plot(100 * losses, accepted, "s-", label="scans with a correction accepted")
    axes[3].set_title("by the paint's loss of reflectivity")
    axes[3].set_ylim(0, 1.05)
    axes[3].legend(fontsize=8)
    axes[0].set_title("returns on paint kept as marking")
    axes[1].set_title("markings found by a fitted line or arc")
    axes[2].set_title("feature cells off the markings, per scan")
    for ax in axes[:3]:
        ax.set_xlabel("horizontal range [m]")
        ax.grid(alpha=0.3)
    axes[0].set_ylim(0, 1.05)
    axes[1].set_ylim(0, 1.05)
    axes[3].set_xlabel("paint loss [%]")
    axes[3].grid(alpha=0.3)
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out / "markings-detection.png", dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(drives[0].t_s, drives[0].odometry_m, "k-", label="odometry only")
    for d in drives:
        ax.plot(d.t_s, d.corrected_m, label=f"corrected, paint loss {d.paint_loss:.0%}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("position error [m]")
    ax.set_yscale("log")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "markings-drive.png", dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> None:
    """Print the tables and write the figures (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    parser.add_argument("--scans", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--no-figures", action="store_true")
    args = parser.parse_args(argv)
    config = default_config().markings
    tables = [detection_table(config, loss, args.scans, args.seed) for loss in LOSSES]
    print(f"detection by range band over {args.scans} scans (seed {args.seed})")
    print("loss  band_m   return_recall  return_false  marking_recall  false_cells/scan  n_paint")
    for tab in tables:
        for b in range(len(BANDS_M) - 1):
            print(
                f"{tab.paint_loss:4.0%}  {BANDS_M[b]:4.0f}-{BANDS_M[b + 1]:<4.0f} "
                f"{tab.return_recall[b]:13.3f} {tab.return_false_rate[b]:13.2e} "
                f"{tab.feature_recall[b]:15.3f} {tab.false_cells_per_scan[b]:17.2f} "
                f"{tab.n_paint_returns[b]:8.0f}"
            )
    losses = np.round(np.arange(0.0, 0.81, 0.1), 2)
    recall, accepted = loss_sweep(config, losses, max(args.scans // 2, 1), args.seed)
    print("paint loss sweep: loss  return_recall_15m  correction_accepted")
    for row in zip(losses, recall, accepted, strict=True):
        print(f"  {row[0]:4.0%}  {row[1]:16.3f}  {row[2]:19.2f}")
    drives = [drive_errors(config, loss, args.seed) for loss in LOSSES]
    print("drive 90 m, odometry drift 2 % + 0.002 rad/s")
    print("loss  accepted  odometry_final_m  odometry_max_m  corrected_rms_m  corrected_max_m")
    for d in drives:
        print(
            f"{d.paint_loss:4.0%}  {d.accepted:8.2f}  {d.odometry_m[-1]:16.3f}  "
            f"{d.odometry_m.max():14.3f}  {float(np.sqrt(np.mean(d.corrected_m**2))):15.3f}  "
            f"{d.corrected_m.max():15.3f}"
        )
    if not args.no_figures:
        args.out.mkdir(parents=True, exist_ok=True)
        _figures(tables, (losses, recall, accepted), drives, args.out)
        print(f"wrote {args.out / 'markings-detection.png'} and {args.out / 'markings-drive.png'}")


if __name__ == "__main__":
    main()
