"""Raw depth images, rectified by their camera_info's distortion (io/rectify.h): kinect2_bridge's ``sd/image_depth``
is raw, and a Kinect v2's lens moves its corners by about 20 px. The maps are held to OpenCV's own
(initUndistortRectifyMap); a raw frame made with OpenCV from a rendered one shows what rectifying buys, through the
core and through the bag tools (the node: test_ros_first_day.py)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import cv2  # python3-opencv (the quick start installs it)
import numpy as np
import pytest
from framebag import write_frames_bag

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.simulation.scenes import FLOOR, KEPT, lab_scene, render_frame

FX, FY, CX, CY, W, H = 365.5, 365.5, 254.9, 205.4, 512, 424
CAM = kp.Camera(W, H, FX, FY, CX, CY)
K = np.array([[FX, 0.0, CX], [0.0, FY, CY], [0.0, 0.0, 1.0]])
KINECT_V2_D = [0.0905, -0.2699, 0.0, 0.0, 0.0952]  # a Kinect v2's IR lens, as libfreenect2 reads it from the device
HEIGHT, TILT = 1.1, 0.26


@pytest.mark.parametrize(
    ("model", "D"),
    [
        ("plumb_bob", KINECT_V2_D),
        ("plumb_bob", [0.12, -0.3, 0.002, -0.001, 0.1]),
        ("rational_polynomial", [0.2, -0.1, 0.001, 0.002, 0.01, 0.15, -0.05, 0.005]),
        ("equidistant", [0.1, -0.05, 0.01, 0.0]),
    ],
)
def test_the_maps_are_opencvs(model: str, D: list[float]) -> None:
    init = cv2.fisheye.initUndistortRectifyMap if model == "equidistant" else cv2.initUndistortRectifyMap
    mx, my = init(K, np.array(D), np.eye(3), K, (W, H), cv2.CV_32FC1)
    raw = (np.arange(W * H) % 60000 + 1).astype(np.uint16).reshape(H, W)
    want = cv2.remap(raw, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    r = kp.DepthRectifier(CAM, model, D)
    got = r.apply(raw)
    # OpenCV's maps are float32: a pixel half-way between two may round the other way.
    assert np.mean(got != want) < 1e-4, f"{np.mean(got != want):.6f} of the pixels differ"
    shift = np.hypot(mx - np.arange(W)[None], my - np.arange(H)[:, None]).max()
    assert r.max_shift == pytest.approx(shift, abs=1e-3)


def _raw_frame(seed: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(raw frame through the Kinect v2's lens, the rectified frame, the raw frame's truth objects), made with
    OpenCV from a rendered frame of a wider pinhole camera: each raw pixel takes what its ray meets."""
    pad = 120
    big = kp.Camera(W + 2 * pad, H + 2 * pad, FX, FY, CX + pad, CY + pad)
    f = render_frame(big, lab_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=seed)
    u, v = np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64))
    rays = cv2.undistortPoints(np.stack([u.ravel(), v.ravel()], 1).reshape(-1, 1, 2), K, np.array(KINECT_V2_D))
    mx = (rays[:, 0, 0] * FX + CX + pad).reshape(H, W).astype(np.float32)
    my = (rays[:, 0, 1] * FY + CY + pad).reshape(H, W).astype(np.float32)
    raw = cv2.remap(f.depth, mx, my, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    obj = cv2.remap(f.truth["object"].astype(np.float32), mx, my, cv2.INTER_NEAREST, borderValue=-1)
    return raw, f.depth[pad : pad + H, pad : pad + W].copy(), obj


def test_a_raw_kinect_v2_frame_keeps_its_floor_unless_rectified() -> None:
    raw, rectified, obj = _raw_frame()
    config = kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, refine_floor=False)
    want = np.asarray(kp.Pipeline(CAM, config).process(rectified).ranges)
    floor = (obj == FLOOR) & (raw > 0)
    kept, near = {}, {}
    for mode in ("never", "auto"):
        t = _core.TopicRectification()
        depth = t.apply(mode, "/kinect2/sd/image_depth", CAM, "plumb_bob", KINECT_V2_D, raw)
        res = kp.Pipeline(CAM, config).process(depth)
        got = np.asarray(res.ranges)
        if mode == "auto":
            floor = (_core.DepthRectifier(CAM, "plumb_bob", KINECT_V2_D).apply(obj.astype(np.float32)) == FLOOR) & (
                depth > 0
            )
        kept[mode] = float(np.mean(np.asarray(res.labels)[floor] == KEPT))
        both = np.isfinite(got) & np.isfinite(want)
        near[mode] = float(np.mean(np.abs(got - want)[both] < 0.03))
    assert kept["never"] > 0.02 and near["never"] < 0.9, f"taken as rectified: {kept}, {near}"
    assert kept["auto"] < 0.001, f"floor pixels kept: {kept['auto']:.4f}"
    assert near["auto"] > 0.97, f"beams within 3 cm of the rectified frame's: {near['auto']:.3f}"


