"""Ground truth per scan: object states, class labels and per-beam owners (SR-SIM-3).

Class labels (:class:`ObjectClass`) are the kinds of object, except that forklifts
(counterbalance and reach trucks alike) carry their *state*, defined here from the motion that
drives them, with the thresholds of :class:`LabelRules`:

* a **reversal** of a motion is a maximal time interval ``[a, b]`` (possibly a single instant)
  on which the signed speed is zero (a speed below :data:`STANDSTILL_MPS`, 1 um/s, counts as
  zero: a knot speed of -1e-283 m/s is rounding, not a change of direction), such that the
  last non-zero speed before ``a`` and the first non-zero speed after ``b`` have opposite
  signs (forward, stop, backward);
* a **stop** is the instant ``a`` at which the speed reaches zero after motion: the start of
  a standstill interval entered from a non-zero speed, or a zero crossing (every reversal
  starts with a stop; so does a plain stop-and-go; a forklift at rest from the start has none);
* ``forklift_near_reversal`` at time ``t``: ``|v(t)| < near_reversal_speed_mps`` and some
  stop ``a`` has ``a - reversal_window_s <= t <= a + reversal_window_s``;
* ``forklift_stationary``: not near reversal and ``|v(t)| < stationary_speed_mps``;
* ``forklift_moving``: otherwise.

The near-reversal speed threshold is the source material's (``|v| < 0.3 m/s``). The label is
*causal* on purpose: whether a stop turns into a reversal is decided by the driver after the
stop, so no observer (and no classifier) can tell a forklift braking for a reversal from one
braking for a stop-and-go, nor the first second at rest of either. Both are near reversal: the
state in which a reversal may come, which the predictor covers with its bimodal stop-or-reverse
envelope and the widest margin tier. (An earlier rule labelled only the stops that did turn
into reversals, which asked the classifier to know the future; see the README.) States are
taken at the scan's stamp (the time of its first beam).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from pipeline.config import SimSection
from pipeline.sources.sim.lidar import BeamTruth
from pipeline.sources.sim.motion import Motion
from pipeline.sources.sim.objects import FORKLIFT_KINDS, ObjectKind
from pipeline.sources.sim.world import World
from pipeline.types import FloatArray, IntArray, frozen_array

STANDSTILL_MPS = 1e-6
"""Speeds below this magnitude [m/s] are standstill when finding reversals."""

__all__ = [
    "CLASS_NAMES",
    "KIND_NAMES",
    "STANDSTILL_MPS",
    "LabelRules",
    "ObjectClass",
    "ScanTruth",
    "forklift_states",
    "object_labels",
    "reversal_intervals",
    "scan_truth",
    "stop_times",
]


class ObjectClass(enum.IntEnum):
    """Class label codes (stable: they are stored in datasets)."""

    FORKLIFT_MOVING = 0
    FORKLIFT_STATIONARY = 1
    FORKLIFT_NEAR_REVERSAL = 2
    PALLET_JACK = 3
    CART = 4
    PERSON = 5
    AMR = 6
    BAGGAGE_TUG = 7
    DOLLY = 8
    ULD_CONTAINER = 9
    STATIC = 10  # static structure (a beam's or a cluster's label, never an object's)


CLASS_NAMES: tuple[str, ...] = tuple(c.name.lower() for c in ObjectClass)
KIND_NAMES: tuple[str, ...] = tuple(k.value for k in ObjectKind)

_KIND_CLASS = {
    ObjectKind.PALLET_JACK: ObjectClass.PALLET_JACK,
    ObjectKind.CART: ObjectClass.CART,
    ObjectKind.PERSON: ObjectClass.PERSON,
    ObjectKind.AMR: ObjectClass.AMR,
    ObjectKind.BAGGAGE_TUG: ObjectClass.BAGGAGE_TUG,
    ObjectKind.DOLLY: ObjectClass.DOLLY,
    ObjectKind.ULD_CONTAINER: ObjectClass.ULD_CONTAINER,
}


@dataclass(frozen=True, slots=True)
class LabelRules:
    """Thresholds of the forklift state labels (m/s, s)."""

    stationary_speed_mps: float = 0.05
    near_reversal_speed_mps: float = 0.3
    reversal_window_s: float = 1.0

    @staticmethod
    def from_config(sim: SimSection) -> LabelRules:
        """The rules configured in the ``sim`` section."""
        return LabelRules(
            stationary_speed_mps=sim.label_stationary_speed_mps,
            near_reversal_speed_mps=sim.label_near_reversal_speed_mps,
            reversal_window_s=sim.label_reversal_window_s,
        )


def reversal_intervals(motion: Motion) -> FloatArray:
    """The reversals of ``motion`` as ``(J, 2)`` rows ``[a, b]`` (see the module docstring).

    Exact for the piecewise-linear speed: zero sets are runs of zero-speed knots or single
    crossings inside a knot segment.
    """
    kt = motion.knot_t_s
    kv = np.where(np.abs(motion.knot_v_mps) < STANDSTILL_MPS, 0.0, motion.knot_v_mps)
    n = kt.size
    rows: list[tuple[float, float]] = []
    k = 0
    while k < n:
        if kv[k] == 0.0:
            m = k  # a run of zero knots k..m: the speed is zero on [kt[k], kt[m]]
            while m + 1 < n and kv[m + 1] == 0.0:
                m += 1
            before = np.sign(kv[k - 1]) if k > 0 else 0.0
            after = np.sign(kv[m + 1]) if m + 1 < n else 0.0
            if before * after < 0:
                rows.append((float(kt[k]), float(kt[m])))
            k = m + 1
            continue
        if k + 1 < n and kv[k] * kv[k + 1] < 0:  # a strict crossing inside the segment
            tc = kt[k] + kv[k] / (kv[k] - kv[k + 1]) * (kt[k + 1] - kt[k])
            rows.append((float(tc), float(tc)))
        k += 1
    return np.array(rows, dtype=np.float64).reshape(-1, 2)


def stop_times(motion: Motion) -> FloatArray:
    """The stops of ``motion`` (module docstring), ascending [s].

    Exact for the piecewise-linear speed: a stop is a zero knot after a non-zero one, or a
    strict sign change inside a knot segment.
    """
    kt = motion.knot_t_s
    kv = np.where(np.abs(motion.knot_v_mps) < STANDSTILL_MPS, 0.0, motion.knot_v_mps)
    entry = np.flatnonzero((kv[1:] == 0.0) & (kv[:-1] != 0.0)) + 1
    cross = np.flatnonzero(kv[:-1] * kv[1:] < 0)
    tc = kt[cross] + kv[cross] / (kv[cross] - kv[cross + 1]) * (kt[cross + 1] - kt[cross])
    out: FloatArray = np.sort(np.concatenate([kt[entry], tc]).astype(np.float64))
    return out


def forklift_states(motion: Motion, t_s: FloatArray, rules: LabelRules) -> IntArray:
    """Forklift state codes at times ``t_s`` from the motion (module docstring rules)."""
    t = np.asarray(t_s, dtype=np.float64)
    speed = np.abs(motion.speed_at(t))
    stops = stop_times(motion)
    w = rules.reversal_window_s
    in_window = (np.abs(t[:, None] - stops[None, :]) <= w).any(axis=1)
    near = in_window & (speed < rules.near_reversal_speed_mps)
    still = ~near & (speed < rules.stationary_speed_mps)
    out = np.full(t.shape, int(ObjectClass.FORKLIFT_MOVING), dtype=np.int64)
    out[still] = int(ObjectClass.FORKLIFT_STATIONARY)
    out[near] = int(ObjectClass.FORKLIFT_NEAR_REVERSAL)
    return out


def object_labels(world: World, t_s: float, rules: LabelRules) -> IntArray:
    """Class label code of every object of ``world`` at ``t_s``, ``(N,)``."""
    out = np.empty(len(world.objects), dtype=np.int64)
    for i, obj in enumerate(world.objects):
        kind = obj.model.kind
        if kind in FORKLIFT_KINDS:
            if obj.motion is None:
                raise ValueError(f"{obj.name}: a forklift needs its motion to be labelled")
            out[i] = forklift_states(obj.motion, np.array([t_s]), rules)[0]
        else:
            out[i] = int(_KIND_CLASS[kind])
    return out


@dataclass(frozen=True, slots=True)
class ScanTruth:
    """Everything true about one scan. Object arrays have one row per object of the world
    (in :attr:`World.objects` order), in the world frame, at ``stamp_s``; ``kind`` indexes
    :data:`KIND_NAMES`, ``label`` :data:`CLASS_NAMES`. ``n_returns`` counts the beams with a
    finite range whose first hit was that object. Poses are ``(x_m, y_m, yaw_rad)``."""

    stamp_s: float
    seq: int
    scanner_pose: FloatArray
    ego_pose: FloatArray
    ego_speed_mps: float
    object_id: IntArray
    kind: IntArray
    label: IntArray
    x_m: FloatArray
    y_m: FloatArray
    heading_rad: FloatArray
    speed_mps: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    accel_mps2: FloatArray
    length_m: FloatArray
    width_m: FloatArray
    n_returns: IntArray
    beams: BeamTruth

    def __post_init__(self) -> None:
        for name in self.__slots__:
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                object.__setattr__(self, name, frozen_array(value, value.dtype.type))


def scan_truth(
    world: World,
    beams: BeamTruth,
    ranges_m: FloatArray,
    *,
    stamp_s: float,
    seq: int,
    scanner_pose: FloatArray,
    ego_pose: FloatArray,
    ego_speed_mps: float,
    rules: LabelRules,
) -> ScanTruth:
    """Assemble the :class:`ScanTruth` of one scan."""
    n = len(world.objects)
    cols = {
        k: np.empty(n)
        for k in ("x_m", "y_m", "heading_rad", "speed_mps", "vx_mps", "vy_mps", "accel_mps2")
    }
    t = np.array([stamp_s])
    for i, obj in enumerate(world.objects):
        st = obj.trajectory.at(t)
        for k in cols:
            cols[k][i] = st[k][0]
    ids = world.object_ids
    returned = np.isfinite(ranges_m)
    owners = beams.owner_id[returned]
    n_returns = (owners[None, :] == ids[:, None]).sum(axis=1)
    return ScanTruth(
        stamp_s=stamp_s,
        seq=seq,
        scanner_pose=np.asarray(scanner_pose, dtype=np.float64),
        ego_pose=np.asarray(ego_pose, dtype=np.float64),
        ego_speed_mps=float(ego_speed_mps),
        object_id=ids,
        kind=np.array(
            [KIND_NAMES.index(o.model.kind.value) for o in world.objects], dtype=np.int64
        ),
        label=object_labels(world, stamp_s, rules),
        length_m=np.array([o.model.length_m for o in world.objects]),
        width_m=np.array([o.model.width_m for o in world.objects]),
        n_returns=n_returns.astype(np.int64),
        beams=beams,
        **cols,
    )
