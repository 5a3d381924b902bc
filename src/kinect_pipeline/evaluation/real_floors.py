"""Real floors (issue #25): the scenes where a real robot's floor fooled the pipeline, rendered with exact ground
truth, and the shared real RealSense frames. Worst frame of each measure; used by ``kinect-pipeline quality`` and
the tests (test_real_floors.py)."""

from __future__ import annotations

import glob
import math
import os
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .. import _core
from ..outputs import progress
from ..simulation.scenes import Scene, furniture_scene, lab_scene, people_scene, render_frame
from .metrics import frame_quality

DEG = math.pi / 180
KINECT = _core.Camera.from_fov(512, 424, math.radians(70.6), math.radians(60.0))
#: realsense_lowcam's camera (cam_params_realsense.json), used for the rendered RealSense frames too.
RS_K = (617.25, 617.549, 317.392, 245.980)
RS_CAM = _core.Camera(640, 480, *RS_K)
#: The issue's robot: a RealSense 0.63 m high, 20 deg down, 10 deg of roll.
RS_HEIGHT, RS_PITCH, RS_ROLL = 0.63, 20 * DEG, 10 * DEG
#: A told pose off by (height [m], pitch [deg], roll [deg]).
Told = tuple[float, float, float]


@dataclass
class Worst:
    """The worst frame of a run: least floor removed (nearer than 4 m), most phantom and false cliff beams."""

    floor: float = 1.0
    phantom: float = 0.0
    cliff: float = 0.0
    frames: int = 0
    accepted: int = 0  #: frames whose floor fit was accepted

    def add(self, res: _core.Result, frame: object, sigma: Callable[[np.ndarray], np.ndarray]) -> None:
        q = frame_quality(res, frame, floor_radius=4.0, sigma=sigma)  # type: ignore[arg-type]
        if not math.isnan(q.floor_removed):
            self.floor = min(self.floor, q.floor_removed)
        self.phantom = max(self.phantom, q.phantom_beams)
        self.cliff = max(self.cliff, float(np.isfinite(res.cliff_ranges).mean()) if res.cliff_ranges.size else 0.0)
        self.frames += 1
        self.accepted += bool(res.floor_fit.accepted)


def stereo_robot(scene: Scene, told: Told, refine: bool = True, frames: int = 20, encoding: str = "16UC1") -> Worst:
    """The RealSense robot driving through ``scene`` (rocking +-1 deg in pitch and roll), rendered with an active
    stereo camera's artefacts, told the mount off by ``told``, with the sensor's preset."""
    cfg = _core.Config(
        sensor_model="realsense_d4xx",
        sensor_height=RS_HEIGHT + told[0],
        sensor_pitch=RS_PITCH + told[1] * DEG,
        sensor_roll=RS_ROLL + told[2] * DEG,
        ceiling_height=2.0,
        refine_floor=refine,
    )
    pipe = _core.Pipeline(RS_CAM, cfg)
    worst = Worst()
    for i in range(frames):
        rock = 1.0 * DEG * math.sin(2 * math.pi * i / 17)
        fr = render_frame(RS_CAM, scene, RS_HEIGHT, RS_PITCH + rock, RS_ROLL + rock, encoding, seed=i, stereo=True)
        worst.add(pipe.process(fr.depth, rock, rock, stamp=i / 10), fr, _core.stereo_sigma)
    return worst


def people_robot(refine: bool = True, exact: bool = False, encoding: str = "16UC1", frames: int = 45) -> Worst:
    """Eight people 1.2-2 m ahead, 30 cm apart (a new group each frame), a Kinect v2 at 1.1 m tilted 5 deg on a base
    pitching +-6 deg, told the mount 4 cm / 0.6 deg / 0.5 deg off (or exactly)."""
    tilt = 5 * DEG
    off = (0.0, 0.0, 0.0) if exact else (0.04, 0.6 * DEG, 0.5 * DEG)
    cfg = _core.Config(sensor_height=1.1 + off[0], sensor_pitch=tilt + off[1], sensor_roll=off[2], refine_floor=refine)
    pipe = _core.Pipeline(KINECT, cfg)
    worst = Worst()
    for i in range(frames):
        bp = 6 * DEG * math.sin(2 * math.pi * i / 15)
        fr = render_frame(KINECT, people_scene(seed=i, count=8, spacing=0.3), 1.1, tilt + bp, 0.0, encoding, seed=i)
        worst.add(pipe.process(fr.depth, bp, 0.0, stamp=i / 30), fr, _core.kinect_sigma)
    return worst


#: The curved floor's bend [1/m] and where it starts [m]: 5 cm up at 4.4 m (``render_frame(floor_curve=...)``).
CURVE, CURVE_FROM = 0.006, 1.5


