"""Simulated microphone array on an apron: beepers, horns and apron noise (SR-ACU-5).

The array (:func:`circular_array`) is ``n`` microphones on a circle, neighbours
``spacing_m`` apart (airside recommendation #23: 4-8 MEMS microphones about 15 cm apart).
Every sound is a point source in the robot frame whose waveform reaches each microphone
delayed by ``r / c`` and attenuated by ``1 / r`` (spherical spreading, ``r`` the distance
from the source to that microphone). Delays are fractional, applied as a phase shift of the
waveform's spectrum (exact for a band-limited signal), relative to the array's centre so that
the padding stays small.

Sources (waveform at 1 m, then levels set where the array hears them):

- a reversing beeper (:class:`Beeper`): a tone of 1-2.5 kHz with its 2nd and 3rd harmonics,
  pulsed on and off with a period and duty cycle, with 2 ms ramps;
- a horn (:class:`Horn`): a harmonic stack of fundamental 250-600 Hz, amplitudes ``1 / k``,
  sustained for a while;
- apron noise (:class:`ApronNoise`), each part at its level in dB SPL at the array (DESIGN
  #23): a turbine engine (broadband falling 3 dB per octave above 200 Hz plus harmonics of a
  shaft tone) 50 m away, a ground power unit (400 Hz hum with harmonics to 3.2 kHz) 15 m away,
  a belt loader (broadband 200-4000 Hz with a slow rattle) 8 m away, wind on each microphone
  (independent noise below 150 Hz, the same level on every microphone) and the microphones'
  own noise (independent, white).

The signal-to-noise ratio of an experiment is set exactly (:func:`scaled_to_snr`): the
broadband (unweighted) power of the signal at the reference microphone while it sounds, over
the noise's power there. Randomness only through the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pipeline.sensors.doa import circular_array
from pipeline.types import BoolArray, FloatArray
from pipeline.types.acoustic import AudioClip

__all__ = [
    "ApronNoise",
    "Beeper",
    "Horn",
    "apron_noise",
    "circular_array",
    "level_pa",
    "propagate",
    "scaled_to_snr",
    "source_signal",
]

# Reference pressure of dB SPL [Pa].
P_REF_PA = 20e-6
# Extra samples at each end of a rendered waveform, so fractional delays of up to this many
# samples never wrap around the circular shift.
_PAD = 64
# Onset and release ramps of a beeper pulse [s].
_RAMP_S = 0.002


def level_pa(level_db: float) -> float:
    """RMS pressure [Pa] of a sound pressure level [dB SPL]."""
    return float(P_REF_PA * 10.0 ** (level_db / 20.0))


@dataclass(frozen=True, slots=True)
class Beeper:
    """A reversing beeper at ``(x_m, y_m)`` in the robot frame: a tone of ``freq_hz`` pulsed
    on for ``duty`` of every ``period_s``, its first pulse starting ``phase_s`` into the period
    before the clip; harmonics 2 and 3 at ``harmonic_db`` below the fundamental."""

    x_m: float
    y_m: float
    freq_hz: float = 1_250.0
    period_s: float = 0.8
    duty: float = 0.5
    phase_s: float = 0.0
    harmonic_db: tuple[float, float] = (-12.0, -10.0)

    def on(self, t_s: FloatArray) -> FloatArray:
        """Gain in [0, 1] at times ``t_s`` [s] from the clip's start: 1 during a pulse, with
        linear ramps of 2 ms at either end."""
        into = np.mod(t_s + self.phase_s, self.period_s)
        width = self.duty * self.period_s
        rise = np.clip(into / _RAMP_S, 0.0, 1.0)
        fall = np.clip((width - into) / _RAMP_S, 0.0, 1.0)
        gain: FloatArray = np.minimum(rise, fall)
        return gain

    def waveform(self, t_s: FloatArray, nyquist_hz: float) -> FloatArray:
        """Pressure at 1 m (unscaled) at times ``t_s`` [s]."""
        tone = np.sin(2.0 * np.pi * self.freq_hz * t_s)
        for k, db in zip((2, 3), self.harmonic_db, strict=True):
            if k * self.freq_hz < 0.95 * nyquist_hz:
                tone = tone + 10.0 ** (db / 20.0) * np.sin(2.0 * np.pi * k * self.freq_hz * t_s)
        wave: FloatArray = tone * self.on(t_s)
        return wave


@dataclass(frozen=True, slots=True)
class Horn:
    """A horn at ``(x_m, y_m)``: ``n_harmonics`` harmonics of ``f0_hz`` (amplitude ``1 / k``)
    sounding from ``start_s`` for ``duration_s`` (times from the clip's start)."""

    x_m: float
    y_m: float
    f0_hz: float = 420.0
    start_s: float = 0.2
    duration_s: float = 0.8
    n_harmonics: int = 6

    def on(self, t_s: FloatArray) -> FloatArray:
        """Gain in [0, 1] at times ``t_s`` [s] (10 ms ramps)."""
        rise = np.clip((t_s - self.start_s) / 0.01, 0.0, 1.0)
        fall = np.clip((self.start_s + self.duration_s - t_s) / 0.01, 0.0, 1.0)
        gain: FloatArray = np.minimum(rise, fall)
        return gain

    def waveform(self, t_s: FloatArray, nyquist_hz: float) -> FloatArray:
        """Pressure at 1 m (unscaled) at times ``t_s`` [s]."""
        wave = np.zeros_like(t_s)
        for k in range(1, self.n_harmonics + 1):
            if k * self.f0_hz < 0.95 * nyquist_hz:
                wave = wave + np.sin(2.0 * np.pi * k * self.f0_hz * t_s + 0.7 * k) / k
        gained: FloatArray = wave * self.on(t_s)
        return gained


Source = Beeper | Horn


@dataclass(frozen=True, slots=True)
class ApronNoise:
    """Levels [dB SPL at the array] of the apron's noise and where its sources stand.

    Defaults: an idling engine 85 dB (80-90 dB at 50 m), a ground power unit 80 dB (75-85 dB),
    a belt loader 75 dB (70-80 dB), wind 70 dB per microphone, microphone self-noise 30 dB
    (MEMS class). A level of ``None`` leaves the part out.
    """

    engine_db: float | None = 85.0
    gpu_db: float | None = 80.0
    belt_db: float | None = 75.0
    wind_db: float | None = 70.0
    self_db: float = 30.0
    engine_bearing_rad: float = 2.3
    gpu_bearing_rad: float = -1.9
    belt_bearing_rad: float = 0.6
    engine_shaft_hz: float = 95.0


def _shaped_noise(
    rng: np.random.Generator, n: int, fs: float, shape: FloatArray | None, count: int = 1
) -> FloatArray:
    """``count`` independent unit-RMS noises of ``n`` samples whose spectrum magnitude is
    ``shape(f)`` (given on ``rfftfreq(n, 1/fs)``; None: white)."""
    white = rng.standard_normal((count, n))
    out = white if shape is None else np.fft.irfft(np.fft.rfft(white, axis=1) * shape, n=n, axis=1)
    rms = np.sqrt(np.mean(out * out, axis=1, keepdims=True))
    normed: FloatArray = out / np.where(rms > 0.0, rms, 1.0)
    return normed


def propagate(
    wave_1m: FloatArray,
    src_xy_m: tuple[float, float],
    mic_xy_m: FloatArray,
    fs: float,
    c_mps: float,
) -> FloatArray:
    """The waveform ``wave_1m`` (pressure at 1 m, ``n + 2 * 64`` samples with 64 samples of
    padding at each end) as each microphone hears it: (n_mics, n) [Pa].

    Delay ``(r_i - r_0) / c`` relative to the array centre's distance ``r_0`` (a phase shift of
    the spectrum: fractional delays are exact for band-limited waveforms), amplitude ``1 / r_i``
    (never louder than at 1 m: distances below 1 m count as 1 m).
    """
    centre = mic_xy_m.mean(axis=0)
    r_i = np.hypot(mic_xy_m[:, 0] - src_xy_m[0], mic_xy_m[:, 1] - src_xy_m[1])
    r_0 = math.hypot(centre[0] - src_xy_m[0], centre[1] - src_xy_m[1])
    delay = (r_i - r_0) / c_mps
    if np.max(np.abs(delay)) * fs >= _PAD:
        raise ValueError("propagate: the array is wider than the padding allows")
    n_total = wave_1m.shape[0]
    freqs = np.fft.rfftfreq(n_total, 1.0 / fs)
    spectrum = np.fft.rfft(wave_1m)
    shifted = np.fft.irfft(
        spectrum[None, :] * np.exp(-2j * np.pi * freqs[None, :] * delay[:, None]), n=n_total
    )
    gain = 1.0 / np.maximum(r_i, 1.0)
    heard: FloatArray = shifted[:, _PAD:-_PAD] * gain[:, None]
    return heard


def _times(n: int, fs: float) -> FloatArray:
    """Times [s] of ``n`` samples plus the padding at each end, from the clip's first sample."""
    times: FloatArray = (np.arange(n + 2 * _PAD) - _PAD) / fs
    return times


def source_signal(
    source: Source, mic_xy_m: FloatArray, n: int, fs: float, c_mps: float
) -> tuple[FloatArray, BoolArray]:
    """``source`` as each microphone hears it, (n_mics, n) [Pa, unscaled: 1 at 1 m], and where it
    sounds at the array's centre (n,) (for setting the SNR over the sounding samples)."""
    t = _times(n, fs)
    wave = source.waveform(t, fs / 2.0)
    heard = propagate(wave, (source.x_m, source.y_m), mic_xy_m, fs, c_mps)
    # Times are of arrival at the array's centre: the travel time to it is not modelled.
    sounding = source.on(t[_PAD:-_PAD]) > 0.5
    return heard, sounding


def _at_bearing(bearing_rad: float, range_m: float) -> tuple[float, float]:
    return range_m * math.cos(bearing_rad), range_m * math.sin(bearing_rad)


def apron_noise(
    noise: ApronNoise,
    mic_xy_m: FloatArray,
    n: int,
    fs: float,
    c_mps: float,
    rng: np.random.Generator,
) -> FloatArray:
    """Apron noise (n_mics, n) [Pa] at the levels of ``noise`` (module docstring)."""
    n_mics = mic_xy_m.shape[0]
    total = n + 2 * _PAD
    freqs = np.fft.rfftfreq(total, 1.0 / fs)
    t = _times(n, fs)
    out = np.zeros((n_mics, n))

    def point(level_db: float, bearing_rad: float, range_m: float, wave: FloatArray) -> None:
        heard = propagate(wave, _at_bearing(bearing_rad, range_m), mic_xy_m, fs, c_mps)
        rms = float(np.sqrt(np.mean(heard * heard)))
        out[:] += heard * (level_pa(level_db) / rms)

    if noise.engine_db is not None:
        # Broadband falling 3 dB/octave above 200 Hz, plus shaft harmonics to 2 kHz.
        shape = 1.0 / np.sqrt(1.0 + freqs / 200.0)
        wave = _shaped_noise(rng, total, fs, shape)[0]
        f0 = noise.engine_shaft_hz
        phases = rng.uniform(0.0, 2.0 * np.pi, 20)
        for k in range(1, 21):
            wave = wave + 0.5 / k * np.sin(2.0 * np.pi * k * f0 * t + phases[k - 1])
        point(noise.engine_db, noise.engine_bearing_rad, 50.0, wave)
    if noise.gpu_db is not None:
        # 400 Hz generator hum with harmonics up to 3.2 kHz, over a weak broadband floor.
        wave = 0.1 * _shaped_noise(rng, total, fs, None)[0]
        phases = rng.uniform(0.0, 2.0 * np.pi, 8)
        for k in range(1, 9):
            wave = wave + 1.0 / k * np.sin(2.0 * np.pi * 400.0 * k * t + phases[k - 1])
        point(noise.gpu_db, noise.gpu_bearing_rad, 15.0, wave)
    if noise.belt_db is not None:
        # Broadband 200-4000 Hz, rattling at 1.3 Hz (30 % amplitude modulation).
        shape = ((freqs > 200.0) & (freqs < 4000.0)).astype(np.float64)
        wave = _shaped_noise(rng, total, fs, shape)[0]
        wave = wave * (1.0 + 0.3 * np.sin(2.0 * np.pi * 1.3 * t + rng.uniform(0.0, 6.3)))
        point(noise.belt_db, noise.belt_bearing_rad, 8.0, wave)
    if noise.wind_db is not None:
        # Turbulence at each microphone's port: independent per microphone, below 150 Hz.
        low: FloatArray = np.asarray(1.0 / (1.0 + (np.fft.rfftfreq(n, 1.0 / fs) / 150.0) ** 4))
        out += level_pa(noise.wind_db) * _shaped_noise(rng, n, fs, low, n_mics)
    out += level_pa(noise.self_db) * rng.standard_normal((n_mics, n))
    return out


def scaled_to_snr(
    signal: FloatArray, sounding: BoolArray, noise: FloatArray, snr_db: float, ref_mic: int = 0
) -> FloatArray:
    """``signal`` scaled so that its mean power at ``ref_mic`` over the ``sounding`` samples is
    ``snr_db`` above the noise's mean power there (broadband, unweighted)."""
    if not np.any(sounding):
        raise ValueError("scaled_to_snr: the signal never sounds in this clip")
    p_sig = float(np.mean(signal[ref_mic, sounding] ** 2))
    p_noise = float(np.mean(noise[ref_mic] ** 2))
    scaled: FloatArray = signal * math.sqrt(p_noise / p_sig * 10.0 ** (snr_db / 10.0))
    return scaled


def clip_of(samples: FloatArray, fs: float, stamp_s: float, mic_xy_m: FloatArray) -> AudioClip:
    """The :class:`AudioClip` of rendered samples."""
    return AudioClip(samples, fs, stamp_s, mic_xy_m)
