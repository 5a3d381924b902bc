"""The Python contract of issue #2: kp.Camera / kp.Config / kp.Pipeline.process and its Result."""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.simulation.scenes import FIRST_BOX, FLOOR, Scene, boxes_scene, render_frame

HEIGHT, TILT = 1.1, 0.26


@pytest.fixture(scope="module")
def cam() -> kp.Camera:
    return kp.Camera(512, 424, 365.0, 365.0, 255.5, 211.5)


def test_camera_from_fov_matches_the_thesis_numbers() -> None:
    c = kp.Camera.from_fov(512, 424, math.radians(70.6), math.radians(60))
    assert (c.width, c.height) == (512, 424)
    assert c.hfov == pytest.approx(math.radians(70.6))
    assert c.vfov == pytest.approx(math.radians(60))
    assert (c.cx, c.cy) == (255.5, 211.5)


def test_config_fields_are_the_ros_parameter_names() -> None:
    cfg = kp.Config(sensor_height=1.1, sensor_pitch=0.26, ceiling_height=2.0, max_depth=12.0)
    d = cfg.to_dict()
    for name in (
        "sensor_height",
        "sensor_pitch",
        "sensor_roll",
        "ceiling_height",
        "max_depth",
        "geometry",
        "projection",
        "open_kernel_size",
        "open_kernel_shape",
        "threshold_curve",
        "range_min",
        "range_max",
        "scan_beams",
        "confidence_window",
        "confidence_distance",
        "min_intensity",
        "intensity_filter",
    ):
        assert name in d
    assert cfg.geometry == "exact" and cfg.projection == "horizontal"
    cfg.threshold_curve = "1:0.05, 3:0.1"
    assert cfg.threshold_curve == [(1.0, 0.05), (3.0, 0.1)]


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32])
def test_result_has_the_promised_fields(cam: kp.Camera, dtype: type) -> None:
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    depth = np.full((424, 512), 40 if dtype == np.uint8 else (2000 if dtype == np.uint16 else 2.0), dtype=dtype)
    res = pipe.process(depth, base_pitch=0.0, base_roll=0.0)
    assert res.depth.shape == depth.shape and res.depth.dtype == depth.dtype
    assert res.labels.shape == depth.shape and res.labels.dtype == np.uint8
    assert set(np.unique(res.labels)) <= {0, 1, 2, 3, 4}
    assert res.ranges.dtype == np.float32 and res.intensities.dtype == np.float32
    assert len(res.ranges) == len(res.intensities) == 512
    assert res.angle_min < 0 < res.angle_max
    assert res.angle_max == pytest.approx(res.angle_min + 511 * res.angle_increment, rel=1e-5)
    assert res.range_min < res.range_max


def _tf2_roll(mount_pitch: float, base_pitch: float) -> float:
    """The roll of a level mount's optical frame as tf2 composes it: a pitched base, a pitched camera_link, the
    optical frame's fixed rotation (as a URDF and robot_state_publisher give them)."""
    import rospy
    import tf2_py
    from geometry_msgs.msg import TransformStamped

    buf = tf2_py.BufferCore()
    for parent, child, rpy in (
        ("base_footprint", "base_link", (0.0, base_pitch, 0.0)),
        ("base_link", "camera_link", (0.0, mount_pitch, 0.0)),
        ("camera_link", "camera_depth_optical_frame", (-math.pi / 2, 0.0, -math.pi / 2)),
    ):
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = parent, child
        t.transform.translation.z = 0.5
        q = t.transform.rotation
        q.x, q.y, q.z, q.w = _core.quaternion_from_rpy(*rpy)
        buf.set_transform_static(t, "test")
    tr = buf.lookup_transform_core("base_footprint", "camera_depth_optical_frame", rospy.Time(0)).transform
    q, p = tr.rotation, tr.translation
    return _core.pose_from_optical_transform(((q.x, q.y, q.z, q.w), (p.x, p.y, p.z)))[2]