def _bag(path: Path, topic: str, frames: list[np.ndarray], D: list[float], R: Any = None) -> None:
    """A ROS 1 bag of 16UC1 frames on ``topic`` with the Kinect v2's camera_info (plumb_bob, D; R: the identity)."""
    info = {"width": W, "height": H, "K": K.ravel(), "D": D, **({} if R is None else {"R": R})}
    write_frames_bag(path, frames, [info], topic)


def _replay(tmp_path: Path, name: str, topic: str, frames: list[np.ndarray], rectify: str) -> tuple[Any, np.ndarray]:
    from kinect_pipeline.tools.replay import ReplayOptions, replay

    _bag(tmp_path / f"{name}.bag", topic, frames, KINECT_V2_D)
    opts = ReplayOptions(config={"sensor_height": HEIGHT, "sensor_pitch": TILT}, rectify=rectify)
    r = replay(tmp_path / f"{name}.bag", tmp_path / f"{name}_out.bag", opts, show_progress=False)
    return r, _scans(tmp_path / f"{name}_out.bag")


def _scans(bag: Path) -> np.ndarray:
    from kinect_pipeline.bags.reader import open_bag

    with open_bag(bag) as b:
        return np.array([np.array(b.decode(c, raw).ranges) for c, _, raw in b.messages() if c.topic.endswith("/scan")])


def test_replay_rectifies_a_raw_topic_and_takes_a_rect_topic_as_it_is(tmp_path: Path) -> None:
    pairs = [_raw_frame(seed) for seed in (0, 1)]
    raw, rect = [p[0] for p in pairs], [p[1] for p in pairs]
    r_rect, want = _replay(tmp_path, "rect", "/kinect2/sd/image_depth_rect", rect, "auto")
    assert "rectified: no (the topic's name says it is rectified" in r_rect.camera, r_rect.camera
    r_raw, got = _replay(tmp_path, "raw", "/kinect2/sd/image_depth", raw, "auto")
    assert "rectified: yes (pixels move up to 19.8 px" in r_raw.camera, r_raw.camera
    _, as_is = _replay(tmp_path, "as_is", "/kinect2/sd/image_depth", raw, "never")
    both = np.isfinite(got) & np.isfinite(want)
    assert np.mean(np.abs(got - want)[both] < 0.03) > 0.97
    both = np.isfinite(as_is) & np.isfinite(want)
    assert np.mean(np.abs(as_is - want)[both] < 0.03) < 0.9, "the check can fail"


