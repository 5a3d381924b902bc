"""Negative obstacles (cliff_scan, cliff_in_scan) on generated stairs and holes, and never on a flat floor while
the Segway pitches, in every encoding."""

from __future__ import annotations

import math

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.simulation.robot import SegwayMotion
from kinect_pipeline.simulation.scenes import ENCODINGS, Scene, hole_scene, render_frame, stair_scene

CAM = kp.Camera.from_fov(512, 424, math.radians(70.6), math.radians(60.0))
HEIGHT, TILT = 1.1, 0.3


def angles(res: kp.Result) -> np.ndarray:
    return res.angle_min + res.angle_increment * np.arange(len(res.ranges))


@pytest.mark.parametrize("encoding", list(ENCODINGS))
def test_a_stair_down_stops_the_robot_before_it(encoding: str) -> None:
    edge, step = 2.5, 0.17
    motion = SegwayMotion()
    for i in (0, 10, 21, 30):
        bp = motion.pitch(i)
        frame = render_frame(CAM, stair_scene(edge, step), HEIGHT, TILT + bp, 0.0, encoding, seed=i, tof=True)
        cfg = kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, cliff_in_scan=True)
        res = kp.Pipeline(CAM, cfg).process(frame.depth, bp)
        a = angles(res)
        ahead = np.abs(a) < 0.2  # clear of the box on the left
        cliff = res.cliff_ranges[ahead]
        assert np.isfinite(cliff).all(), f"frame {i}: {np.count_nonzero(~np.isfinite(cliff))} beams see no cliff"
        # The lower level shows from where the ray over the edge meets it: edge / cos * (h + step) / h.
        rim = edge / np.cos(a[ahead])
        first = rim * (HEIGHT + step) / HEIGHT
        tol = 0.15 if encoding == "8UC1" else 0.08
        assert (cliff > rim - tol).all() and (cliff < first + tol).all(), (
            f"frame {i}: cliff {cliff.min():.2f}..{cliff.max():.2f} m, expected {rim.min():.2f}..{first.max():.2f} m"
        )
        # In the scan as obstacles: never farther than the cliff, and the cliff itself where nothing stands nearer.
        assert (res.ranges[ahead] <= cliff).all()
        assert (res.ranges[ahead] == cliff).mean() > 0.95
        # Without cliff_in_scan the scan is free ahead (the floor ends, nothing stands there).
        plain = kp.Pipeline(CAM, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)).process(frame.depth, bp)
        assert np.isposinf(plain.ranges[ahead]).mean() > 0.95
        np.testing.assert_array_equal(plain.cliff_ranges, res.cliff_ranges)


@pytest.mark.parametrize("encoding", list(ENCODINGS))
def test_a_hole_shows_in_its_beams_only(encoding: str) -> None:
    frame = render_frame(CAM, hole_scene(), HEIGHT, TILT, 0.0, encoding, seed=3)
    res = kp.Pipeline(CAM, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT)).process(frame.depth, 0.0)
    a = angles(res)
    # The hole spans y -0.2..0.6 at x 2.0..2.6: bearings from atan2(-0.2, 2.0) to atan2(0.6, 2.0).
    inside = (a > math.atan2(-0.2, 2.0) + 0.03) & (a < math.atan2(0.6, 2.6) - 0.03)
    outside = (a < math.atan2(-0.2, 2.6) - 0.03) | (a > math.atan2(0.6, 2.0) + 0.03)
    assert np.isfinite(res.cliff_ranges[inside]).all()
    r = res.cliff_ranges[inside]
    assert (r > 2.0).all() and (r < 2.9).all(), (r.min(), r.max())
    assert not np.isfinite(res.cliff_ranges[outside]).any()
    # The hole is not in the scan (cliff_in_scan is off by default): at most a stray noisy floor pixel is.
    assert np.isfinite(res.ranges[inside]).mean() < 0.05


@pytest.mark.parametrize("encoding", list(ENCODINGS))
def test_a_flat_floor_never_fires_while_the_segway_pitches(encoding: str) -> None:
    motion = SegwayMotion()
    fired_static_tilt = 0
    for i in range(0, 45, 3):
        bp = motion.pitch(i)
        roll = 0.02 * math.sin(0.3 * i)
        frame = render_frame(CAM, Scene(), HEIGHT, TILT + bp, roll, encoding, seed=100 + i, tof=True)
        cfg = kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, cliff_in_scan=True)
        res = kp.Pipeline(CAM, cfg).process(frame.depth, bp, roll)
        assert not np.isfinite(res.cliff_ranges).any(), f"frame {i}, base pitch {math.degrees(bp):.1f} deg"
        assert res.counts["below_floor"] < 20, res.counts
        # Ignoring the base pitch (a static tilt): the floor looks lower than predicted when the base pitches up.
        static = kp.Pipeline(CAM, cfg).process(frame.depth, 0.0, roll)
        fired_static_tilt += bool(np.isfinite(static.cliff_ranges).any())
    assert fired_static_tilt > 0, "the comparison shows nothing: pitch compensation would not matter"


def test_cliff_options_are_validated_and_can_be_turned_off() -> None:
    with pytest.raises(ValueError, match="cliff_min_pixels = 0"):
        kp.Config(cliff_min_pixels=0).validate()
    frame = render_frame(CAM, hole_scene(), HEIGHT, TILT, 0.0, "16UC1", seed=None)
    off = kp.Pipeline(CAM, kp.Config(sensor_height=HEIGHT, sensor_pitch=TILT, cliff_scan=False)).process(frame.depth)
    assert off.cliff_ranges.size == 0
    assert off.counts["below_floor"] > 0