def test_a_level_mount_through_tf_keeps_the_level_paths_and_a_roll_does_not(cam: kp.Camera) -> None:
    rolls = [_tf2_roll(p, b) for p in (0.1, 0.26, 0.5) for b in (0.0, 0.01, -0.05)]
    assert any(r != 0.0 for r in rolls), rolls  # tf2's rounding leaves a roll ...
    assert all(abs(r) < 1e-12 for r in rolls), rolls  # ... that is no roll
    depth = _core.render_scene(cam, HEIGHT, TILT, 0.0, boxes=[[1.5, 1.8, -0.3, 0.3, 0.0, 0.8]])["depth"]
    mm = np.nan_to_num(depth * 1000.0, nan=0.0, posinf=0.0).astype(np.uint16)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    level = pipe.process(mm, base_roll=0.0)
    assert level.level_rows and level.counts["floor"] > 0 and level.counts["kept"] > 0
    for r in rolls:
        res = pipe.process(mm, base_roll=r)
        assert res.level_rows, r
        assert abs(res.pose.roll - r) < 1e-12  # reported as told (no roll added)
        assert np.array_equal(res.labels, level.labels)
    assert not pipe.process(mm, base_roll=0.001).level_rows
    upside_down = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, sensor_roll=math.pi - 1e-9))
    assert upside_down.process(mm[::-1, ::-1].copy()).level_rows


@pytest.mark.parametrize("geometry", ["exact", "thesis"])
def test_noise_free_floor_with_boxes(cam: kp.Camera, geometry: str) -> None:
    """Exact mode removes every floor pixel, keeps every box pixel >= 5 cm above the floor, and the horizontal
    scan matches the rendered ranges within 1 cm (16UC1) in every bin that sees a box."""
    frame = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, geometry=geometry))
    res = pipe.process(frame.depth)
    obj, height = frame.truth["object"], frame.truth["height"]
    floor = obj == FLOOR
    box = (obj >= FIRST_BOX) & (height >= 0.05)
    if geometry == "thesis":
        # The thesis's approximations misplace the floor at a 15 deg tilt: that is why exact is the default.
        assert (res.labels[floor] == kp.LABELS["floor"]).mean() < 0.99
        return
    assert np.all(res.labels[floor] != kp.LABELS["kept"]), "a floor pixel was kept"
    assert np.all(res.labels[box] == kp.LABELS["kept"]), "a box pixel 5 cm or more above the floor was removed"

    n = len(res.ranges)
    angle = frame.truth["angle"]  # NaN where no ray meets the scene
    rel = np.where(np.isfinite(angle), angle - (res.angle_min - res.angle_increment / 2), -1.0)
    idx = np.floor(rel / res.angle_increment).astype(int)
    want = np.full(n, np.inf)
    sel = (obj >= FIRST_BOX) & (idx >= 0) & (idx < n)
    np.minimum.at(want, idx[sel], frame.truth["range"][sel])
    sees_box = np.isfinite(want)
    assert sees_box.sum() > 50
    got = res.ranges.astype(np.float64)
    # Bins are narrower than the pixels near the image centre: a bin holding no centre of the nearest face holds
    # the face's neighbour (the binning fills it) while the centre-binned reference holds what lies behind.
    near = np.minimum(np.roll(want, 1), np.roll(want, -1))
    with np.errstate(invalid="ignore"):  # inf - inf where neither sees a box: NaN, which compares as not equal
        exact = np.abs(got - want) <= 0.01
        ok = exact | ((got < want) & (np.abs(got - near) <= 0.01))
    assert ok[sees_box].all(), f"beams {np.nonzero(sees_box & ~ok)[0][:10]} differ from the rendered ranges"
    assert exact[sees_box].mean() > 0.9


def test_thesis_geometry_stays_reachable_and_differs_from_exact(cam: kp.Camera) -> None:
    frame = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "8UC1", seed=None)
    a = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)).process(frame.depth)
    b = kp.Pipeline(
        cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, geometry="thesis", projection="column")
    ).process(frame.depth)
    assert (a.labels != b.labels).mean() > 0.01


