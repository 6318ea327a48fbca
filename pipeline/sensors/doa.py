"""Direction of arrival from a microphone array: GCC-PHAT per pair, bearing by least squares
(SR-ACU-2).

**GCC-PHAT.** For microphones ``i`` and ``j`` hearing ``x_i(t) = s(t - t_i)``, the cross-spectrum
``G_ij(f) = X_i(f) conj(X_j(f))`` has phase ``-2 pi f (t_i - t_j)``; dividing by its magnitude
(the phase transform) whitens it, and ``cc(tau) = Re sum_f W(f) G_ij / |G_ij| e^{2 pi j f tau}``
peaks at ``tau = t_i - t_j``. The search is bounded by the pair's geometry: a sound from
anywhere reaches two microphones ``d_ij`` apart at most ``d_ij / c`` apart, so only
``|tau| <= d_ij / c`` is searched (:func:`gcc_phat` for two signals, on a grid ``interp`` times
finer than the sample period; :func:`pair_correlations` for the cross-spectra of a detection,
evaluated directly at any set of delays).

**Bearing.** A far-field source in unit direction ``u`` reaches a microphone at ``p`` at
``t0 - p . u / c``, so ``tau_ij = -(p_i - p_j) . u / c``. A tone's cross-correlation repeats every
period, and a pair wider than half a wavelength has more than one peak within its bound; so the
bearing is first the best of a 1-degree grid of directions by the summed pair correlations at
each direction's delays (steered response power), then each pair's delay is the peak of its own
correlation nearest that direction's delay (within the pair's bound), and the bearing is the
least-squares solution ``u`` of ``A u = tau`` over all pairs (``A`` rows ``-(p_i - p_j) / c``).
When another direction responds as strongly, the bearing is flagged ambiguous (:class:`Bearing`):
with 15 cm between neighbours a tone above about 1.1 kHz can alias exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from pipeline.types import FloatArray, IntArray

__all__ = [
    "AMBIGUITY_MARGIN",
    "AMBIGUITY_RAD",
    "Bearing",
    "bearing_from_delays",
    "circular_array",
    "estimate_bearing",
    "gcc_phat",
    "pair_correlations",
    "pair_indices",
    "pair_max_delays_s",
]

ComplexArray = npt.NDArray[np.complex128]

# Directions tried by the steered response before the least-squares refinement.
_GRID = np.deg2rad(np.arange(0.0, 360.0, 1.0))
# A second direction this far from the best [rad] whose response is within this much of the
# best's makes the bearing ambiguous.
AMBIGUITY_RAD = math.radians(20.0)
AMBIGUITY_MARGIN = 0.02


def circular_array(
    n_mics: int, spacing_m: float, centre_xy_m: tuple[float, float] = (0.0, 0.0)
) -> FloatArray:
    """Positions (n, 2) [m] of ``n`` microphones on a circle, neighbours ``spacing_m`` apart.

    The first microphone sits at angle ``pi / n`` from the robot's x axis, so a square array is
    aligned with the robot's axes.
    """
    if n_mics < 2 or not spacing_m > 0.0:
        raise ValueError(
            f"circular_array: need n_mics >= 2 and spacing_m > 0, got {n_mics}, {spacing_m}"
        )
    radius = spacing_m / (2.0 * math.sin(math.pi / n_mics))
    angle = math.pi / n_mics + 2.0 * math.pi * np.arange(n_mics) / n_mics
    return np.stack(
        [centre_xy_m[0] + radius * np.cos(angle), centre_xy_m[1] + radius * np.sin(angle)],
        axis=1,
    )


def pair_indices(n_mics: int) -> tuple[IntArray, IntArray]:
    """Every microphone pair ``(i, j)`` with ``i < j``."""
    i, j = np.triu_indices(n_mics, k=1)
    return i.astype(np.int64), j.astype(np.int64)


def pair_max_delays_s(mic_xy_m: FloatArray, c_mps: float) -> FloatArray:
    """The largest possible delay ``d_ij / c`` [s] of each pair (order of :func:`pair_indices`)."""
    i, j = pair_indices(mic_xy_m.shape[0])
    bounds: FloatArray = np.hypot(*(mic_xy_m[i] - mic_xy_m[j]).T) / c_mps
    return bounds


def gcc_phat(
    x: FloatArray, y: FloatArray, fs: float, max_delay_s: float, interp: int = 1
) -> tuple[float, float]:
    """The delay ``t_x - t_y`` [s] of ``y`` relative to ``x`` by GCC-PHAT over the whole band,
    searched within ``|tau| <= max_delay_s`` on a grid of ``1 / (fs * interp)``, and the peak's
    value (1 for a pure delay of a white signal).

    The correlation is circular over ``n`` samples (pad the signals for a linear one).
    """
    if x.shape != y.shape or x.ndim != 1:
        raise ValueError(f"gcc_phat: x and y must be 1-D of equal length, got {x.shape}, {y.shape}")
    n = x.shape[0]
    cross = np.fft.rfft(x) * np.conj(np.fft.rfft(y))
    magnitude = np.abs(cross)
    weighted = np.where(magnitude > 0.0, cross / np.where(magnitude > 0.0, magnitude, 1.0), 0.0)
    cc = np.fft.irfft(weighted, n=n * interp) * interp
    max_shift = min(math.floor(max_delay_s * fs * interp + 1e-9), n * interp // 2)
    # Lags -max_shift..max_shift, in order.
    lags = np.arange(-max_shift, max_shift + 1)
    values = cc[lags % (n * interp)]
    best = int(np.argmax(values))
    return float(lags[best]) / (fs * interp), float(values[best])


def pair_correlations(
    spectra: ComplexArray, freqs_hz: FloatArray, delays_s: FloatArray
) -> FloatArray:
    """GCC-PHAT of each pair at the given delays: (pairs, k) for ``delays_s`` (pairs, k).

    ``spectra`` (n_mics, n_freq, frames) are the STFT frames and bins a detection rests on; the
    cross-spectrum of each pair is summed over the frames, then phase-transformed and
    evaluated at each delay (normalised: 1 when every bin agrees)."""
    i, j = pair_indices(spectra.shape[0])
    cross = np.sum(spectra[i] * np.conj(spectra[j]), axis=2)  # (pairs, n_freq)
    magnitude = np.abs(cross)
    weighted = np.where(magnitude > 0.0, cross / np.where(magnitude > 0.0, magnitude, 1.0), 0.0)
    phase = np.exp(2j * np.pi * freqs_hz[None, None, :] * delays_s[:, :, None])
    cc: FloatArray = np.real(np.sum(weighted[:, None, :] * phase, axis=2)) / max(len(freqs_hz), 1)
    return cc


def bearing_from_delays(mic_xy_m: FloatArray, delays_s: FloatArray, c_mps: float) -> float:
    """Far-field bearing [rad] whose pair delays fit ``delays_s`` (pairs,) best in least squares
    (module docstring)."""
    i, j = pair_indices(mic_xy_m.shape[0])
    a = -(mic_xy_m[i] - mic_xy_m[j]) / c_mps
    u, *_ = np.linalg.lstsq(a, delays_s, rcond=None)
    return float(math.atan2(u[1], u[0]))


def _direction_delays(mic_xy_m: FloatArray, bearing_rad: FloatArray, c_mps: float) -> FloatArray:
    """Far-field pair delays (pairs, k) [s] of sources at ``bearing_rad`` (k,)."""
    i, j = pair_indices(mic_xy_m.shape[0])
    u = np.stack([np.cos(bearing_rad), np.sin(bearing_rad)], axis=0)  # (2, k)
    delays: FloatArray = -((mic_xy_m[i] - mic_xy_m[j]) @ u) / c_mps
    return delays


@dataclass(frozen=True, slots=True)
class Bearing:
    """A direction of arrival: ``bearing_rad`` (robot frame), each pair's delay ``delays_s``
    [s] (order of :func:`pair_indices`, each within its pair's bound), the steered response
    at the grid's best direction, ``power`` in [-1, 1] (1: every pair and bin agree), and
    ``ambiguous``: another direction more than :data:`AMBIGUITY_RAD` away responds within
    :data:`AMBIGUITY_MARGIN` of it (a grating lobe: a tone whose wavelength is shorter than twice
    the array's spacing can reach every pair with the same phases from two directions)."""

    bearing_rad: float
    delays_s: FloatArray
    power: float
    ambiguous: bool


def estimate_bearing(
    spectra: ComplexArray, freqs_hz: FloatArray, mic_xy_m: FloatArray, c_mps: float, step_s: float
) -> Bearing:
    """Bearing of the sound in ``spectra`` (n_mics, n_freq, frames) at ``freqs_hz`` (module
    docstring); pair delays refined on a grid of ``step_s`` [s] within each pair's bound."""
    grid_delays = _direction_delays(mic_xy_m, _GRID, c_mps)
    response = pair_correlations(spectra, freqs_hz, grid_delays).mean(axis=0)
    best = int(np.argmax(response))
    bound = pair_max_delays_s(mic_xy_m, c_mps)
    # Each pair: the correlation's peak within half the shortest period of the predicted delay.
    half_period = 0.5 / float(np.max(freqs_hz))
    offsets = np.arange(-half_period, half_period + step_s / 2, step_s)
    candidates = grid_delays[:, best][:, None] + offsets[None, :]
    candidates = np.clip(candidates, -bound[:, None], bound[:, None])
    cc = pair_correlations(spectra, freqs_hz, candidates)
    delays = candidates[np.arange(candidates.shape[0]), np.argmax(cc, axis=1)]
    apart = np.abs(np.angle(np.exp(1j * (_GRID - _GRID[best])))) > AMBIGUITY_RAD
    rival = float(np.max(response[apart]))
    ambiguous = rival >= float(response[best]) - AMBIGUITY_MARGIN
    return Bearing(
        bearing_from_delays(mic_xy_m, delays, c_mps), delays, float(response[best]), ambiguous
    )
