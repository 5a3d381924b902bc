"""Synthetic scenes with exact ground truth, rendered by the C++ core's ray caster.

Coordinates: the gravity-aligned frame on the floor right under the sensor (x forward, y left, z up), metres.
A box is ``(x0, x1, y0, y1, z0, z1)``; a hole is a floor footprint ``(x0, x1, y0, y1)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import _core

Box = tuple[float, float, float, float, float, float]
Hole = tuple[float, float, float, float]

#: Object ids in ``Frame.truth["object"]``.
NOTHING, FLOOR, CEILING, HOLE, FIRST_BOX = -1, 0, 1, 2, 10


@dataclass(frozen=True)
class Scene:
    """Boxes, floor holes and an optional real ceiling (0 = none)."""

    boxes: tuple[Box, ...] = ()
    holes: tuple[Hole, ...] = ()
    hole_depth: float = 0.5
    ceiling: float = 0.0
    names: tuple[str, ...] = ()


def lab_scene() -> Scene:
    """A MARVIN-like lab: side bench with stools, a desk (an overhang), a person, low clutter of 3, 5, 10 and
    30 cm, a lamp hanging just below the 2 m ceiling plane and a duct just above it, walls, a 2.8 m ceiling."""
    boxes: list[tuple[str, Box]] = [
        ("side bench", (1.6, 4.5, 1.2, 1.9, 0.85, 0.9)),
        ("bench cabinet", (1.6, 4.5, 1.6, 1.9, 0.0, 0.85)),
        ("stool 1", (2.0, 2.35, 0.9, 1.25, 0.0, 0.6)),
        ("stool 2", (3.0, 3.35, 0.9, 1.25, 0.0, 0.6)),
        ("desk top", (3.2, 4.0, -1.0, 0.2, 0.72, 0.76)),
        ("desk leg", (3.85, 3.95, -1.0, -0.9, 0.0, 0.72)),
        ("person", (2.4, 2.7, -0.6, -0.2, 0.0, 1.75)),
        ("clutter 3 cm", (1.3, 1.5, -0.5, -0.3, 0.0, 0.03)),
        ("clutter 5 cm", (1.8, 2.0, 0.1, 0.3, 0.0, 0.05)),
        ("clutter 10 cm", (2.0, 2.2, -1.4, -1.2, 0.0, 0.10)),
        ("clutter 30 cm", (1.4, 1.6, 0.4, 0.6, 0.0, 0.30)),
        ("hanging lamp", (2.8, 3.1, -0.1, 0.2, 1.90, 1.97)),
        ("duct above", (1.5, 4.0, -0.5, -0.2, 2.10, 2.30)),
        ("far wall", (5.5, 5.7, -4.0, 4.0, 0.0, 2.8)),
        ("left wall", (0.0, 5.5, 2.6, 2.8, 0.0, 2.8)),
        ("right wall", (0.0, 5.5, -3.2, -3.0, 0.0, 2.8)),
    ]
    return Scene(
        boxes=tuple(b for _, b in boxes),
        names=tuple(n for n, _ in boxes),
        ceiling=2.8,
    )


def boxes_scene() -> Scene:
    """A floor with a few boxes (no ceiling, no walls): the simplest scene with exact answers."""
    return Scene(
        boxes=(
            (1.5, 1.9, -0.5, 0.0, 0.0, 0.40),
            (2.2, 2.6, 0.3, 0.8, 0.0, 0.25),
            (3.0, 3.3, -1.2, -0.8, 0.0, 1.20),
            (2.0, 2.2, -0.1, 0.1, 0.0, 0.05),
        ),
        names=("box 40 cm", "box 25 cm", "box 1.2 m", "box 5 cm"),
    )


def stair_scene(edge: float = 2.5, step: float = 0.17) -> Scene:
    """A stair down (or a loading dock edge): the floor ends ``edge`` metres ahead across the whole view and the
    next level is ``step`` metres lower; a box on the upper level as something the scan must still see."""
    return Scene(
        boxes=((1.6, 1.9, 0.5, 0.8, 0.0, 0.4),),
        holes=((edge, 30.0, -30.0, 30.0),),
        hole_depth=step,
        names=("box 40 cm",),
    )


def hole_scene() -> Scene:
    """A 60 x 80 cm hole in the floor 2 m ahead, slightly to the left, 50 cm deep, beside a 30 cm box."""
    return Scene(
        boxes=((1.8, 2.0, -0.9, -0.6, 0.0, 0.3),),
        holes=((2.0, 2.6, -0.2, 0.6),),
        hole_depth=0.5,
        names=("box 30 cm",),
    )


def person(x: float, y: float) -> tuple[Box, ...]:
    """A standing person as boxes: two feet, two legs 20 cm apart, a torso with arms; ``(x, y)`` the point between
    the feet [m]."""
    out: list[Box] = []
    for side in (-0.1, 0.1):
        out.append((x - 0.06, x + 0.2, y + side - 0.05, y + side + 0.05, 0.0, 0.08))  # foot
        out.append((x - 0.06, x + 0.06, y + side - 0.06, y + side + 0.06, 0.0, 0.85))  # leg
    out.append((x - 0.12, x + 0.12, y - 0.25, y + 0.25, 0.85, 1.45))  # torso and arms
    out.append((x - 0.1, x + 0.1, y - 0.1, y + 0.1, 1.45, 1.72))  # head and neck
    return tuple(out)


def people_scene(seed: int = 0, count: int = 6, near: float = 1.2, far: float = 2.0, spacing: float = 0.55) -> Scene:
    """``count`` people standing ``near``..``far`` metres ahead across the view (seeded), and a far wall: the legs'
    lowest pixels and the feet stand in the floor band, and little floor shows between them."""
    rng = np.random.default_rng(seed)
    boxes: list[Box] = []
    names: list[str] = []
    for i in range(count):
        x = float(rng.uniform(near, far))
        y = float((i - (count - 1) / 2) * spacing + rng.uniform(-0.1, 0.1))
        part = person(x, y)
        boxes += part
        names += [f"person {i + 1}"] * len(part)
    boxes.append((6.0, 6.2, -5.0, 5.0, 0.0, 2.8))
    names.append("far wall")
    return Scene(boxes=tuple(boxes), names=tuple(names), ceiling=2.8)


def furniture_scene() -> Scene:
    """Chairs, a table and a stand with low feet around the robot, walls behind: vertical legs in the floor band."""
    boxes: list[tuple[str, Box]] = [
        ("table top", (1.8, 2.6, -0.8, 0.4, 0.72, 0.76)),
        ("table leg 1", (1.8, 1.85, -0.8, -0.75, 0.0, 0.72)),
        ("table leg 2", (2.55, 2.6, -0.8, -0.75, 0.0, 0.72)),
        ("table leg 3", (1.8, 1.85, 0.35, 0.4, 0.0, 0.72)),
        ("table leg 4", (2.55, 2.6, 0.35, 0.4, 0.0, 0.72)),
        ("chair seat", (1.3, 1.7, 0.7, 1.1, 0.42, 0.46)),
        ("chair leg 1", (1.3, 1.33, 0.7, 0.73, 0.0, 0.42)),
        ("chair leg 2", (1.67, 1.7, 0.7, 0.73, 0.0, 0.42)),
        ("chair leg 3", (1.3, 1.33, 1.07, 1.1, 0.0, 0.42)),
        ("chair leg 4", (1.67, 1.7, 1.07, 1.1, 0.0, 0.42)),
        ("stand foot", (2.8, 3.3, -1.4, -0.9, 0.0, 0.03)),
        ("stand pole", (3.03, 3.07, -1.17, -1.13, 0.0, 1.5)),
        ("far wall", (4.5, 4.7, -4.0, 4.0, 0.0, 2.8)),
        ("left wall", (0.0, 4.5, 2.0, 2.2, 0.0, 2.8)),
        ("right wall", (0.0, 4.5, -2.6, -2.4, 0.0, 2.8)),
    ]
    return Scene(boxes=tuple(b for _, b in boxes), names=tuple(n for n, _ in boxes), ceiling=2.8)


@dataclass
class Frame:
    """One rendered frame: the encoded depth the pipeline reads and the ground truth."""

    depth: np.ndarray  #: encoded depth (uint8 / uint16 / float32)
    metres: np.ndarray  #: float32 metres after noise (+Inf unknown)
    truth: dict[str, np.ndarray] = field(default_factory=dict)  #: noise-free depth/height/range/angle/object
    height: float = 0.0
    pitch: float = 0.0
    roll: float = 0.0


ENCODINGS = {"8UC1": np.uint8, "16UC1": np.uint16, "32FC1": np.float32}


def render_frame(
    camera: _core.Camera,
    scene: Scene,
    height: float,
    pitch: float,
    roll: float = 0.0,
    encoding: str = "16UC1",
    seed: int | None = 0,
    max_depth: float = 12.0,
    sigma0: float = 0.0015,
    k: float = 0.0019,
    dropout: float = 0.01,
    tof: bool = False,
    max_range: float = 8.0,
    flying: float = 0.5,
    stereo: bool = False,
    floor_curve: float = 0.0,
    floor_curve_from: float = 1.5,
    multipath: float = 0.0,
) -> Frame:
    """Renders ``scene`` seen from ``height`` with total ``pitch`` / ``roll`` [rad] and encodes it.

    ``seed=None`` gives a noise-free frame; otherwise Kinect-v2-like noise sigma0 + k (z - 0.4)^2 and dropouts.
    ``tof=True`` adds the time-of-flight artefacts: nothing beyond ``max_range`` [m] and flying pixels at depth
    jumps (probability ``flying``). ``stereo=True`` gives an active stereo camera's frame instead of the Kinect's
    noise (``_core.add_stereo_artefacts``: disparity noise and bias, wrong matches, the matching window's smear;
    ``sigma0``, ``k`` and ``tof`` are then not used). ``floor_curve`` [1/m] bends the floor: it rises by
    ``floor_curve * (r - floor_curve_from)^2`` at horizontal range r beyond ``floor_curve_from`` [m] (negative: it
    falls), a gently curved floor (the truth keeps the plane's labels). ``multipath`` [m] (with ``tof``): a
    time-of-flight camera's multipath before floor-wall corners, the floor seen up to that much farther
    (``add_multipath``).
    """
    if encoding not in ENCODINGS:
        raise ValueError(f"encoding {encoding!r}: expected one of {', '.join(ENCODINGS)}")
    truth = _core.render_scene(
        camera,
        height,
        pitch,
        roll,
        boxes=list(scene.boxes),
        holes=list(scene.holes),
        hole_depth=scene.hole_depth,
        ceiling=scene.ceiling,
    )
    metres = truth["depth"]
    if floor_curve != 0.0:
        metres = bend_floor(metres, truth, height, floor_curve, floor_curve_from)
    if stereo and seed is not None:
        metres = _core.add_stereo_artefacts(metres, seed, dropout=dropout, max_range=max_range)
        depth = _core.encode_depth(metres, encoding, max_depth)
        return Frame(depth=depth, metres=metres, truth=dict(truth), height=height, pitch=pitch, roll=roll)
    if tof:
        if multipath > 0.0:
            metres = add_multipath(metres, truth, multipath)
        metres = _core.add_tof_artefacts(metres, 0 if seed is None else seed + 7919, max_range, flying)
    if seed is not None:
        metres = _core.add_kinect_noise(metres, seed, sigma0, k, dropout)
    depth = _core.encode_depth(metres, encoding, max_depth)
    return Frame(depth=depth, metres=metres, truth=dict(truth), height=height, pitch=pitch, roll=roll)


def bend_floor(
    metres: np.ndarray, truth: dict[str, np.ndarray], height: float, curve: float, start: float
) -> np.ndarray:
    """``metres`` with the floor raised by ``curve * (r - start)^2`` at horizontal range r > ``start``: a ray that
    met the floor plane at depth d, ``height`` below the sensor, meets the raised floor at d (height - rise) /
    height."""
    floor = truth["object"] == FLOOR
    rise = curve * np.maximum(0.0, truth["range"] - start) ** 2
    out = metres.copy()
    out[floor] = (metres[floor] * (height - rise[floor]) / height).astype(np.float32)
    return out


def add_multipath(
    metres: np.ndarray, truth: dict[str, np.ndarray], amplitude: float, reach: float = 0.25
) -> np.ndarray:
    """``metres`` with a time-of-flight camera's multipath: light from the floor also reaches the sensor by way of
    the wall behind it, so the floor before a wall is seen farther, by ``amplitude * exp(-g / reach)`` of range
    [m] at a gap g [m] between the floor point and the surface above it in the image (a box, a wall)."""
    obj, rng = truth["object"], truth["range"]
    out = metres.copy()
    above = np.full(obj.shape[1], np.inf)  # per column, the range of the last solid surface seen going down
    for r in range(obj.shape[0]):
        solid = obj[r] >= FIRST_BOX
        above = np.where(solid, rng[r], above)
        floor = (obj[r] == FLOOR) & np.isfinite(above) & (rng[r] > 0)
        gap = np.maximum(above - rng[r], 0.0)
        extra = amplitude * np.exp(-gap / reach)
        out[r] = np.where(floor, metres[r] * (1.0 + extra / np.where(floor, rng[r], 1.0)), metres[r])
    return out.astype(np.float32)


kinect_sigma = _core.kinect_sigma

#: Ground-truth labels, the pipeline's own values (the core's list).
KEPT, INVALID, FLOOR_LABEL, ABOVE_CEILING, BELOW_FLOOR = (
    _core.LABELS[n] for n in ("kept", "invalid", "floor", "above_ceiling", "below_floor")
)


def truth_labels(truth: dict[str, np.ndarray], ceiling_height: float = 2.0) -> np.ndarray:
    """What each pixel really is: nothing seen (invalid), floor, a hole (below floor), above the ceiling plane,
    or an obstacle to keep."""
    obj, height = truth["object"], truth["height"]
    out = np.zeros(obj.shape, np.uint8)
    out[obj == NOTHING] = INVALID
    out[obj == FLOOR] = FLOOR_LABEL
    out[obj == HOLE] = BELOW_FLOOR
    out[(obj != NOTHING) & (obj != FLOOR) & (obj != HOLE) & (height > ceiling_height)] = ABOVE_CEILING
    return out


def ideal_scan(
    truth: dict[str, np.ndarray], angle_min: float, angle_increment: float, beams: int, mask: np.ndarray
) -> np.ndarray:
    """Nearest true horizontal range per beam over the pixels in ``mask`` (binned by the hit's bearing);
    +Inf where none."""
    out = np.full(beams, np.inf)
    angle = truth["angle"][mask].astype(np.float64)
    rng = truth["range"][mask].astype(np.float64)
    idx = np.floor((angle - (angle_min - 0.5 * angle_increment)) / angle_increment).astype(np.int64)
    ok = (idx >= 0) & (idx < beams)
    np.minimum.at(out, idx[ok], rng[ok])
    return out
