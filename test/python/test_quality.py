"""Default parameters on noisy Kinect-v2-like frames at a correctly known pose (issue #2's numbers)."""

from __future__ import annotations

import math

import pytest

import kinect_pipeline as kp
from kinect_pipeline.evaluation.metrics import frame_quality
from kinect_pipeline.simulation.scenes import lab_scene, render_frame

# Base pitch up to +-6 deg, roll 2 deg, on a sensor tilted down 15 deg at 1.1 m, and a low, level one.
CONDITIONS = [
    (1.1, math.radians(15), math.radians(6), math.radians(2)),
    (1.1, math.radians(15), -math.radians(6), math.radians(2)),
    (1.1, math.radians(15), 0.0, -math.radians(2)),
    (0.5, math.radians(2), math.radians(6), math.radians(2)),
    (0.5, math.radians(2), -math.radians(6), -math.radians(2)),
]


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1", "32FC1"])
@pytest.mark.parametrize(("height", "tilt", "base_pitch", "base_roll"), CONDITIONS)
def test_default_quality_on_noisy_frames(
    encoding: str, height: float, tilt: float, base_pitch: float, base_roll: float
) -> None:
    cam = kp.kinect_v2_camera()
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=height, sensor_pitch=tilt))
    seed = int(1000 * (height + tilt + base_pitch + base_roll)) % 9973
    frame = render_frame(cam, lab_scene(), height, tilt + base_pitch, base_roll, encoding, seed=seed)
    q = frame_quality(pipe.process(frame.depth, base_pitch, base_roll), frame)
    assert q.floor_pixels > 10000 and q.obstacle_pixels > 10000
    assert q.floor_removed >= 0.995, q
    assert q.obstacles_kept >= 0.99, q
    if q.above_ceiling_pixels > 500:
        assert q.above_ceiling_removed >= 0.99, q
    assert q.phantom_beams <= 0.002, q


def test_the_quality_check_can_fail() -> None:
    """The same frame at a wrong pose (configured 2 deg too level), without the floor refinement that would correct
    it, must fail the floor check: the metric has teeth. (Too steep would label the floor "below floor", which also
    removes it.)"""
    cam = kp.kinect_v2_camera()
    tilt = math.radians(15)
    pipe = kp.Pipeline(cam, kp.Config(sensor_height=1.1, sensor_pitch=tilt - math.radians(2), refine_floor=False))
    frame = render_frame(cam, lab_scene(), 1.1, tilt, 0.0, "16UC1", seed=7)
    q = frame_quality(pipe.process(frame.depth), frame)
    assert q.floor_removed < 0.995


def test_surface_band_meets_the_phantom_goal_where_the_nearest_pixel_does_not() -> None:
    """Issue #4's goal on the quality table's ground truth (every pitch condition): with surface_band 1 the floor is
    removed, obstacles kept, phantom beams <= 0.2 % and missed beams <= 1 %; the nearest-pixel default has the far
    wall's noise tail as phantoms (so the comparison has teeth)."""
    from kinect_pipeline.evaluation.quality import evaluate

    rows = evaluate(frames=3)
    by = {(r.condition, r.variant): r for r in rows}
    for condition in ("static", "oscillating", "jerks"):
        band = by[(condition, "exact, horizontal, surface_band 1")]
        assert band.floor_removed >= 0.995, band  # fractions
        assert min(band.kept) >= 0.99, band
        assert band.phantom <= 0.002, band
        assert band.missed <= 0.01, band
        nearest = by[(condition, "exact, horizontal (default)")]
        assert nearest.phantom > 0.01, nearest
        assert band.range_error_cm <= nearest.range_error_cm, (band, nearest)