def test_a_distortion_the_tools_cannot_take_skips_the_frame_naming_it(tmp_path: Path) -> None:
    from kinect_pipeline.tools.replay import ReplayError

    with pytest.raises(ReplayError, match=r"distortion_model 'plumb_bob', D = \[0.1, 0.2\]: expected plumb_bob \(4 or"):
        frame = np.full((H, W), 2000, np.uint16)
        _bag(tmp_path / "in.bag", "/kinect2/sd/image_depth", [frame], [0.1, 0.2])
        from kinect_pipeline.tools.replay import ReplayOptions, replay

        replay(tmp_path / "in.bag", tmp_path / "out.bag", ReplayOptions(), show_progress=False)
    assert not (tmp_path / "out.bag").exists()


def test_a_camera_info_yaml_with_a_lens_rectifies_a_bag_without_camera_info(tmp_path: Path) -> None:
    """--intrinsics YAML as camera_calibration writes it, distortion_coefficients included (the node's
    ~camera_info_url reads the same file)."""
    from clitool import cli

    raw, rect, _ = _raw_frame(0)
    yaml_file = tmp_path / "kinect2_ir.yaml"
    yaml_file.write_text(
        f"image_width: {W}\nimage_height: {H}\ncamera_name: kinect2_ir\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{FX}, 0, {CX}, 0, {FY}, {CY}, 0, 0, 1]\n"
        "distortion_model: plumb_bob\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: {KINECT_V2_D}\n"
    )
    scans = {}
    for name, frame in (("raw", raw), ("rect", rect)):
        topic = "/kinect2/sd/image_depth" + ("_rect" if name == "rect" else "")
        write_frames_bag(tmp_path / f"{name}.bag", [frame], [], topic)
        out = tmp_path / f"{name}_out.bag"
        args = ["--param", f"sensor_height={HEIGHT}", "--param", f"sensor_pitch={TILT}", "--quiet"]
        r = cli("replay", str(tmp_path / f"{name}.bag"), "-o", str(out), "--intrinsics", str(yaml_file), *args)
        assert r.returncode == 0, r.stderr
        said = "rectified: yes" if name == "raw" else "rectified: no (the topic's name says"
        assert said in r.stdout, r.stdout
        scans[name] = _scans(out)
    both = np.isfinite(scans["raw"]) & np.isfinite(scans["rect"])
    assert np.mean(np.abs(scans["raw"] - scans["rect"])[both] < 0.03) > 0.97


def test_a_camera_info_yaml_with_a_lens_the_core_cannot_take_is_named(tmp_path: Path) -> None:
    from kinect_pipeline.intrinsics import IntrinsicsError, parse_intrinsics

    yaml_file = tmp_path / "odd.yaml"
    yaml_file.write_text(
        "image_width: 512\nimage_height: 424\ncamera_matrix:\n  rows: 3\n  cols: 3\n"
        "  data: [365, 0, 255, 0, 365, 211, 0, 0, 1]\ndistortion_model: fisheye\n"
        "distortion_coefficients:\n  rows: 1\n  cols: 4\n  data: [0.1, 0, 0, 0]\n"
    )
    with pytest.raises(
        IntrinsicsError, match=r"odd.yaml: camera_info distortion_model 'fisheye', D = \[0.1, 0, 0, 0\]"
    ):
        parse_intrinsics([str(yaml_file)])


def test_a_stereo_cameras_depth_is_taken_as_rectified_whatever_its_topics_name(tmp_path: Path) -> None:
    """Depth from a stereo pair is computed on rectified images; its camera_info's R (the rectification's rotation)
    says it is a stereo camera's."""
    from kinect_pipeline.tools.replay import ReplayOptions, replay

    a = np.radians(1.0)
    R = [np.cos(a), -np.sin(a), 0.0, np.sin(a), np.cos(a), 0.0, 0.0, 0.0, 1.0]
    _, rect, _ = _raw_frame(0)
    _bag(tmp_path / "stereo.bag", "/stereo/depth", [rect], KINECT_V2_D, R)
    for mode, said in (("auto", "rectified: no (the camera_info's R rotates: a stereo camera's"), ("always", "yes")):
        out = tmp_path / f"out_{mode}.bag"
        r = replay(tmp_path / "stereo.bag", out, ReplayOptions(rectify=mode), show_progress=False)
        assert said in r.camera, r.camera
    t = _core.TopicRectification()
    assert t.apply("auto", "/stereo/depth", CAM, "plumb_bob", KINECT_V2_D, rect, R) is rect
    assert t.apply("auto", "/stereo/depth", CAM, "plumb_bob", KINECT_V2_D, rect, np.eye(3).ravel()) is not rect
    with pytest.raises(ValueError, match="R: expected 9 values"):
        t.apply("auto", "/stereo/depth", CAM, "plumb_bob", KINECT_V2_D, rect, [1.0, 0.0])