def curved_floor_robot(
    refine: bool = True, profile: bool = True, roll: float = 0.0, encoding: str = "16UC1", frames: int = 20
) -> Worst:
    """The RealSense robot's pose (0.63 m, 20 deg down, ``roll`` [deg]) over the lab with a gently curved floor, a
    Kinect v2's noise and the default sensor model, told the exact pose; ``profile=False``: floor_profile_max 0."""
    cfg = _core.Config(
        sensor_height=RS_HEIGHT,
        sensor_pitch=RS_PITCH,
        sensor_roll=roll * DEG,
        ceiling_height=2.0,
        refine_floor=refine,
        floor_profile_max=_core.Config().floor_profile_max if profile else 0.0,
    )
    pipe = _core.Pipeline(RS_CAM, cfg)
    worst = Worst()
    for i in range(frames):
        fr = render_frame(
            RS_CAM,
            lab_scene(),
            RS_HEIGHT,
            RS_PITCH,
            roll * DEG,
            encoding,
            seed=i,
            floor_curve=CURVE,
            floor_curve_from=CURVE_FROM,
        )
        worst.add(pipe.process(fr.depth, stamp=i / 30), fr, _core.kinect_sigma)
    return worst


def shared_realsense_frames(folder: str) -> list[np.ndarray]:
    """The shared real RealSense frames (``realsense_lowcam/depth/*.png``, uint16 mm) under ``folder``."""
    import cv2

    return [cv2.imread(f, cv2.IMREAD_UNCHANGED) for f in sorted(glob.glob(os.path.join(folder, "depth", "*.png")))]


def calibrated_config(depth: np.ndarray, min_floor: float = 0.0) -> _core.Config | None:
    """The sensor's preset at the floor a real RealSense frame (16-bit mm) holds, as the core's floor calibration
    finds it; None if it finds none, or one covering less than ``min_floor`` of the image."""
    metres = np.where(depth > 0, depth / 1000.0, np.inf).astype(np.float32)
    fp = _core.calibrate_from_floor(metres, RS_CAM)
    if not fp["found"] or fp["floor_fraction"] < min_floor:
        return None
    return _core.Config(
        sensor_model="realsense_d4xx",
        sensor_height=fp["height"],
        sensor_pitch=fp["pitch"],
        sensor_roll=fp["roll"],
        ceiling_height=max(2.0, fp["height"] + 0.5),
    )


def real_frames_false_cliffs(frames: list[np.ndarray]) -> list[float]:
    """Per real RealSense frame whose floor calibrate trusts (found, >= 20 % of the image), the share of cliff
    beams, told that floor, with the sensor's preset (the frames hold no hole and no stair)."""
    out = []
    for depth in frames:
        cfg = calibrated_config(depth, min_floor=0.2)
        if cfg is None:
            continue
        res = _core.Pipeline(RS_CAM, cfg).process(depth)
        out.append(float(np.isfinite(res.cliff_ranges).mean()))
    return out


ROBOT_SCENES: dict[str, Callable[[], Scene]] = {
    "furniture": furniture_scene,
    "lab": lab_scene,
    "people": lambda: people_scene(count=8, spacing=0.3),
}
ROBOT_POSES: dict[str, Told] = {"exact": (0.0, 0.0, 0.0), "5 cm / 1° / −1° off": (0.05, 1.0, -1.0)}


def table(frames: int = 20, show_progress: bool = False, real_folder: str | None = None) -> str:
    """A Markdown table: each scene with refine_floor on and off, worst frame of floor removed (< 4 m) / phantom
    beams / false cliff beams, in %; and the shared real RealSense frames' false cliff beams."""
    rows: list[tuple[str, str, Worst, Worst]] = []
    jobs = [(s, p) for s in ROBOT_SCENES for p in ROBOT_POSES]
    for scene, pose in progress(jobs, len(jobs), "stereo robot") if show_progress else jobs:
        on, off = (stereo_robot(ROBOT_SCENES[scene](), ROBOT_POSES[pose], refine, frames) for refine in (True, False))
        rows.append((f"RealSense robot (stereo), {scene}", pose, on, off))
    for exact in (False, True):
        on, off = (people_robot(refine, exact, frames=max(frames, 15)) for refine in (True, False))
        rows.append(("people, Kinect v2 pitching ±6°", "exact" if exact else "4 cm / 0.6° / 0.5° off", on, off))
    for roll in (0.0, 10.0):
        on, off = (curved_floor_robot(refine, roll=roll, frames=frames) for refine in (True, False))
        rows.append((f"gently curved floor (+5 cm at 4.4 m), roll {roll:.0f}°, Kinect v2 noise", "exact", on, off))
    out = [
        "| scene | told pose | refine_floor on (default) | refine_floor off |",
        "|---|---|---|---|",
    ]
    fmt = "{:.2f} / {:.2f} / {:.2f}"
    for scene, pose, w_on, w_off in rows:
        cells = [fmt.format(100 * w.floor, 100 * w.phantom, 100 * w.cliff) for w in (w_on, w_off)]
        out.append(f"| {scene} | {pose} | {cells[0]} | {cells[1]} |")
    if real_folder:
        cliffs = real_frames_false_cliffs(shared_realsense_frames(real_folder))
        if cliffs:
            worst = 100 * max(cliffs)
            out.append(
                f"| real RealSense frames (realsense_lowcam, {len(cliffs)} with a trusted floor) | their own floor "
                f"| – / – / {worst:.2f} (worst frame) | – |"
            )
    return "\n".join(out)
