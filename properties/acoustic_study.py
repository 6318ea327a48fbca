"""Feasibility of acoustic alerts on an apron: detection rate, false alarms per hour and bearing
error against SNR (SR-ACU-1, SR-ACU-2; docs/findings/acoustic.md).

``python -m properties.acoustic_study [--windows N] [--noise-hours H] [--seed S]`` simulates
3 s windows of the configured array hearing one reversing beeper 8 m away (random bearing,
1-2.5 kHz, period 0.5-1.0 s, duty 0.5, random phase) over apron noise at the DESIGN #23 levels,
at broadband SNRs from -30 to +20 dB (set exactly at microphone 0), and ``H`` hours of noise
alone; each window runs through the detector at the configured setting and at a looser one
(``pulse_min_corr`` 0.3). It prints a Markdown table and writes docs/images/acoustic-detection.png
and docs/images/acoustic-bearing.png.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np

from pipeline.config import AcousticSection, default_config
from pipeline.sensors.acoustic import AcousticDetector
from properties.acoustic_cases import band_snr_db, beeper_at, heard, noise_only, wrap_rad

__all__ = ["SNRS_DB", "Study", "main", "run_study"]

SNRS_DB = tuple(float(v) for v in range(-30, 25, 5))
WINDOW_S = 3.0
LOOSE_CORR = 0.3


@dataclass
class Study:
    """Results per setting (``configured``, ``loose``): detections and bearing errors [deg]
    per SNR, the in-band SNR per SNR [dB], and false alarms over ``noise_s`` of noise alone."""

    windows: int
    noise_s: float = 0.0
    detected: dict[str, dict[float, int]] = field(default_factory=dict)
    errors_deg: dict[str, dict[float, list[float]]] = field(default_factory=dict)
    band_snr_db: dict[float, list[float]] = field(default_factory=dict)
    false_alarms: dict[str, int] = field(default_factory=dict)
    ambiguous: dict[float, int] = field(default_factory=dict)
    gross_unflagged: dict[float, int] = field(default_factory=dict)

    def rate(self, setting: str, snr: float) -> float:
        """Share of windows with an alert."""
        return self.detected[setting][snr] / self.windows

    def per_hour(self, setting: str) -> float:
        """False alarms per hour of noise alone."""
        return self.false_alarms[setting] * 3600.0 / self.noise_s

    def error(self, setting: str, snr: float, q: float) -> float:
        """The ``q`` quantile of the bearing error [deg] of the detections (NaN: none)."""
        errs = self.errors_deg[setting][snr]
        return float(np.quantile(errs, q)) if errs else math.nan


def _detectors(section: AcousticSection) -> dict[str, AcousticDetector]:
    loose = section.model_copy(update={"pulse_min_corr": LOOSE_CORR})
    return {"configured": AcousticDetector(section), "loose": AcousticDetector(loose)}


def run_study(windows: int, noise_hours: float, seed: int) -> Study:
    """Run the study (module docstring)."""
    section = default_config().acoustic
    detectors = _detectors(section)
    study = Study(windows)
    rng = np.random.default_rng(seed)
    for name in detectors:
        study.detected[name] = dict.fromkeys(SNRS_DB, 0)
        study.errors_deg[name] = {snr: [] for snr in SNRS_DB}
        study.false_alarms[name] = 0
    for snr in SNRS_DB:
        study.band_snr_db[snr] = []
        study.ambiguous[snr] = 0
        study.gross_unflagged[snr] = 0
        for _ in range(windows):
            bearing = float(rng.uniform(-math.pi, math.pi))
            period = float(rng.uniform(0.5, 1.0))
            source = beeper_at(
                bearing, float(rng.uniform(1000.0, 2500.0)), period, float(rng.uniform(0, period))
            )
            case = heard(section, source, snr, WINDOW_S, rng)
            study.band_snr_db[snr].append(
                band_snr_db(case, section.beeper_low_hz, section.beeper_high_hz)
            )
            for name, detector in detectors.items():
                alert = detector.detect(case.clip).alert
                if alert is not None:
                    study.detected[name][snr] += 1
                    error = abs(wrap_rad(alert.bearing_rad - case.bearing_rad))
                    study.errors_deg[name][snr].append(math.degrees(error))
                    if name == "configured":
                        study.ambiguous[snr] += alert.ambiguous
                        gross = math.degrees(error) > 5.0 and not alert.ambiguous
                        study.gross_unflagged[snr] += gross
    n_noise = math.ceil(noise_hours * 3600.0 / WINDOW_S)
    for _ in range(n_noise):
        clip = noise_only(section, WINDOW_S, rng)
        for name, detector in detectors.items():
            if detector.detect(clip).alert is not None:
                study.false_alarms[name] += 1
    study.noise_s = n_noise * WINDOW_S
    return study


def table(study: Study) -> str:
    """The study as a Markdown table."""
    lines = [
        "| broadband SNR [dB] | in-band SNR, median [dB] | detected (configured) | detected "
        "(loose) | bearing error p50 / p95 / max [deg] (configured) | flagged ambiguous | "
        "off by > 5 deg, not flagged |",
        "|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for snr in SNRS_DB:
        band = float(np.median(study.band_snr_db[snr]))
        lines.append(
            f"| {snr:+.0f} | {band:+.1f} | {study.rate('configured', snr):.0%} | "
            f"{study.rate('loose', snr):.0%} | {study.error('configured', snr, 0.5):.1f} / "
            f"{study.error('configured', snr, 0.95):.1f} / "
            f"{study.error('configured', snr, 1.0):.1f} | {study.ambiguous[snr]} | "
            f"{study.gross_unflagged[snr]} |"
        )
    lines.append("")
    lines.append(
        f"False alarms on {study.noise_s / 3600.0:.2f} h of noise alone: configured "
        f"{study.false_alarms['configured']} ({study.per_hour('configured'):.1f} per hour), "
        f"loose {study.false_alarms['loose']} ({study.per_hour('loose'):.1f} per hour)."
    )
    return "\n".join(lines)


def figures(study: Study, out: Path) -> None:
    """docs/images/acoustic-detection.png and acoustic-bearing.png."""
    snrs = np.array(SNRS_DB)
    # In-band minus broadband SNR does not depend on the scaling: one offset per study.
    offset = float(np.median([float(np.median(study.band_snr_db[s])) - s for s in SNRS_DB]))
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    for name, colour in (("configured", "tab:blue"), ("loose", "tab:orange")):
        rates = [study.rate(name, s) for s in SNRS_DB]
        ax.plot(
            snrs,
            rates,
            "o-",
            color=colour,
            label=f"{name}: {study.per_hour(name):.1f} false alarms / h",
        )
    ax.axvline(10.0, color="tab:red", linestyle="--", linewidth=1, label="source: 10 dB")
    ax.set_xlabel("broadband SNR at the microphone [dB]")
    ax.set_ylabel("windows with a beeper alert")
    ax.set_ylim(-0.02, 1.02)
    top = ax.secondary_xaxis("top", functions=(partial(np.add, offset), partial(np.add, -offset)))
    top.set_xlabel(f"in-band (1-2.5 kHz) SNR [dB] (broadband {offset:+.1f} dB, median)")
    ax.set_title(
        f"Reversing beeper 8 m away over apron noise, {study.windows} windows of 3 s per point",
        fontsize=9,
    )
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "acoustic-detection.png", dpi=120)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7.5, 4.0))
    for q, style in ((0.5, "o-"), (0.95, "s--")):
        ax.plot(
            snrs, [study.error("configured", s, q) for s in SNRS_DB], style, label=f"p{q:.0%}"[:-1]
        )
    ax.set_yscale("log")
    ax.set_xlabel("broadband SNR at the microphone [dB]")
    ax.set_ylabel("bearing error of the alerts [deg]")
    ax.set_title("Bearing error (GCC-PHAT + least squares), configured setting", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "acoustic-bearing.png", dpi=120)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    """Command line entry (module docstring)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--windows", type=int, default=40)
    parser.add_argument("--noise-hours", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=23)
    parser.add_argument("--out", type=Path, default=Path("docs/images"))
    args = parser.parse_args(argv)
    study = run_study(args.windows, args.noise_hours, args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    figures(study, args.out)
    print(table(study))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