def test_column_projection_is_depth_over_cos(cam: kp.Camera) -> None:
    # A wall facing the level camera at z = 3 m: a column at angle theta_x sees 3 / cos(theta_x). Bins are
    # uniform in angle and columns are not, so a bin takes the nearest of the columns it overlaps.
    depth = np.full((424, 512), 3.0, dtype=np.float32)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=0.0, projection="column", ceiling_height=5.0))
    res = pipe.process(depth)
    beam = res.angle_min + res.angle_increment * np.arange(len(res.ranges))
    np.testing.assert_allclose(res.ranges, 3.0 / np.cos(beam), rtol=3e-3)


def test_predicted_planes_are_exposed(cam: kp.Camera) -> None:
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    pipe.process(np.zeros((424, 512), np.uint16))
    floor, ceiling = pipe.predicted_floor(), pipe.predicted_ceiling()
    assert floor.shape == (424, 512)
    # Row 211 looks half a pixel above the optical axis, which is tilted 15 deg down.
    yn = (211 - cam.cy) / cam.fy
    assert floor[211, 255] == pytest.approx(HEIGHT / (math.sin(TILT) + math.cos(TILT) * yn), rel=1e-5)
    assert np.isinf(ceiling[211, 255])


def test_predicted_planes_before_a_frame_are_refused_not_read_past_their_ends(cam: kp.Camera) -> None:
    """A new pipeline, one whose only frame was refused, and one given a new config have no planes yet: reading
    them crashed the process (SIGSEGV)."""
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    for step in ("new", "refused frame", "new config"):
        if step == "refused frame":
            with pytest.raises(ValueError):
                pipe.process(np.zeros((10, 10), np.uint16))
        if step == "new config":
            pipe.process(np.zeros((424, 512), np.uint16))
            assert pipe.predicted_floor().shape == (424, 512)
            pipe.config = kp.Config(sensor_height=0.5)
        for read in (pipe.predicted_floor, pipe.predicted_ceiling):
            with pytest.raises(RuntimeError, match=r"no planes yet: .* expected process\(\) first"):
                read()
    pipe.process(np.zeros((424, 512), np.uint16))
    assert np.isfinite(pipe.predicted_floor()).any()


def test_non_contiguous_and_negative_strides_give_the_same_answer(cam: kp.Camera) -> None:
    frame = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=3)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    ref = pipe.process(frame.depth)
    big = np.zeros((424 * 2, 512 * 2), np.uint16)
    big[::2, ::2] = frame.depth
    for view in (big[::2, ::2], np.asfortranarray(frame.depth), frame.depth[::-1][::-1]):
        pipe.reset()
        res = pipe.process(view)
        np.testing.assert_array_equal(res.labels, ref.labels)
        np.testing.assert_array_equal(res.ranges, ref.ranges)
    # Row-strided crops are read in place (no copy needed); a crop of a bigger frame works too.
    wide = np.zeros((424, 600), np.uint16)
    wide[:, 40:552] = frame.depth
    pipe.reset()
    np.testing.assert_array_equal(pipe.process(wide[:, 40:552]).labels, ref.labels)


def test_input_is_not_modified(cam: kp.Camera) -> None:
    frame = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "8UC1", seed=4)
    before = frame.depth.copy()
    kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)).process(frame.depth)
    np.testing.assert_array_equal(frame.depth, before)


def test_threads_can_share_a_pipeline_and_release_the_gil(cam: kp.Camera) -> None:
    frame = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "32FC1", seed=5)
    # floor_learn_time 0: nothing learned from frame to frame (the floor profile would move a pixel or two while it
    # converges), so every call gives the first call's labels.
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, floor_learn_time=0.0))
    ref = pipe.process(frame.depth).labels
    out: list[np.ndarray] = []

    def work() -> None:
        for _ in range(5):
            out.append(pipe.process(frame.depth).labels)

    threads = [threading.Thread(target=work) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=60)
    assert len(out) == 15
    for labels in out:
        np.testing.assert_array_equal(labels, ref)


