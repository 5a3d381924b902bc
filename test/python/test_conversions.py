"""Image / CameraInfo conversions of the tools are the core's (the ROS node's): same checks, same messages."""

from __future__ import annotations

import numpy as np
import pytest

from kinect_pipeline import _core


@pytest.mark.parametrize(("encoding", "dtype"), [("16UC1", "<u2"), ("mono16", ">u2"), ("32FC1", ">f4"), ("8UC1", "u1")])
def test_depth_from_buffer_reads_every_encoding_and_byte_order(encoding: str, dtype: str) -> None:
    want = (np.arange(12).reshape(3, 4) * 7 + 1).astype(dtype)
    padded = np.zeros((3, 6), dtype)
    padded[:, :4] = want  # a step larger than the row
    big = np.dtype(dtype).byteorder == ">"
    got = _core.depth_from_buffer(encoding, 4, 3, padded.strides[0], big, padded.tobytes())
    assert got.dtype == want.dtype.newbyteorder("=") and got.dtype.isnative
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("rgb8", 4, 3, 12, False, bytes(36)), "depth image encoding 'rgb8': expected 8UC1 or mono8"),
        (("16UC1", 4, 3, 6, False, bytes(36)), "depth image step 6 bytes is less than width 4 x 2"),
        (("16UC1", 4, 3, 8, False, bytes(20)), "depth image has 20 bytes, expected step 8 x height 3 = 24"),
        (("16UC1", 0, 3, 8, False, b""), "depth image is empty"),
    ],
)
def test_bad_images_get_the_nodes_message(args: tuple, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        _core.depth_from_buffer(*args)


def test_camera_from_intrinsics_is_the_nodes() -> None:
    cam = _core.camera_from_intrinsics(512, 424, [365.5, 0, 255.5, 0, 366.0, 211.5, 0, 0, 1], "kinect2")
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height) == (365.5, 366.0, 255.5, 211.5, 512, 424)
    with pytest.raises(ValueError, match=r"K\[0\] \(fx\) = 0: the camera is uncalibrated \(frame 'kinect2'\)"):
        _core.camera_from_intrinsics(512, 424, [0.0] * 9, "kinect2")
    with pytest.raises(ValueError, match="camera_info size 0x424"):
        _core.camera_from_intrinsics(0, 424, [365.5, 0, 255.5, 0, 366.0, 211.5, 0, 0, 1], "")
    with pytest.raises(ValueError, match="fy"):
        _core.camera_from_intrinsics(512, 424, [365.5, 0, 255.5, 0, -1.0, 211.5, 0, 0, 1], "")
    with pytest.raises(ValueError, match="9 values"):
        _core.camera_from_intrinsics(512, 424, [1.0, 2.0], "")


def test_a_matrix_the_camera_would_misread_is_refused() -> None:
    """The core's camera has no skew and takes K[8] as 1: a K that says otherwise is refused, naming the value."""
    k = [365.5, 0.0, 255.5, 0.0, 366.0, 211.5, 0.0, 0.0, 1.0]
    assert _core.camera_from_intrinsics(512, 424, [*k[:1], 0.5, *k[2:]]).fx == 365.5  # 0.29 px: within a pixel
    with pytest.raises(ValueError, match=r"K\[1\] \(skew\) = 2: .* 1.15574 px off; expected \|skew\| < 1.73"):
        _core.camera_from_intrinsics(512, 424, [*k[:1], 2.0, *k[2:]])
    for i, v in ((3, 1.0), (6, 0.5), (7, -2.0), (8, 0.0), (8, 2.0), (8, float("nan"))):
        bad = list(k)
        bad[i] = v
        with pytest.raises(ValueError, match=r"expected a pinhole camera's \[fx s cx; 0 fy cy; 0 0 1\]"):
            _core.camera_from_intrinsics(512, 424, bad)


def test_the_tools_use_them(tmp_path: object) -> None:
    from types import SimpleNamespace

    from kinect_pipeline.bags.messages import camera_from_info, depth_array
    from kinect_pipeline.bags.ros1 import BagError

    header = SimpleNamespace(frame_id="cam")
    ros1 = SimpleNamespace(width=4, height=3, K=[0.0] * 9, header=header)
    ros2 = SimpleNamespace(width=4, height=3, k=[2.0, 0, 1.5, 0, 2.0, 1.0, 0, 0, 1], header=header)
    with pytest.raises(BagError, match=r"K\[0\] \(fx\) = 0"):
        camera_from_info(ros1)
    assert camera_from_info(ros2).fx == 2.0
    img = SimpleNamespace(encoding="bgr8", width=4, height=3, step=12, is_bigendian=0, data=np.zeros(36, np.uint8))
    with pytest.raises(BagError, match="encoding 'bgr8'"):
        depth_array(img)


def test_evaluate_curve_takes_depths_and_arrays() -> None:
    curve = "0.5:0.1, 2:0.4"
    assert _core.evaluate_curve(curve, 1.25) == pytest.approx(0.25)
    np.testing.assert_allclose(_core.evaluate_curve(curve, np.array([0.0, 1.25, 9.0])), [0.1, 0.25, 0.4])
    np.testing.assert_allclose(_core.evaluate_curve([(0.5, 0.1), (2.0, 0.4)], [[0.5, 2.0]]), [[0.1, 0.4]])
