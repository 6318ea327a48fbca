"""Acoustic alert detection: reversing beepers and horns heard by a microphone array
(airside recommendation #23; SR-ACU-1, SR-ACU-2).

One analysis window (an :class:`~pipeline.types.acoustic.AudioClip` of a few seconds) at a time:

1. **STFT** of every microphone (Hann window of ``acoustic.stft_len`` samples every
   ``acoustic.stft_hop``), and the band power: the mean over the microphones of ``|X|^2`` per
   bin and frame (wind on the ports is independent per microphone, so the mean lowers it).
2. **Adaptive noise floor**: per bin, the ``acoustic.floor_quantile`` of its power over the
   window. A steady sound (an engine, the 400 Hz hum of a ground power unit) sits in its floor;
   a pulsed or newly started one rises above it. The excess ``e = 10 log10(power / floor)`` [dB].
3. **Beeper** (pulse-pattern matching): for every bin of ``acoustic.beeper_low_hz``..
   ``beeper_high_hz``, the excess over time is correlated with itself (Pearson) at every lag of
   a period in ``acoustic.pulse_min_period_s``..``pulse_max_period_s`` and at half that lag; a
   square wave of that period correlates fully at the period and negatively at half of it, so
   the score is ``(r(P) - r(P / 2)) / 2``. The best bin's score must reach
   ``acoustic.pulse_min_corr``, and its frames above their median must exceed those below by
   ``acoustic.on_db`` on average (the pulses stand out of the floor).
4. **Horn** (harmonic stack): for every fundamental bin in ``acoustic.horn_low_hz``..
   ``horn_high_hz``, the mean excess of its first ``acoustic.horn_harmonics`` harmonics; a horn
   is heard where it reaches ``acoustic.horn_db`` for ``acoustic.horn_min_s`` in a row.
5. **Bearing** (:mod:`pipeline.sensors.doa`): GCC-PHAT over the frames in which the sound is on
   and the bins it occupies (for a beeper every bin up to three times ``beeper_high_hz`` whose
   pulse score reaches ``pulse_min_corr``: its tone, the tone's neighbours and harmonics; for a
   horn its harmonics), the delay bounded by each pair's geometry, least squares
   over the pairs.

The output is an :class:`~pipeline.types.acoustic.AcousticAlert` stamped with the window's last
sample: a bearing, a confidence (the score, scaled to [0, 1]) and the kind; never a position.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pipeline.config import AcousticSection
from pipeline.errors import SafecaseError
from pipeline.sensors.doa import Bearing, ComplexArray, circular_array, estimate_bearing
from pipeline.types import BoolArray, FloatArray, IntArray
from pipeline.types.acoustic import AcousticAlert, AlertKind, AudioClip

__all__ = [
    "AcousticDetection",
    "AcousticDetector",
    "AcousticInputError",
    "Spectrogram",
    "array_of",
    "spectrogram",
]


class AcousticInputError(SafecaseError, ValueError):
    """Audio the detector cannot use: another sample rate than configured, non-finite samples,
    or a window shorter than two pulse periods."""


def array_of(section: AcousticSection) -> FloatArray:
    """The configured microphone positions (n, 2) [m] in the robot frame."""
    return circular_array(
        section.n_mics, section.mic_spacing_m, (section.mount_x_m, section.mount_y_m)
    )


@dataclass(frozen=True, slots=True)
class Spectrogram:
    """STFT of a clip: ``spectra`` (n_mics, n_freq, n_frames), the mean power over microphones
    ``power`` (n_freq, n_frames) [Pa^2 per bin], bin centres ``freqs_hz`` and the frame period
    ``hop_s`` [s]."""

    spectra: ComplexArray
    power: FloatArray
    freqs_hz: FloatArray
    hop_s: float


def spectrogram(clip: AudioClip, section: AcousticSection) -> Spectrogram:
    """The clip's STFT and band power (module docstring, step 1)."""
    # Imported here: scipy.signal costs half a second, which every `safecase` command would pay.
    import scipy.signal

    freqs, _, z = scipy.signal.stft(
        clip.samples,
        fs=clip.sample_rate_hz,
        window="hann",
        nperseg=section.stft_len,
        noverlap=section.stft_len - section.stft_hop,
        boundary=None,
        padded=False,
    )
    spectra = np.asarray(z, dtype=np.complex128)
    power = np.mean(np.abs(spectra) ** 2, axis=0)
    return Spectrogram(spectra, power, freqs, section.stft_hop / clip.sample_rate_hz)