@pytest.mark.parametrize(
    ("depth", "exc", "match"),
    [
        (np.zeros((424, 512), np.float64), TypeError, "float64"),
        (np.zeros((424, 512), np.int32), TypeError, "int32"),
        ([[1, 2], [3, 4]], TypeError, "numpy array"),
        (np.zeros(512, np.uint16), ValueError, "1-D"),
        (np.zeros((424, 512, 3), np.uint8), ValueError, "3-D"),
        (np.zeros((0, 512), np.uint16), ValueError, "empty"),
        (np.zeros((480, 640), np.uint16), ValueError, "640x480"),
    ],
)
def test_bad_input_is_refused_clearly(cam: kp.Camera, depth: object, exc: type, match: str) -> None:
    pipe = kp.Pipeline(cam, kp.Config())
    with pytest.raises(exc, match=match):
        pipe.process(depth)
    pipe.process(np.zeros((424, 512), np.uint16))  # still serves good frames


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"sensor_height": -1.0}, ValueError, "sensor_height"),
        ({"ceiling_height": 0.5}, ValueError, "ceiling_height"),
        ({"geometry": "approx"}, ValueError, "geometry"),
        ({"projection": "radial"}, ValueError, "projection"),
        ({"open_kernel_size": 4}, ValueError, "open_kernel_size"),
        ({"threshold_curve": [(1.0, 0.1)]}, ValueError, "at least 2"),
        ({"threshold_curve": [(2.0, 0.1), (1.0, 0.2)]}, ValueError, "increasing"),
        ({"threshold_curve": "1:0.1, 2:oops"}, ValueError, "oops"),
        ({"no_such_field": 1}, TypeError, "no_such_field"),
        # an int its C++ field cannot hold was "expected an integer"; True was taken as 1
        (
            {"open_kernel_size": 2**40},
            ValueError,
            r"open_kernel_size = 1\.09951e\+12: expected an integer in \[0, 31\]",
        ),
        ({"open_kernel_size": -(2**70)}, ValueError, r"open_kernel_size = -1\.18059e\+21: expected an integer in"),
        ({"open_kernel_size": True}, TypeError, r"open_kernel_size = True \(bool\): expected an integer"),
    ],
)
def test_bad_config_is_refused_naming_the_field(kwargs: dict, exc: type, match: str) -> None:
    with pytest.raises(exc, match=match):
        kp.Config(**kwargs)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((0, 424, 365.0, 365.0, 1.0, 1.0), "width"),
        ((512, 424, 0.0, 365.0, 1.0, 1.0), "fx"),
        ((512, 424, math.nan, 365.0, 1.0, 1.0), "fx"),
    ],
)
def test_bad_camera_is_refused(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        kp.Camera(*args)


def test_a_field_of_view_giving_no_usable_focal_length_is_named() -> None:
    """It named the fx it gave, not the hfov the caller passed."""
    with pytest.raises(ValueError, match=r"^Camera\.from_fov: hfov = 1e-09, vfov = 0\.5 rad over 512x424 px: .*fx"):
        kp.Camera.from_fov(512, 424, 1e-9, 0.5)
    assert kp.Camera.from_fov(512, 424, 1.2, 1.0).fx == pytest.approx(256 / math.tan(0.6))


def test_confidence_of_a_beam_that_appears(cam: kp.Camera) -> None:
    """A beam that was +Inf gets intensity 1 when an obstacle appears: reported at once, never held back."""
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, intensity_filter=True))
    empty = render_frame(cam, Scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None)
    full = render_frame(cam, boxes_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None)
    for _ in range(3):
        r0 = pipe.process(empty.depth)
    assert not np.isfinite(r0.ranges).any()
    r1 = pipe.process(full.depth)
    seen = np.isfinite(r1.ranges)
    assert seen.sum() > 50
    assert np.all(r1.intensities[seen] == 1.0)


