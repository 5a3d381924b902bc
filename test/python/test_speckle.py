"""speckle_jump: a stereo camera's wrong matches (tiny islands nearer than everything around them) taken as no
measurement before the opening, which would keep them; thin real things stay."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline import _core
from kinect_pipeline.evaluation.metrics import frame_quality
from kinect_pipeline.evaluation.real_floors import (
    DEG,
    ROBOT_SCENES,
    RS_CAM,
    calibrated_config,
    shared_realsense_frames,
)
from kinect_pipeline.simulation.scenes import render_frame

CAM = kp.Camera(120, 80, 100.0, 100.0, 59.5, 39.5)
REAL = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "real")


def _wall(encoding: str, things: list[tuple[int, int, int, int, float]]) -> np.ndarray:
    """A wall 3 m ahead of a level camera at 1.1 m, with (row, col, rows, cols, depth [m]) patches in front of it,
    in the rows that see it between the floor and the 2 m ceiling plane."""
    z = np.full((CAM.height, CAM.width), 3.0, np.float32)
    for r, c, nr, nc, d in things:
        z[r : r + nr, c : c + nc] = d
    if encoding == "16UC1":
        return np.round(z * 1000).astype(np.uint16)
    if encoding == "8UC1":
        return np.round(z / 12.0 * 255).astype(np.uint8)
    return z


def _nearest(depth: np.ndarray, jump: float) -> tuple[float, int]:
    cfg = kp.Config(sensor_height=1.1, ceiling_height=2.0, speckle_jump=jump, refine_floor=False)
    res = kp.Pipeline(CAM, cfg).process(depth)
    return float(np.nanmin(res.ranges)), res.speckles


@pytest.mark.parametrize("encoding", ["8UC1", "16UC1", "32FC1"])
def test_a_wrong_match_goes_and_thin_things_stay(encoding: str) -> None:
    blob = _wall(encoding, [(20, 60, 2, 2, 1.0)])  # 2 x 2 pixels 2 m in front of the wall
    off, none = _nearest(blob, 0.0)
    on, removed = _nearest(blob, 0.125)
    assert off < 1.05 and none == 0, "without the filter the opening keeps the blob"
    assert on > 2.8 and removed == 4, (on, removed)
    # A pole one pixel wide, a bar one pixel high and a 3 x 3 box: real, and kept.
    for thing in [(10, 30, 25, 1, 1.5), (25, 40, 1, 12, 1.5), (20, 70, 3, 3, 1.5)]:
        depth = _wall(encoding, [thing])
        near, _ = _nearest(depth, 0.125)
        assert near == _nearest(depth, 0.0)[0] and near < 1.6, (thing, near)


def test_noise_and_edges_are_not_wrong_matches() -> None:
    # A rendered lab frame with a Kinect's noise: nothing is an island 12.5 % in front of its surroundings.
    fr = render_frame(kp.kinect_v2_camera(), ROBOT_SCENES["lab"](), 1.1, 0.26, 0.0, "16UC1", seed=3)
    cfg = kp.Config(sensor_pitch=0.26, speckle_jump=0.125)
    res = kp.Pipeline(kp.kinect_v2_camera(), cfg).process(fr.depth)
    ref = kp.Pipeline(kp.kinect_v2_camera(), kp.Config(sensor_pitch=0.26)).process(fr.depth)
    assert res.speckles < 10, res.speckles
    np.testing.assert_array_equal(np.isfinite(res.ranges), np.isfinite(ref.ranges))
    assert np.nanmax(np.abs(res.ranges - ref.ranges)) < 0.01


def test_off_by_default_and_a_bad_value_named() -> None:
    assert kp.Config().speckle_jump == 0.0
    with pytest.raises(ValueError, match="speckle_jump"):
        kp.Config(speckle_jump=-0.1)


def _stereo_robot(jump: float) -> tuple[float, float, float]:
    """The stereo robot 1.4 m high, 20 deg down, told 5 cm / 1 deg off: worst phantom beams, least floor removed
    (< 4 m), least obstacle pixels kept, over 12 frames of the furniture scene."""
    h, p = 1.4, 20 * DEG
    cfg = kp.Config(
        sensor_model="realsense_d4xx",
        sensor_height=h + 0.05,
        sensor_pitch=p + DEG,
        sensor_roll=-DEG,
        ceiling_height=2.0,
        speckle_jump=jump,
    )
    pipe = kp.Pipeline(RS_CAM, cfg)
    phantom, floor, kept = 0.0, 1.0, 1.0
    for i in range(12):
        rock = DEG * math.sin(2 * math.pi * i / 17)
        fr = render_frame(RS_CAM, ROBOT_SCENES["furniture"](), h, p + rock, rock, "16UC1", seed=i, stereo=True)
        q = frame_quality(
            pipe.process(fr.depth, rock, rock, stamp=i / 10), fr, floor_radius=4.0, sigma=_core.stereo_sigma
        )
        phantom, floor, kept = max(phantom, q.phantom_beams), min(floor, q.floor_removed), min(kept, q.obstacles_kept)
    return phantom, floor, kept


def test_a_high_stereo_camera_loses_its_phantoms_and_nothing_else() -> None:
    off, on = _stereo_robot(0.0), _stereo_robot(0.125)
    assert off[0] > 0.015, "the rendered wrong matches make phantoms without the filter"
    assert on[0] <= 0.01, on
    assert on[1] >= off[1] - 1e-4 and on[1] >= 0.995, (on, off)
    assert on[2] >= off[2] - 1e-3, (on, off)


@pytest.mark.skipif(not os.path.isdir(os.path.join(REAL, "realsense_lowcam")), reason="no ../shared real frames")
def test_real_stereo_frames_keep_their_floor_and_show_no_cliff() -> None:
    frames = shared_realsense_frames(os.path.join(REAL, "realsense_lowcam"))
    seen = 0
    for depth in frames:
        cfg = calibrated_config(depth, min_floor=0.2)
        if cfg is None:
            continue
        assert cfg.speckle_jump == 0.125, "the stereo preset's"
        res = kp.Pipeline(RS_CAM, cfg).process(depth)
        cfg.speckle_jump = 0.0
        ref = kp.Pipeline(RS_CAM, cfg).process(depth)
        seen += res.speckles
        assert not np.isfinite(res.cliff_ranges).any()
        assert res.counts["floor"] >= 0.999 * ref.counts["floor"], (res.counts, ref.counts)
        # At most a few beams move, and only farther (a wrong match no longer sets them).
        moved = np.isfinite(ref.ranges) & (~np.isfinite(res.ranges) | (res.ranges > ref.ranges + 0.10))
        assert moved.mean() <= 0.01 and not (res.ranges < ref.ranges - 0.10).any()
    assert seen > 0, "the real frames hold wrong matches"
