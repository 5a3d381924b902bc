"""Quality of one processed frame against the renderer's ground truth (counting only: no pipeline math here)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .. import _core
from ..simulation.scenes import FIRST_BOX, FLOOR, KEPT, NOTHING, Frame, ideal_scan


@dataclass
class FrameQuality:
    """Fractions in [0, 1] (NaN where the frame has no such pixel or beam)."""

    floor_removed: float  #: floor pixels within ``floor_radius`` that were removed
    obstacles_kept: float  #: obstacle pixels 5 cm .. 1.95 m above the floor that were kept
    above_ceiling_removed: float  #: pixels of anything 5 cm or more above the ceiling plane that were removed
    phantom_beams: float  #: finite beams shorter than anything real by > 5 cm + 4 sigma (of all beams)
    floor_pixels: int
    obstacle_pixels: int
    above_ceiling_pixels: int

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def phantom_beams(ranges: np.ndarray, real: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Phantom beams against ``real`` (the true nearest range per beam, +Inf none): finite and shorter than the
    nearest real range within one beam either side by more than 5 cm (first mask), and by more than 5 cm + 4 sigma
    of the sensor's noise at that range (second: the goal's definition; a min over many noisy pixels lies about
    2 sigma short of a far wall, which the plain 5 cm rule takes for phantoms)."""
    real = np.asarray(real, np.float64)
    real = np.minimum(real, np.minimum(np.roll(real, 1), np.roll(real, -1)))
    r = np.asarray(ranges, np.float64)
    fin = np.isfinite(r)
    # horizontal range <= depth: sigma(range) is the smaller, stricter margin
    sigma = _core.kinect_sigma(np.where(np.isfinite(real), real, 0.0))
    return fin & (r < real - 0.05), fin & (r < real - 0.05 - 4.0 * sigma)


def missed_beams(ranges: np.ndarray, real: np.ndarray) -> np.ndarray:
    """Beams where ``real`` has an obstacle and the scan has none or puts it more than 10 cm too far."""
    r = np.asarray(ranges, np.float64)
    real = np.asarray(real, np.float64)
    return np.isfinite(real) & (~np.isfinite(r) | (r > real + 0.10))


def frame_quality(
    result: _core.Result,
    frame: Frame,
    ceiling_height: float = 2.0,
    floor_radius: float = 6.0,
) -> FrameQuality:
    """Scores a processed frame. A phantom beam is one shorter than the nearest real surface (any object,
    the floor included, within one beam either side) by more than 5 cm + 4 sigma of the sensor's noise."""
    t = frame.truth
    obj, height, rng = t["object"], t["height"], t["range"]
    labels = result.labels
    floor = (obj == FLOOR) & (rng < floor_radius)
    obstacles = (obj >= FIRST_BOX) & (height >= 0.05) & (height <= ceiling_height - 0.05)
    # 5 cm clear of the plane on both sides: closer than that, sensor noise decides (no threshold band there).
    above = (obj != NOTHING) & (height >= ceiling_height + 0.05)

    def frac(mask: np.ndarray, good: np.ndarray) -> float:
        n = int(mask.sum())
        return float((mask & good).sum() / n) if n else float("nan")

    removed = labels != KEPT
    beams = len(result.ranges)
    real = ideal_scan(t, result.angle_min, result.angle_increment, beams, obj != NOTHING)
    return FrameQuality(
        floor_removed=frac(floor, removed),
        obstacles_kept=frac(obstacles, ~removed),
        above_ceiling_removed=frac(above, removed),
        phantom_beams=float(phantom_beams(result.ranges, real)[1].sum() / beams),
        floor_pixels=int(floor.sum()),
        obstacle_pixels=int(obstacles.sum()),
        above_ceiling_pixels=int(above.sum()),
    )