def _bad_states(st: tuple) -> list[tuple[tuple, str]]:
    n = 16  # the profile's bands
    return [
        ((0.2, *st[1:]), r"learned height = 0\.2: expected finite, within the config's floor_max_height_error 0\.08"),
        ((math.nan, *st[1:]), "learned height = nan"),
        ((*st[:3], math.inf, *st[4:]), "last stamp = inf"),
        ((*st[:4], -1.0, *st[5:]), "weight of the learned height = -1"),
        ((*st[:7], *(math.nan,) * n, *st[7 + n :]), "profile bias 0 = nan"),
        ((*st[:7], 1e40, *st[8:]), "profile bias 0 = inf"),
        ((*st[: 7 + n], -1.0, *st[8 + n :]), "profile weight 0 = -1"),
        ((*st[:-1], math.nan), "time since the profile learned = nan"),
    ]


def test_a_floor_state_the_config_cannot_hold_is_refused_and_the_old_one_kept(cam: kp.Camera) -> None:
    """NaN, out-of-bounds or negative values were taken as they were and spoilt every later frame (a NaN profile:
    no floor pixel in any frame; a learned height of 0.2 m past its 0.08 m bound applied as it was)."""
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    frame = kp.encode_depth(kp.render_scene(cam, HEIGHT, TILT, 0.0)["depth"], "16UC1", 12.0)
    pipe.process(frame, stamp=0.0)
    good = pipe.floor_state
    assert len(good) == 8 + 2 * 16
    for bad, says in _bad_states(good):
        with pytest.raises(ValueError, match=rf"^floor state: {says}"):
            pipe.floor_state = bad
        assert pipe.floor_state == good, "a refused state leaves the one there"
    with pytest.raises(TypeError, match=r"floor_state\[2\] = 'x' \(str\): expected a number"):
        pipe.floor_state = (*good[:2], "x", *good[3:])
    pipe.floor_state = good
    assert (pipe.process(frame, stamp=0.1).labels == kp.LABELS["floor"]).any()


@pytest.mark.parametrize(
    ("call", "says"),
    [
        (lambda: kp.Config(sensor_model=None), r"Config\.sensor_model = None \(NoneType\): expected a sensor preset"),
        (lambda: kp.Config(cliff_scan=None), r"Config\.cliff_scan = None \(NoneType\): expected True or False"),
        (lambda: kp.Config(refine_floor=0.5), r"Config\.refine_floor = 0\.5 \(float\): expected True or False"),
        (lambda: kp.Config(intensity_filter=1), r"Config\.intensity_filter = 1 \(int\): expected True or False"),
    ],
)
def test_a_flag_or_a_name_of_another_type_is_refused_naming_it(call: Any, says: str) -> None:
    """A flag took any truth value (None: False, 0.5: True); a sensor_model of None was an unnamed RuntimeError."""
    with pytest.raises(TypeError, match=says):
        call()
    assert kp.Config(cliff_scan=np.bool_(True)).cliff_scan is True
    cam = kp.Camera(64, 48, 60.0, 60.0, 32.0, 24.0)
    for bad in (None, 1):  # the reference paths' switch and the renderer's floor: True or False only too
        with pytest.raises(TypeError, match="incompatible"):
            kp.Pipeline(cam, kp.Config(), reference_paths=bad)
        with pytest.raises(TypeError, match="incompatible"):
            kp.render_scene(cam, 1.0, 0.3, 0.0, floor=bad)


def test_a_stamp_that_is_not_a_number_is_refused_naming_it(cam: kp.Camera) -> None:
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT))
    frame = np.zeros((424, 512), np.uint16)
    for stamp in ("1.0", [1.0]):
        with pytest.raises(TypeError, match=r"^stamp = .*: expected a number"):
            pipe.process(frame, stamp=stamp)
    pipe.process(frame, stamp=np.float64(1.0))