def test_a_rectified_topics_camera_is_its_camera_infos_projection(tmp_path: Path) -> None:
    """camera_calibration's P (with which image_proc rectifies) differs from K: a rectified image's camera is P's,
    as image_geometry takes it; a raw image rectified here keeps K."""
    from kinect_pipeline.tools.replay import ReplayOptions, replay

    _, rect, _ = _raw_frame(0)
    wrong_k = [FX * 1.1, 0.0, CX + 12, 0.0, FY * 1.1, CY - 9, 0.0, 0.0, 1.0]
    P = [FX, 0.0, CX, 0.0, 0.0, FY, CY, 0.0, 0.0, 0.0, 1.0, 0.0]
    info = {"width": W, "height": H, "K": wrong_k, "D": KINECT_V2_D, "P": P}
    write_frames_bag(tmp_path / "rect.bag", [rect], [info], "/kinect2/sd/image_depth_rect")
    opts = ReplayOptions(config={"sensor_height": HEIGHT, "sensor_pitch": TILT})
    replay(tmp_path / "rect.bag", tmp_path / "out.bag", opts, show_progress=False)
    config = kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)
    want = np.asarray(kp.Pipeline(CAM, config).process(rect).ranges)
    np.testing.assert_array_equal(_scans(tmp_path / "out.bag")[0], want)
    assert _core.rectified_intrinsics(P) == [FX, 0.0, CX, 0.0, FY, CY, 0.0, 0.0, 1.0]
    assert _core.rectified_intrinsics([0.0] * 12) is None, "not set"


def test_a_camera_info_yamls_projection_is_a_rectified_topics_camera(tmp_path: Path) -> None:
    """--intrinsics YAML with a projection_matrix other than its camera_matrix, on a bag without camera_info: as the
    node's ~camera_info_url, a rectified topic's camera is P's."""
    from clitool import cli

    _, rect, _ = _raw_frame(0)
    yaml_file = tmp_path / "kinect2_ir.yaml"
    yaml_file.write_text(
        f"image_width: {W}\nimage_height: {H}\ncamera_name: kinect2_ir\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: [{FX * 1.1}, 0, {CX + 10}, 0, {FY * 1.1}, {CY}, 0, 0, 1]\n"
        f"distortion_model: plumb_bob\ndistortion_coefficients:\n  rows: 1\n  cols: 5\n  data: {KINECT_V2_D}\n"
        f"projection_matrix:\n  rows: 3\n  cols: 4\n  data: [{FX}, 0, {CX}, 0, 0, {FY}, {CY}, 0, 0, 0, 1, 0]\n"
    )
    write_frames_bag(tmp_path / "rect.bag", [rect], [], "/kinect2/sd/image_depth_rect")
    args = ["--param", f"sensor_height={HEIGHT}", "--param", f"sensor_pitch={TILT}", "--quiet"]
    r = cli("replay", str(tmp_path / "rect.bag"), "-o", str(tmp_path / "o.bag"), "--intrinsics", str(yaml_file), *args)
    assert r.returncode == 0, r.stderr
    want = np.asarray(kp.Pipeline(CAM, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)).process(rect).ranges)
    np.testing.assert_array_equal(_scans(tmp_path / "o.bag")[0], want)
