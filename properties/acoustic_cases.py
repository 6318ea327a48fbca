"""Case builders of the acoustic properties and the acoustic study (SR-ACU-1, -2, -4): clips of a
simulated array hearing a beeper or a horn over apron noise at an exact SNR, noise-only clips,
and delayed pairs of broadband signals."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.config import AcousticSection
from pipeline.sensors.acoustic import array_of
from pipeline.sources.sim.acoustic import (
    ApronNoise,
    Beeper,
    Horn,
    apron_noise,
    scaled_to_snr,
    source_signal,
)
from pipeline.types import FloatArray
from pipeline.types.acoustic import AudioClip

__all__ = ["Heard", "band_snr_db", "beeper_at", "heard", "noise_only", "wrap_rad"]

# How far the sound sources stand from the array [m] (a reversing vehicle close behind).
SOURCE_RANGE_M = 8.0


@dataclass(frozen=True, slots=True)
class Heard:
    """A clip with what it contains: the source's true bearing [rad] (NaN: noise only), the
    broadband SNR it was set to [dB] and the signal and noise parts at the microphones."""

    clip: AudioClip
    bearing_rad: float
    snr_db: float
    signal: FloatArray
    noise: FloatArray


def wrap_rad(angle: float) -> float:
    """``angle`` wrapped into [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def beeper_at(
    bearing_rad: float, freq_hz: float, period_s: float, phase_s: float, duty: float = 0.5
) -> Beeper:
    """A beeper ``SOURCE_RANGE_M`` from the array's centre at ``bearing_rad``."""
    return Beeper(
        SOURCE_RANGE_M * math.cos(bearing_rad),
        SOURCE_RANGE_M * math.sin(bearing_rad),
        freq_hz=freq_hz,
        period_s=period_s,
        duty=duty,
        phase_s=phase_s,
    )


def heard(
    section: AcousticSection,
    source: Beeper | Horn,
    snr_db: float,
    duration_s: float,
    rng: np.random.Generator,
    noise: ApronNoise | None = None,
    stamp_s: float = 0.0,
) -> Heard:
    """``source`` over apron noise at broadband SNR ``snr_db`` at microphone 0, as the
    configured array hears it for ``duration_s``."""
    quiet = noise_only(section, duration_s, rng, noise, stamp_s)
    mics, background, fs = quiet.mic_xy_m, quiet.samples, quiet.sample_rate_hz
    signal, sounding = source_signal(
        source, mics, background.shape[1], fs, section.speed_of_sound_mps
    )
    scaled = scaled_to_snr(signal, sounding, background, snr_db)
    bearing = math.atan2(source.y_m - mics[:, 1].mean(), source.x_m - mics[:, 0].mean())
    return Heard(
        AudioClip(background + scaled, fs, stamp_s, mics), bearing, snr_db, scaled, background
    )


def noise_only(
    section: AcousticSection,
    duration_s: float,
    rng: np.random.Generator,
    noise: ApronNoise | None = None,
    stamp_s: float = 0.0,
) -> AudioClip:
    """Apron noise alone, as the configured array hears it for ``duration_s``."""
    mics = array_of(section)
    fs, c = section.sample_rate_hz, section.speed_of_sound_mps
    n = round(duration_s * fs)
    background = apron_noise(noise if noise is not None else ApronNoise(), mics, n, fs, c, rng)
    return AudioClip(background, fs, stamp_s, mics)


def band_snr_db(case: Heard, low_hz: float, high_hz: float) -> float:
    """The SNR of ``case`` at microphone 0 within ``low_hz``..``high_hz`` [dB], over the whole
    clip (the signal's power averaged over its on and off times)."""
    fs = case.clip.sample_rate_hz
    freqs = np.fft.rfftfreq(case.signal.shape[1], 1.0 / fs)
    band = (freqs >= low_hz) & (freqs <= high_hz)
    p_sig = float(np.sum(np.abs(np.fft.rfft(case.signal[0])[band]) ** 2))
    p_noise = float(np.sum(np.abs(np.fft.rfft(case.noise[0])[band]) ** 2))
    return 10.0 * math.log10(p_sig / p_noise)
