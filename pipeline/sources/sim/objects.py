"""Object models: what a 2D LiDAR in the scan plane sees of each kind of moving object.

Every model is an :class:`~pipeline.sources.sim.shapes.Outline` in its body frame: x forward (the
direction of travel at positive speed), y to the left, origin at the centre of the outline's
bounding box. The outline is the cut of the object at the scan plane of a typical AMR safety
scanner, about 0.15-0.25 m above the floor; that is why a pallet jack shows its two fork tines
and steer unit, a person two shins, a dolly its wheels and tow bar.

Dimensions are typical published spec-sheet figures for the class, rounded, each cited where it
is defined; none is a particular product unless named. Serves SR-SIM-1 (geometry that the ray
caster and its shapely oracle both see) and SR-SIM-3 (footprints for the no-overlap check).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, replace

import numpy as np

from pipeline.sources.sim.shapes import Outline, chamfered_rectangle, rectangle, regular_polygon
from pipeline.types import FloatArray

__all__ = [
    "DOLLY_DRAWBAR_M",
    "DOLLY_FRONT_AXLE_X_M",
    "DOLLY_REAR_AXLE_X_M",
    "DOLLY_REAR_HITCH_M",
    "DOLLY_WHEELBASE_M",
    "FORKLIFT_KINDS",
    "TUG_HITCH_X_M",
    "Gait",
    "ObjectKind",
    "ObjectModel",
    "amr",
    "baggage_tug",
    "cart",
    "counterbalance_forklift",
    "dolly",
    "model_for",
    "pallet_jack",
    "person",
    "reach_truck",
    "uld_container",
]


class ObjectKind(enum.Enum):
    """The physical kind of a simulated object (its model), not its class label."""

    COUNTERBALANCE_FORKLIFT = "counterbalance_forklift"
    REACH_TRUCK = "reach_truck"
    PALLET_JACK = "pallet_jack"
    CART = "cart"
    PERSON = "person"
    AMR = "amr"
    BAGGAGE_TUG = "baggage_tug"
    DOLLY = "dolly"
    ULD_CONTAINER = "uld_container"


FORKLIFT_KINDS = frozenset({ObjectKind.COUNTERBALANCE_FORKLIFT, ObjectKind.REACH_TRUCK})

_LEG_SIDES = 10  # a shin is drawn as a 10-gon


@dataclass(frozen=True, slots=True)
class Gait:
    """Two shins seen at the scan plane, swinging fore and aft while the person walks.

    Shin diameter ~0.11 m and step width ~0.2 m between the legs' centres are anthropometric
    and gait-lab typical values; a walking step is ~0.65 m (cadence ~110 steps/min at
    1.2 m/s, the usual self-selected walking speed). At shin height the legs swing through
    ``swing_fraction`` of the step length. The swing amplitude grows with speed up to
    ``full_swing_speed_mps`` and is zero when standing.
    """

    leg_radius_m: float = 0.055
    step_width_m: float = 0.20
    step_length_m: float = 0.65
    swing_fraction: float = 0.6
    full_swing_speed_mps: float = 1.0

    def leg_centres(self, arc_m: FloatArray, speed_mps: FloatArray) -> FloatArray:
        """Centres of the (left, right) shins in the body frame, ``(T, 2, 2)``.

        ``arc_m`` is the distance walked so far (drives the gait phase), ``speed_mps`` the
        current speed (drives the swing amplitude).
        """
        phase = np.pi * arc_m / self.step_length_m  # one step = half a gait cycle
        amp = (
            0.5
            * self.swing_fraction
            * self.step_length_m
            * np.clip(np.abs(speed_mps) / self.full_swing_speed_mps, 0.0, 1.0)
        )
        fore = amp * np.sin(phase)
        out = np.empty((*arc_m.shape, 2, 2))
        out[..., 0, 0] = fore
        out[..., 0, 1] = self.step_width_m / 2
        out[..., 1, 0] = -fore
        out[..., 1, 1] = -self.step_width_m / 2
        return out


@dataclass(frozen=True, slots=True)
class ObjectModel:
    """One kind of object: its outline at the scan plane and nominal bounding box (metres).

    ``length_m`` / ``width_m`` are the nominal bounding-box dimensions of the outline (x / y
    extent), the figures recorded as ground truth. ``gait`` is set only for people; their
    outline then moves with the gait phase.
    """

    kind: ObjectKind
    outline: Outline
    length_m: float
    width_m: float
    reflectivity: float = 0.5
    gait: Gait | None = None
    articulated_part: int | None = None
    articulation_pivot_x_m: float = 0.0

    def body_vertices(
        self, arc_m: FloatArray, speed_mps: FloatArray, articulation_rad: FloatArray
    ) -> FloatArray:
        """Body-frame vertices at ``T`` instants, ``(T, V, 2)``.

        ``arc_m`` (distance travelled) and ``speed_mps`` drive a person's gait;
        ``articulation_rad`` turns the articulated part (a dolly's drawbar) about its pivot.
        """
        base = self.outline.vertices_m
        if self.articulated_part is not None:
            s = self.outline.part_starts
            lo, hi = int(s[self.articulated_part]), int(s[self.articulated_part + 1])
            out = np.repeat(base[None, :, :], arc_m.shape[0], axis=0)
            rel_x = base[lo:hi, 0] - self.articulation_pivot_x_m
            rel_y = base[lo:hi, 1]
            c = np.cos(articulation_rad)[:, None]
            sn = np.sin(articulation_rad)[:, None]
            out[:, lo:hi, 0] = self.articulation_pivot_x_m + c * rel_x - sn * rel_y
            out[:, lo:hi, 1] = sn * rel_x + c * rel_y
            return out
        if self.gait is None:
            return np.broadcast_to(base, arc_m.shape + base.shape)
        centres = self.gait.leg_centres(arc_m, speed_mps)  # (T, 2, 2)
        # The outline's two parts are the shin polygons around the origin, in order.
        per_vertex = np.repeat(centres, _LEG_SIDES, axis=-2)  # (T, 2*_LEG_SIDES, 2)
        return base[None, :, :] + per_vertex


def _centred(kind: ObjectKind, parts: list[FloatArray], reflectivity: float) -> ObjectModel:
    """Shift parts so the bounding box is centred on the origin; record its dimensions."""
    allv = np.concatenate(parts, axis=0)
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    centre = (lo + hi) / 2
    outline = Outline.from_parts([p - centre for p in parts])
    return ObjectModel(
        kind=kind,
        outline=outline,
        length_m=float(hi[0] - lo[0]),
        width_m=float(hi[1] - lo[1]),
        reflectivity=reflectivity,
    )


def counterbalance_forklift() -> ObjectModel:
    """A 2.5 t electric counterbalance forklift, forks leading (x forward = fork side).

    Typical VDI 2198 spec-sheet figures of the 2.5 t class (e.g. the published sheets of the
    Linde E25, Toyota 8FBE25 and Jungheinrich EFG 425 trucks are all within a few cm of
    these): overall width b1 ~1.15 m, length to fork face l2 ~2.30 m, fork arms 1150 mm long
    (ISO 2331 lengths run 800-2400 mm) with a 100 mm x 40 mm section, fork spread ~0.6 m
    outside. The counterweight's rear corners are rounded (here chamfered 0.3 m); the mast
    (~0.9 m wide, ~0.25 m deep at floor level) is narrower than the body, so the outline seen
    by a LiDAR is irregular: body, a step in at the mast, then two thin tines.
    """
    body = chamfered_rectangle(0.0, 2.05, -0.575, 0.575, rear_chamfer_m=0.30)
    mast = rectangle(2.04, 2.30, -0.45, 0.45)
    left = rectangle(2.29, 3.45, 0.20, 0.30)
    right = rectangle(2.29, 3.45, -0.30, -0.20)
    return _centred(ObjectKind.COUNTERBALANCE_FORKLIFT, [body, mast, left, right], 0.55)


def reach_truck() -> ObjectModel:
    """A 1.4-1.6 t stand-on reach truck in travel position (mast retracted), forks leading.

    Typical spec-sheet figures of the class (Toyota BT Reflex, Crown ESR, Jungheinrich ETV 214
    sheets): chassis width ~1.20 m, chassis length ~1.35 m, two outrigger base legs ~1.1 m long
    running forward along the outer edges, mast ~0.8 m wide between them, 1150 mm forks
    reaching just past the leg tips. Works in 2.7-3.0 m aisles.
    """
    chassis = chamfered_rectangle(0.0, 1.35, -0.60, 0.60, rear_chamfer_m=0.25)
    leg_left = rectangle(1.34, 2.45, 0.42, 0.56)
    leg_right = rectangle(1.34, 2.45, -0.56, -0.42)
    mast = rectangle(1.34, 1.60, -0.40, 0.40)
    tine_left = rectangle(1.59, 2.74, 0.20, 0.30)
    tine_right = rectangle(1.59, 2.74, -0.30, -0.20)
    parts = [chassis, leg_left, leg_right, mast, tine_left, tine_right]
    return _centred(ObjectKind.REACH_TRUCK, parts, 0.55)


def pallet_jack(*, loaded: bool = False) -> ObjectModel:
    """A manual hand pallet truck, pulled handle first (x forward = steer unit side).

    Standard hand pallet truck: fork arms 1150 mm long, 540 mm over the forks with ~160 mm
    wide arms (the size recommended for Euro pallets in suppliers' buying guides), a steer /
    pump unit ~0.40 m long. The forks are assumed raised to travel height, in the scan plane.
    ``loaded`` adds a 1200 x 800 mm Euro pallet (EN 13698-1) riding on the forks.
    """
    steer = chamfered_rectangle(1.15, 1.55, -0.20, 0.20, front_chamfer_m=0.08)
    tine_left = rectangle(0.0, 1.16, 0.11, 0.27)
    tine_right = rectangle(0.0, 1.16, -0.27, -0.11)
    parts = [steer, tine_left, tine_right]
    if loaded:
        parts.append(rectangle(-0.05, 1.15, -0.40, 0.40))
    return _centred(ObjectKind.PALLET_JACK, parts, 0.45)


def cart() -> ObjectModel:
    """A platform trolley: 1000 x 600 mm deck (the common workshop size in suppliers'
    catalogues), deck edge at the scan plane, push handle posts at the rear corners."""
    deck = rectangle(0.0, 1.00, -0.30, 0.30)
    post_left = rectangle(-0.04, 0.02, 0.24, 0.30)
    post_right = rectangle(-0.04, 0.02, -0.30, -0.24)
    return _centred(ObjectKind.CART, [deck, post_left, post_right], 0.5)


def person(gait: Gait | None = None) -> ObjectModel:
    """A person as a LiDAR at shin height sees them: two shins (see :class:`Gait`)."""
    g = gait or Gait()
    left = regular_polygon(g.leg_radius_m, _LEG_SIDES)
    right = regular_polygon(g.leg_radius_m, _LEG_SIDES)
    outline = Outline.from_parts([left, right])
    swing = 0.5 * g.swing_fraction * g.step_length_m
    return ObjectModel(
        kind=ObjectKind.PERSON,
        outline=outline,
        length_m=2 * (swing + g.leg_radius_m),
        width_m=g.step_width_m + 2 * g.leg_radius_m,
        reflectivity=0.3,
        gait=g,
    )


def amr() -> ObjectModel:
    """Another mobile robot: the Neobotix MP-500 platform, 823 mm long and 592 mm wide
    (Neobotix MP-500 mechanical documentation), corners chamfered 0.05 m."""
    body = chamfered_rectangle(0.0, 0.823, -0.296, 0.296, rear_chamfer_m=0.05, front_chamfer_m=0.05)
    return _centred(ObjectKind.AMR, [body], 0.6)


def baggage_tug() -> ObjectModel:
    """An airport baggage tractor of the 2-3 t drawbar-pull class.

    Published overall dimensions of such tractors cluster around 2.7-3.2 m long and 1.2-1.5 m
    wide; the mid-range 2.90 x 1.35 m is used, front corners chamfered 0.2 m, with the tow
    hitch 0.25 m behind the rear face (see :mod:`pipeline.sources.sim.motion` for the train).
    """
    body = chamfered_rectangle(0.0, 2.90, -0.675, 0.675, front_chamfer_m=0.20)
    return _centred(ObjectKind.BAGGAGE_TUG, [body], 0.6)


DOLLY_WHEELBASE_M = 1.50
DOLLY_DRAWBAR_M = 1.20
DOLLY_REAR_HITCH_M = 0.45  # behind the rear axle
_DOLLY_CENTRE_X = (-0.20 + DOLLY_WHEELBASE_M + DOLLY_DRAWBAR_M) / 2
DOLLY_REAR_AXLE_X_M = -_DOLLY_CENTRE_X  # rear axle in the dolly's body frame
DOLLY_FRONT_AXLE_X_M = DOLLY_WHEELBASE_M - _DOLLY_CENTRE_X
TUG_HITCH_X_M = -1.45 - 0.25  # tow hitch in the tug's body frame (0.25 m behind the rear)


def dolly() -> ObjectModel:
    """A ULD container dolly (for LD3 containers) seen at the scan plane: four wheels and the
    drawbar; its deck (~0.5 m high) and any container on it are above the scan plane.

    Deck and track sized to carry an LD3 (base 156.2 x 153.4 cm, IATA standard container
    table): axles 1.50 m apart, wheels (0.40 m diameter, 0.15 m wide) on a 1.45 m track, a
    1.20 m drawbar from the front axle (on a turntable) to the tow eye. The drawbar is the
    articulated part: it turns about the front axle by the trajectory's articulation angle.
    """
    half_track = 0.725
    parts = []
    for x in (0.0, DOLLY_WHEELBASE_M):
        for side in (1.0, -1.0):
            inner, outer = side * (half_track - 0.15), side * half_track
            parts.append(rectangle(x - 0.20, x + 0.20, min(inner, outer), max(inner, outer)))
    parts.append(rectangle(DOLLY_WHEELBASE_M, DOLLY_WHEELBASE_M + DOLLY_DRAWBAR_M, -0.03, 0.03))
    model = _centred(ObjectKind.DOLLY, parts, 0.5)
    return replace(model, articulated_part=4, articulation_pivot_x_m=DOLLY_FRONT_AXLE_X_M)


def uld_container() -> ObjectModel:
    """An LD3 unit load device resting on the ground: base 156.2 x 153.4 cm (IATA standard
    container dimensions table; the upper contour's overhang is above the scan plane)."""
    base = rectangle(0.0, 1.562, -0.767, 0.767)
    return _centred(ObjectKind.ULD_CONTAINER, [base], 0.7)


def model_for(kind: ObjectKind) -> ObjectModel:
    """The default model of ``kind``."""
    factories = {
        ObjectKind.COUNTERBALANCE_FORKLIFT: counterbalance_forklift,
        ObjectKind.REACH_TRUCK: reach_truck,
        ObjectKind.PALLET_JACK: pallet_jack,
        ObjectKind.CART: cart,
        ObjectKind.PERSON: person,
        ObjectKind.AMR: amr,
        ObjectKind.BAGGAGE_TUG: baggage_tug,
        ObjectKind.DOLLY: dolly,
        ObjectKind.ULD_CONTAINER: uld_container,
    }
    return factories[kind]()
