"""A camera_info's binning and region of interest (REP 104), as image_proc's crop_decimate sends them: the width,
height and K of the full-resolution camera, the image cropped to the roi and subsampled by the binning. The core's
``camera_from_intrinsics`` gives the image's own camera (as image_geometry reads it); the bag tools and the node
(test/ros/test_conversions.cpp, test_ros_first_day.py) go through it. Held here to the renderer's ground truth: the
window's pixels of a full-resolution frame are what the derived camera sees."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from framebag import write_frames_bag

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.simulation.scenes import lab_scene, render_frame

K = [365.0, 0.0, 255.5, 0.0, 366.0, 211.5, 0.0, 0.0, 1.0]
FULL = kp.Camera(512, 424, 365.0, 366.0, 255.5, 211.5)
HEIGHT, TILT = 1.1, 0.26
#: (binning_x, binning_y, roi): crop_decimate's 2x2 of the whole image, a crop, a crop with unequal binning
WINDOWS = [(2, 2, (0, 0, 0, 0)), (1, 1, (100, 50, 301, 201)), (2, 3, (37, 20, 440, 390))]


def _window(depth: np.ndarray, bx: int, by: int, roi: tuple[int, int, int, int]) -> np.ndarray:
    """What crop_decimate sends: the roi's pixels, every bx-th column and by-th row from its corner."""
    x, y, w, h = roi if roi[2] else (0, 0, depth.shape[1], depth.shape[0])
    return np.ascontiguousarray(depth[y : y + h - h % by : by, x : x + w - w % bx : bx])


@pytest.mark.parametrize(("bx", "by", "roi"), WINDOWS)
def test_the_windows_camera_sees_what_the_full_camera_sees_at_those_pixels(
    bx: int, by: int, roi: tuple[int, int, int, int]
) -> None:
    cam = _core.camera_from_intrinsics(512, 424, K, "cam", binning_x=bx, binning_y=by, roi=roi)
    want = _window(render_frame(FULL, lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None).depth, bx, by, roi)
    assert (cam.height, cam.width) == want.shape
    got = render_frame(cam, lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None).depth
    off = np.abs(got.astype(np.int32) - want.astype(np.int32))
    assert np.mean(off <= 1) > 0.999, f"{np.mean(off <= 1):.5f} of the pixels within 1 mm"
    # Read without its window (the size alone, as before), the same K sees another scene: the check can fail.
    naive = render_frame(
        kp.Camera(cam.width, cam.height, 365.0, 366.0, 255.5, 211.5), lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None
    ).depth
    assert np.mean(np.abs(naive.astype(np.int32) - want.astype(np.int32)) <= 1) < 0.5


def test_a_window_outside_the_image_is_named() -> None:
    with pytest.raises(ValueError, match=r"roi \(x_offset 300, y_offset 0, width 300, height 100\), binning 0x0: "):
        _core.camera_from_intrinsics(512, 424, K, roi=(300, 0, 300, 100))
    with pytest.raises(ValueError, match="expected an roi of non-zero width and height, or all four 0"):
        _core.camera_from_intrinsics(512, 424, K, roi=(10, 0, 0, 0))
    with pytest.raises(ValueError, match="expected a binning no larger than the roi"):
        _core.camera_from_intrinsics(512, 424, K, binning_y=425)
    cam = _core.camera_from_intrinsics(512, 424, K, binning_x=0, binning_y=1)
    assert (cam.width, cam.height, cam.fx, cam.cx) == (512, 424, 365.0, 255.5), "0 and 1: every pixel"


def _scans(bag: Path) -> list[np.ndarray]:
    from kinect_pipeline.bags.reader import open_bag

    with open_bag(bag) as b:
        return [np.array(b.decode(c, raw).ranges) for c, _, raw in b.messages() if c.topic.endswith("/scan")]


def test_replay_of_a_crop_decimate_bag_uses_the_windows_camera(tmp_path: Path) -> None:
    """The bag as crop_decimate records it (full-resolution camera_info, binning 2, a crop) replays every frame, with
    the scans of the same frames under a camera_info of the window's own camera."""
    from kinect_pipeline.tools.replay import ReplayOptions, replay

    bx, by, roi = 2, 2, (16, 12, 480, 400)
    frames = [
        _window(render_frame(FULL, lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=s).depth, bx, by, roi) for s in (0, 1)
    ]
    cam = _core.camera_from_intrinsics(512, 424, K, binning_x=bx, binning_y=by, roi=roi)
    own = [cam.fx, 0.0, cam.cx, 0.0, cam.fy, cam.cy, 0.0, 0.0, 1.0]
    bags = {
        "crop_decimate": {"width": 512, "height": 424, "K": K, "binning": (bx, by), "roi": roi},
        "own": {"width": cam.width, "height": cam.height, "K": own, "binning": (0, 0), "roi": (0, 0, 0, 0)},
    }
    scans = {}
    opts = ReplayOptions(config={"sensor_height": HEIGHT, "sensor_pitch": TILT})
    for name, info in bags.items():
        write_frames_bag(tmp_path / f"{name}.bag", frames, [info])
        r = replay(tmp_path / f"{name}.bag", tmp_path / f"{name}_out.bag", opts, show_progress=False)
        assert r.processed == 2 and not [p for p in r.problems if "camera_info" in p], r.problems
        scans[name] = _scans(tmp_path / f"{name}_out.bag")
    assert len(scans["own"]) == 2
    for a, b in zip(scans["crop_decimate"], scans["own"], strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.isfinite(scans["own"][0]).sum() > 100, "the scan sees the scene"


def test_replay_names_a_camera_info_whose_window_is_outside_the_image(tmp_path: Path) -> None:
    from kinect_pipeline.tools.replay import ReplayError, ReplayOptions, replay

    frame = np.full((200, 240), 2000, np.uint16)
    info = {"width": 512, "height": 424, "K": K, "binning": (2, 2), "roi": (100, 0, 480, 400)}
    write_frames_bag(tmp_path / "in.bag", [frame], [info])
    with pytest.raises(ReplayError, match=r"binning 2x2: expected an roi inside the camera_info's 512x424; frame sk"):
        replay(tmp_path / "in.bag", tmp_path / "out.bag", ReplayOptions(), show_progress=False)
    assert not (tmp_path / "out.bag").exists(), "nothing written"
