"""Joint probabilistic data association where gates overlap, the Hungarian cascade elsewhere
(SR-TRK-8).

Tracks that share gated detections form a *cluster* (a connected component of the gating
graph over the first priority group, confirmed and lost tracks). A cluster of one track is
assigned by today's cascade (:func:`pipeline.track.associate.cascade`). In a cluster of two or
more, JPDA (Bar-Shalom, Daum and Huang 2009; the form of Stone Soup's ``JPDA`` with its
``PDAHypothesiser``) enumerates every joint event (each track takes one of its gated
detections or none, no detection taken twice) and weighs it by the product over its tracks of

* ``1 - Pd Pg`` for a track that missed (``Pd`` = ``track.jpda_detection_prob``, ``Pg`` =
  ``1 - exp(-chi2 / 2)``, the probability that the 2-D Mahalanobis gate holds the target);
* ``Pd N(z; z_hat, S) / lambda`` for a track that took detection ``z``, with ``lambda`` the
  clutter density.

The association probabilities ``beta`` are the normalised sums over the events; each track of
the cluster is updated with all its gated detections at once (:func:`pda_update`: the combined
innovation, and the covariance with the spread-of-innovations term). ``lambda`` is learned: an
exponential average (gain ``track.jpda_clutter_smoothing``) of the number of detections outside
every gate per cycle over ``track.jpda_surveillance_area_m2``, floored at
``track.jpda_clutter_density_min_per_m2``.

Bounded work: a cluster's joint events are at most ``prod(1 + m_i)`` (``m_i`` gated detections of
track ``i``); a cluster whose bound exceeds ``track.jpda_max_hypotheses`` is not enumerated but
assigned by the cascade, and counted (:class:`JpdaCounts`). For the lifecycle and the
histories, a JPDA track's detection is the one of the most probable joint event, so that
bookkeeping stays one-to-one; its other gated detections stay free for tentative tracks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pipeline.config import TrackSection
from pipeline.track.associate import cascade
from pipeline.track.kalman import innovation, update
from pipeline.types import BoolArray, FloatArray, IntArray, SoftAssociation

__all__ = [
    "JpdaAssociator",
    "JpdaCounts",
    "SoftAssociation",  # re-exported from pipeline.types
    "joint_betas",
    "pda_update",
    "track_clusters",
]


@dataclass(frozen=True, slots=True)
class JpdaCounts:
    """What one cycle's association did: clusters of two or more tracks, how many were
    enumerated and how many fell back to the cascade (bound over the cap), the largest
    bound on joint events met, and the clutter density used [1/m^2]."""

    n_clusters: int
    n_jpda: int
    n_fallback: int
    max_hypotheses: int
    clutter_density_per_m2: float


def track_clusters(feasible: BoolArray, rows: BoolArray) -> tuple[IntArray, IntArray]:
    """Connected components of the gating graph: a label per track (-1 outside ``rows`` or
    gating nothing) and per detection (-1 gated by none of ``rows``)."""
    t, d = feasible.shape
    graph = feasible & rows[:, None]
    r, c = np.nonzero(graph)
    adjacency = coo_matrix((np.ones(r.shape[0]), (r, t + c)), shape=(t + d, t + d))
    _, labels = connected_components(adjacency, directed=False)
    linked = np.concatenate([graph.any(axis=1), graph.any(axis=0)])
    labels = np.where(linked, labels, -1)
    return labels[:t].astype(np.int64), labels[t:].astype(np.int64)


def joint_betas(log_weight: FloatArray) -> tuple[FloatArray, IntArray, int]:
    """Association probabilities of one cluster by enumeration of its joint events.

    ``log_weight`` (k tracks, d + 1): column 0 the log weight of a missed detection, column
    ``j + 1`` that of detection ``j`` (``-inf`` outside the gate). Returns ``beta`` (k, d + 1)
    (rows sum to 1), the most probable joint event (detection per track, -1 missed) and the
    number of valid joint events.
    """
    k = log_weight.shape[0]
    options = [np.flatnonzero(np.isfinite(log_weight[i])) for i in range(k)]
    grids = np.meshgrid(*options, indexing="ij")
    choice = np.stack([g.reshape(-1) for g in grids], axis=1)  # (events, k) columns
    taken = np.where(choice > 0, choice, -np.arange(1, k + 1)[None, :])
    ordered = np.sort(taken, axis=1)
    valid = np.all(ordered[:, 1:] != ordered[:, :-1], axis=1)
    choice = choice[valid]
    total = log_weight[np.arange(k)[None, :], choice].sum(axis=1)
    w = np.exp(total - total.max())
    w /= w.sum()
    cols = log_weight.shape[1]
    flat = (np.arange(k)[None, :] * cols + choice).reshape(-1)
    beta = np.bincount(flat, weights=np.repeat(w, k), minlength=k * cols).astype(np.float64)
    beta = beta.reshape(k, cols)
    best = choice[int(np.argmax(w))] - 1
    return beta, best.astype(np.int64), int(choice.shape[0])


def pda_update(
    x: FloatArray,
    p: FloatArray,
    z_m: FloatArray,
    beta: FloatArray,
    measurement_std_m: float,
    cap_growth: bool = True,
) -> tuple[FloatArray, FloatArray, BoolArray]:
    """Beta-weighted update of states ``x`` (n, 4) and covariances ``p`` with every detection
    ``z_m`` (d, 2) at once (``beta`` (n, d + 1) as in :class:`SoftAssociation`).

    ``x' = x + K nu`` with ``nu = sum_j beta_j nu_j``; ``P' = beta_0 P + (1 - beta_0) P_c +
    K (sum_j beta_j nu_j nu_j' - nu nu') K'``, ``P_c`` the Kalman posterior (Joseph form,
    :func:`pipeline.track.kalman.update`). The spread term can make ``P'`` larger than ``P``;
    with ``cap_growth`` it is scaled down where needed so that ``trace P' <= trace P`` (an
    update never leaves a track less certain than its prediction). Both terms are positive
    semi-definite and the result is symmetrized, so ``P'`` stays symmetric positive definite.
    Returns the states, the covariances and where the cap acted.
    """
    _, s_inv = innovation(p, measurement_std_m)
    k = np.matmul(p[:, :, :2], s_inv)
    nu_j = z_m[None, :, :] - x[:, None, :2]  # (n, d, 2)
    b = beta[:, 1:]
    nu = np.einsum("nd,ndi->ni", b, nu_j)
    x_new = x + np.einsum("nij,nj->ni", k, nu)
    spread = np.einsum("nd,ndi,ndj->nij", b, nu_j, nu_j) - nu[:, :, None] * nu[:, None, :]
    p_tilde = np.matmul(np.matmul(k, spread), np.swapaxes(k, 1, 2))
    _, p_c = update(x, p, x[:, :2], measurement_std_m)
    b0 = beta[:, :1, None]
    base = b0 * p + (1.0 - b0) * p_c
    scale = np.ones(x.shape[0])
    capped = np.zeros(x.shape[0], dtype=bool)
    if cap_growth:
        room = np.trace(p, axis1=1, axis2=2) - np.trace(base, axis1=1, axis2=2)
        grow = np.trace(p_tilde, axis1=1, axis2=2)
        capped = grow > np.maximum(room, 0.0)
        scale = np.where(capped, np.maximum(room, 0.0) / np.where(capped, grow, 1.0), 1.0)
    p_new = base + scale[:, None, None] * p_tilde
    return x_new, 0.5 * (p_new + np.swapaxes(p_new, 1, 2)), capped


class JpdaAssociator:
    """The association role's JPDA component (module docstring), configured by ``track``."""

    def __init__(self, config: TrackSection) -> None:
        self.config = config
        self.p_gate = 1.0 - math.exp(-0.5 * config.gate_mahalanobis_chi2)
        self._clutter: float | None = None
        self.last: JpdaCounts | None = None

    def reset(self) -> None:
        """Forget the learned clutter density."""
        self._clutter = None
        self.last = None

    def associate(
        self, cost: FloatArray, groups: Sequence[BoolArray]
    ) -> tuple[IntArray, BoolArray]:
        """The hard association role (the cascade), for callers that cannot take weights."""
        return cascade(cost, groups)

    def clutter_density(self, cost: FloatArray) -> float:
        """Update the clutter estimate with this cycle's detections outside every gate."""
        c = self.config
        outside = float(np.count_nonzero(~np.isfinite(cost).any(axis=0)))
        a = c.jpda_clutter_smoothing
        self._clutter = outside if self._clutter is None else (1 - a) * self._clutter + a * outside
        return max(self._clutter / c.jpda_surveillance_area_m2, c.jpda_clutter_density_min_per_m2)

    def associate_soft(
        self, cost: FloatArray, groups: Sequence[BoolArray], log_norm: FloatArray
    ) -> SoftAssociation:
        """Association of one cycle. ``cost`` (tracks, detections): gated Mahalanobis d^2
        (``inf`` outside the gates); ``groups`` the cascade's priority masks (JPDA within the
        first); ``log_norm`` (tracks,): ``-log(2 pi sqrt(det S))`` of each track."""
        c = self.config
        t, d = cost.shape
        feasible = np.isfinite(cost)
        density = self.clutter_density(cost)
        miss = math.log(max(1.0 - c.jpda_detection_prob * self.p_gate, 1e-300))
        hit = math.log(c.jpda_detection_prob) - math.log(density)
        log_w = np.full((t, d + 1), -np.inf)
        log_w[:, 0] = miss
        log_w[:, 1:] = np.where(feasible, hit + log_norm[:, None] - 0.5 * cost, -np.inf)
        first = groups[0] if groups else np.zeros(t, dtype=bool)
        label, _ = track_clusters(feasible, first)
        beta = np.zeros((t, d + 1))
        pda = np.zeros(t, dtype=bool)
        chosen = np.full(t, -1, dtype=np.int64)
        n_clusters = n_fallback = worst = 0
        members = np.bincount(label[label >= 0]) if (label >= 0).any() else np.zeros(0, int)
        for cluster in np.flatnonzero(members >= 2):
            rows = np.flatnonzero(label == cluster)
            n_clusters += 1
            bound = int(np.prod(feasible[rows].sum(axis=1) + 1, dtype=np.float64).clip(max=2**62))
            worst = max(worst, bound)
            if bound > c.jpda_max_hypotheses:
                n_fallback += 1
                continue
            beta[rows], chosen[rows], _ = joint_betas(log_w[rows])
            pda[rows] = True
        consumed = np.zeros(d, dtype=bool)
        consumed[chosen[chosen >= 0]] = True
        match, free = cascade(cost, [first & ~pda, *groups[1:]], ~consumed)
        match[pda] = chosen[pda]
        self.last = JpdaCounts(n_clusters, n_clusters - n_fallback, n_fallback, worst, density)
        return SoftAssociation(match, free, pda, beta)