@pytest.mark.parametrize(
    ("call", "exc", "says"),
    [
        (lambda c: kp.evaluate_curve(c, None), TypeError, r"depth = None \(NoneType\): expected a number"),
        (lambda c: kp.evaluate_curve(c, math.nan), ValueError, "depth = nan: expected a depth"),
        (lambda c: kp.evaluate_curve(c, [1.0, math.nan]), ValueError, r"depth \[1\] = nan"),
        (lambda c: kp.threshold_lut(c, "8UC1", math.nan), ValueError, r"Config\.max_depth = nan: expected a value in"),
        (lambda c: kp.threshold_lut(c, "16UC1", math.inf), ValueError, r"Config\.max_depth = inf"),
        (lambda c: kp.encode_depth(np.ones((2, 2), np.float32), "8UC1", -1.0), ValueError, r"max_depth = -1"),
        (lambda c: kp.add_kinect_noise(np.ones((2, 2), np.float32), 1, sigma0=math.nan), ValueError, "sigma0 = nan"),
        (lambda c: kp.add_kinect_noise(np.ones((2, 2), np.float32), 1, dropout=1.5), ValueError, "dropout = 1.5"),
        (lambda c: kp.render_scene(kp.kinect_v2_camera(), -1.0, 0.3, 0.0), ValueError, "height = -1"),
        (lambda c: kp.render_scene(kp.kinect_v2_camera(), 1.0, 3.0, 0.0), ValueError, "pitch = 3"),
        (
            lambda c: kp.Pipeline(kp.kinect_v2_camera(), kp.Config(geometry="thesis")).process(
                np.ones((424, 512), np.float32), 0.0, 2.0
            ),
            ValueError,
            r"pose: roll \(sensor \+ base\) = 2 rad with geometry 'thesis': expected \|roll\| <= pi/2",
        ),
        (lambda c: kp.morph_open(np.array([[1, np.nan, 1]] * 3, np.float32), 3), ValueError, "NaN at row 0, column 1"),
        (
            lambda c: kp.encode_compressed_depth(np.ones((2, 2), np.float32), depth_quantization=1e6),
            ValueError,
            "depth_quantization = 1e\\+06: expected 1 to 150",
        ),
    ],
)
def test_the_tool_functions_refuse_values_that_give_nothing_usable(call: Any, exc: type, says: str) -> None:
    """Each returned NaN, negative depths, all-0 images, moved NaN pixels or data 16 bits could not hold."""
    with pytest.raises(exc, match=says):
        call(kp.default_threshold_curve())
    assert kp.evaluate_curve(kp.default_threshold_curve(), [1.0, math.inf]).shape == (2,)


@pytest.mark.parametrize(
    "tool",
    [
        lambda d: kp.add_kinect_noise(d, 1),
        lambda d: _core.add_tof_artefacts(d, 1),
        lambda d: _core.add_stereo_artefacts(d, 1),
        lambda d: _core.calibrate_from_floor(d, kp.kinect_v2_camera()),
        lambda d: _core.band_scan(d, kp.kinect_v2_camera()),
    ],
)
def test_the_metre_tools_refuse_integer_and_double_depths_naming_the_dtype(tool: Any) -> None:
    """A uint16 frame was taken as float32 silently: 1500 mm became 1500 m. A float64 one is not narrowed."""
    with pytest.raises(TypeError, match=r"^depth: a uint16 array: expected float32 metres .* / 1000"):
        tool(np.full((424, 512), 1500, np.uint16))
    with pytest.raises(TypeError, match=r"^depth: a float64 array: expected float32 metres"):
        tool(np.full((424, 512), 1.5))
    scene = kp.render_scene(kp.kinect_v2_camera(), 1.0, 0.3, 0.0)["depth"]
    tool(np.ascontiguousarray(scene[:, ::-1]))  # float32 metres, any layout


def test_a_compressed_depth_header_with_a_negative_quantisation_is_refused() -> None:
    """depthQuantA = -1 decoded every pixel to a negative depth, as if valid."""
    import struct

    fmt, data = kp.encode_compressed_depth(np.full((4, 4), 2.0, np.float32))
    bad = data[:4] + struct.pack("<f", -1.0) + data[8:]
    with pytest.raises(ValueError, match=r"depthQuantA = -1, .*expected finite values and depthQuantA > 0"):
        kp.decode_compressed_depth(fmt, bad)