@dataclass(frozen=True, slots=True)
class AcousticDetection:
    """What the detector found in one window: the alert (None: nothing heard), the beeper's
    pulse score in [-1, 1] and its bin [Hz], the horn's longest run [s], and behind an alert
    the bearing estimate, the STFT bins and the frames it used (each None without an alert)."""

    alert: AcousticAlert | None
    beeper_score: float
    beeper_hz: float
    horn_run_s: float
    bearing: Bearing | None
    bins: IntArray | None
    frames: BoolArray | None


def _pearson_at(e: FloatArray, lag: int) -> FloatArray:
    """Pearson correlation of each row of ``e`` (bins, frames) with itself ``lag`` frames on."""
    a, b = e[:, :-lag], e[:, lag:]
    a = a - a.mean(axis=1, keepdims=True)
    b = b - b.mean(axis=1, keepdims=True)
    den = np.sqrt(np.sum(a * a, axis=1) * np.sum(b * b, axis=1))
    r: FloatArray = np.sum(a * b, axis=1) / np.where(den > 0.0, den, np.inf)
    return r


class AcousticDetector:
    """The detector of one configuration (module docstring); :meth:`detect` per window."""

    def __init__(self, section: AcousticSection) -> None:
        self.section = section
        self.mic_xy_m = array_of(section)

    def excess_db(self, spec: Spectrogram) -> FloatArray:
        """Excess of each bin's power over its adaptive floor [dB] (bins, frames)."""
        floor = np.quantile(spec.power, self.section.floor_quantile, axis=1, keepdims=True)
        tiny = np.finfo(np.float64).tiny
        excess: FloatArray = 10.0 * np.log10(np.maximum(spec.power, tiny) / np.maximum(floor, tiny))
        return excess

    def _check(self, clip: AudioClip) -> None:
        s = self.section
        if clip.sample_rate_hz != s.sample_rate_hz:
            raise AcousticInputError(
                f"audio at {clip.sample_rate_hz} Hz, the detector is configured for "
                f"acoustic.sample_rate_hz = {s.sample_rate_hz} Hz"
            )
        if clip.n_mics != s.n_mics:
            raise AcousticInputError(
                f"audio of {clip.n_mics} microphones, acoustic.n_mics = {s.n_mics}"
            )
        if not np.all(np.isfinite(clip.samples)):
            raise AcousticInputError("audio with non-finite samples")
        need = 2.0 * s.pulse_max_period_s + s.stft_len / s.sample_rate_hz
        have = clip.samples.shape[1] / s.sample_rate_hz
        if have < need:
            raise AcousticInputError(
                f"a window of {have:.3f} s; the pulse pattern needs two periods of "
                f"acoustic.pulse_max_period_s plus one STFT frame ({need:.3f} s)"
            )

    def beeper_scores(
        self, excess: FloatArray, spec: Spectrogram, high_hz: float
    ) -> tuple[FloatArray, IntArray]:
        """Pulse score per bin from ``acoustic.beeper_low_hz`` to ``high_hz`` (module docstring,
        step 3) and the bins scored."""
        s = self.section
        bins = np.flatnonzero((spec.freqs_hz >= s.beeper_low_hz) & (spec.freqs_hz <= high_hz))
        e = excess[bins]
        lo = max(2, round(s.pulse_min_period_s / spec.hop_s))
        hi = min(round(s.pulse_max_period_s / spec.hop_s), e.shape[1] // 2)
        best = np.full(bins.shape[0], -1.0)
        for lag in range(lo, hi + 1):
            score = 0.5 * (_pearson_at(e, lag) - _pearson_at(e, max(1, lag // 2)))
            best = np.maximum(best, score)
        return best, bins.astype(np.int64)

    def horn_run(self, excess: FloatArray, spec: Spectrogram) -> tuple[int, BoolArray, IntArray]:
        """The longest run of frames [count] in which some fundamental's harmonics reach
        ``horn_db`` (module docstring, step 4), those frames, and that fundamental's harmonic
        bins."""
        s = self.section
        df = spec.freqs_hz[1] - spec.freqs_hz[0]
        f0_bins = np.flatnonzero(
            (spec.freqs_hz >= s.horn_low_hz) & (spec.freqs_hz <= s.horn_high_hz)
        )
        k = np.arange(1, s.horn_harmonics + 1)
        harmonic_bins = np.rint(spec.freqs_hz[f0_bins][:, None] * k[None, :] / df).astype(np.int64)
        level = excess[harmonic_bins].mean(axis=1)  # (f0, frames)
        loud = level >= s.horn_db
        runs = _longest_runs(loud)
        best = int(np.argmax(runs))
        return int(runs[best]), loud[best], harmonic_bins[best]

    def detect(self, clip: AudioClip) -> AcousticDetection:
        """Alert (or None) for one window (module docstring). Raises
        :class:`AcousticInputError` on audio it cannot use."""
        self._check(clip)
        s = self.section
        spec = spectrogram(clip, s)
        excess = self.excess_db(spec)
        # Scored up to the 3rd harmonic of the highest beeper: the bearing uses every pulsing bin.
        top_hz = min(3.0 * s.beeper_high_hz, 0.95 * s.sample_rate_hz / 2.0)
        scores, bins = self.beeper_scores(excess, spec, top_hz)
        in_band = spec.freqs_hz[bins] <= s.beeper_high_hz
        b = int(np.argmax(np.where(in_band, scores, -np.inf)))
        score, tone_bin = float(scores[b]), int(bins[b])
        e = excess[tone_bin]
        on = e > np.median(e)
        contrast = float(e[on].mean() - e[~on].mean()) if np.any(on) and np.any(~on) else 0.0
        run, horn_on, horn_bins = self.horn_run(excess, spec)
        horn_run_s = run * spec.hop_s
        kind: AlertKind | None = None
        if score >= s.pulse_min_corr and contrast >= s.on_db:
            kind = AlertKind.BEEPER
            use = bins[scores >= s.pulse_min_corr]
            frames = on
            confidence = (score - s.pulse_min_corr) / (1.0 - s.pulse_min_corr)
        elif horn_run_s >= s.horn_min_s:
            kind = AlertKind.HORN
            use = np.unique(horn_bins[horn_bins < spec.freqs_hz.shape[0]])
            frames = horn_on
            confidence = min(1.0, horn_run_s / (2.0 * s.horn_min_s))
        if kind is None:
            return AcousticDetection(
                None, score, float(spec.freqs_hz[tone_bin]), horn_run_s, None, None, None
            )
        bearing = estimate_bearing(
            spec.spectra[:, use][:, :, frames],
            spec.freqs_hz[use],
            self.mic_xy_m - self.mic_xy_m.mean(axis=0),
            s.speed_of_sound_mps,
            1.0 / (s.sample_rate_hz * s.gcc_interp),
        )
        alert = AcousticAlert(
            kind,
            bearing.bearing_rad,
            float(np.clip(confidence, 0.0, 1.0)),
            clip.end_s,
            bearing.ambiguous,
        )
        return AcousticDetection(
            alert, score, float(spec.freqs_hz[tone_bin]), horn_run_s, bearing, use, frames
        )


def _longest_runs(flags: BoolArray) -> IntArray:
    """Length of the longest run of True in each row of ``flags`` (rows, frames)."""
    padded = np.concatenate(
        [np.zeros((flags.shape[0], 1), bool), flags, np.zeros((flags.shape[0], 1), bool)], axis=1
    )
    diff = np.diff(padded.astype(np.int8), axis=1)
    runs = np.zeros(flags.shape[0], dtype=np.int64)
    rows_start, cols_start = np.nonzero(diff == 1)
    _, cols_end = np.nonzero(diff == -1)
    if rows_start.shape[0]:
        np.maximum.at(runs, rows_start, cols_end - cols_start)
    return runs
