"""kinect-pipeline calibrate FILE... --intrinsics FX FY CX CY --json"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.cli import main
from kinect_pipeline.simulation.scenes import FLOOR, lab_scene, render_frame

cv2 = pytest.importorskip("cv2")
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CAM = kp.kinect_v2_camera()
INTR = [str(CAM.fx), str(CAM.fy), str(CAM.cx), str(CAM.cy)]


def run_cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, dict, str]:
    rc = main(["calibrate", *args, "--json"])
    out = capsys.readouterr()
    return rc, json.loads(out.out) if out.out.strip() else {}, out.err


@pytest.mark.parametrize("fmt", ["png16", "npy_float", "npy_uint8"])
@pytest.mark.parametrize(("height", "pitch", "roll"), [(1.1, 0.26, 0.0), (0.6, 0.05, 0.03), (1.4, 0.45, -0.02)])
def test_recovers_the_true_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], fmt: str, height: float, pitch: float, roll: float
) -> None:
    enc = {"png16": "16UC1", "npy_float": "32FC1", "npy_uint8": "8UC1"}[fmt]
    f = render_frame(CAM, lab_scene(), height, pitch, roll, enc, seed=21)
    assert (f.truth["object"] == FLOOR).mean() >= 0.15
    path = tmp_path / ("frame.png" if fmt == "png16" else "frame.npy")
    if fmt == "png16":
        assert cv2.imwrite(str(path), f.depth)
    else:
        np.save(path, f.depth)
    rc, d, _ = run_cli(capsys, str(path), "--intrinsics", *INTR)
    assert rc == 0 and d["found"]
    assert abs(d["height"] - height) <= 0.01
    assert abs(math.degrees(d["pitch"] - pitch)) <= 0.2
    assert abs(math.degrees(d["roll"] - roll)) <= 0.2
    assert 0.15 <= d["floor_fraction"] <= 1.0
    assert f"sensor_height:={d['height']:.4f}" in d["launch_args"]


def test_plot_shows_the_floor_under_the_calibrated_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = render_frame(CAM, lab_scene(), 1.1, 0.26, 0.0, "16UC1", seed=7)
    path, png = tmp_path / "f.png", tmp_path / "plot.png"
    cv2.imwrite(str(path), f.depth)
    rc, d, _ = run_cli(capsys, str(path), "--intrinsics", *INTR, "--plot", str(png))
    assert rc == 0 and d["found"]
    img = cv2.imread(str(png))
    assert img is not None and img.shape[0] > 300 and img.shape[1] > 900
    # The floor colour of the label panel covers about the floor fraction the calibration reports.
    green = (img[:, :, 1] > 150) & (img[:, :, 0] < 80) & (img[:, :, 2] < 80)
    assert green.any()


def test_several_frames_average(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    paths = []
    for i in range(3):
        f = render_frame(CAM, lab_scene(), 1.1, 0.26, 0.0, "16UC1", seed=100 + i)
        paths.append(str(tmp_path / f"f{i}.png"))
        cv2.imwrite(paths[-1], f.depth)
    rc, d, _ = run_cli(capsys, *paths, "--intrinsics", *INTR)
    assert rc == 0 and len(d["frames"]) == 3
    assert abs(d["height"] - 1.1) <= 0.01 and d["height_std"] < 0.01


REAL_FRAMES = [
    ("tum_nyu_sun_open3d/NYU_depth_mm.png", (582.6, 582.7, 313.0, 238.4), 0.001),
    ("tum_nyu_sun_open3d/SUN_depth_mm.png", (525.0, 525.0, 319.5, 239.5), 0.001),
    ("tum_nyu_sun_open3d/TUM_depth.png", (525.0, 525.0, 319.5, 239.5), 0.0002),
    ("slambook2/ch5/rgbd/depth/1.pgm", (518.0, 519.0, 325.5, 253.5), 0.001),
    ("slambook2/ch7/1_depth.png", (520.9, 521.0, 325.1, 249.7), 0.0002),
]


@pytest.mark.parametrize(("name", "intr", "scale"), REAL_FRAMES)
def test_real_frames_with_a_floor_give_a_plausible_pose(
    capsys: pytest.CaptureFixture[str], name: str, intr: tuple, scale: float
) -> None:
    path = REAL / name
    if not path.exists():
        pytest.skip(f"{path} not available")
    rc, d, _ = run_cli(capsys, str(path), "--intrinsics", *map(str, intr), "--depth-scale", str(scale))
    assert rc == 0 and d["found"], d
    assert 0.4 <= d["height"] <= 2.0
    assert -10 <= math.degrees(d["pitch"]) <= 40
    assert abs(math.degrees(d["roll"])) <= 10
    assert d["floor_fraction"] >= 0.05


def test_frame_without_floor_says_so(capsys: pytest.CaptureFixture[str]) -> None:
    path = REAL / "mrpt_no_floor" / "obs000_depth_mm.png"
    if not path.exists():
        pytest.skip(f"{path} not available")
    rc, d, err = run_cli(capsys, str(path), "--intrinsics", "572.88", "542.74", "314.65", "240.16")
    assert rc == 1
    assert d["found"] is False
    assert "no floor found" in err and "no floor found" in d["message"]


def test_bad_files_are_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["calibrate", str(tmp_path / "none.png"), "--intrinsics", *INTR])
    assert rc == 1 and "none.png: no such file" in capsys.readouterr().err
    bad = tmp_path / "rgb.png"
    cv2.imwrite(str(bad), np.zeros((10, 10, 3), np.uint8))
    rc = main(["calibrate", str(bad), "--intrinsics", *INTR])
    assert rc == 1 and "single-channel" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["calibrate", "curve"])
def test_frames_in_other_units_than_read_are_refused_naming_the_scale(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: str
) -> None:
    """A wrong --depth-scale gave "no floor found" (1e9) or a floor at a scaled height; float millimetres too."""
    mm = tmp_path / "mm.png"
    cv2.imwrite(str(mm), np.full((48, 64), 1500, np.uint16))
    npy = tmp_path / "mm.npy"
    np.save(npy, np.full((48, 64), 1500.0, np.float32))
    for frame, scale, says in (
        (mm, "1e9", "a median depth of 1.5e+12 m (uint16 at --depth-scale 1e+09 m): expected 0.05 to 100 m"),
        (mm, "1e-6", "a median depth of 0.0015 m (uint16 at --depth-scale 1e-06 m)"),
        (npy, "0.001", "a median depth of 1.5e+03 m (float32 read as metres)"),
    ):
        assert main([command, str(frame), "--intrinsics", *INTR, "--depth-scale", scale]) == 1
        assert says in capsys.readouterr().err
    assert main(["calibrate", str(mm), "--intrinsics", *INTR, "--json"]) == 1  # 1.5 m: read, no floor in it
    assert "no floor found" in capsys.readouterr().err


# -- calibrate --bag: the tf-provided pose of a moving base against the floor seen in each frame ----------------


@pytest.fixture(scope="module")
def tf_bags(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Segway bags (pitching -3..+6 deg) whose tf is right, and whose URDF states the mount 1 deg too far down and
    5 cm too high, and one with a 0.5 deg roll error, in two encodings."""
    pytest.importorskip("rosbags")
    from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag

    d = tmp_path_factory.mktemp("tfbags")
    out = {}
    for name, err, enc in (
        ("ok", (0.0, 0.0, 0.0), "16UC1"),
        ("pitch_height", (0.05, math.radians(1.0), 0.0), "16UC1"),
        ("roll_8bit", (0.0, 0.0, math.radians(-0.5)), "8UC1"),
    ):
        out[name] = d / f"{name}.bag"
        write_sequence_bag(out[name], Scenario(frames=16, encoding=enc, seed=4, tf_error=err))
    return out


def _check(capsys: pytest.CaptureFixture[str], bag: Path, *extra: str) -> dict:
    rc = main(["calibrate", "--bag", str(bag), "--json", *extra])
    out = capsys.readouterr()
    assert rc == 0, out.err
    return json.loads(out.out)


@pytest.mark.parametrize(
    ("name", "height", "pitch_deg", "roll_deg"),
    [("ok", 0.0, 0.0, 0.0), ("pitch_height", 0.05, 1.0, 0.0), ("roll_8bit", 0.0, 0.0, -0.5)],
)
def test_bag_check_recovers_a_known_tf_error(
    tf_bags: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    height: float,
    pitch_deg: float,
    roll_deg: float,
) -> None:
    plot = tmp_path / "tf.png"
    d = _check(capsys, tf_bags[name], "--plot", str(plot))
    s = d["summary"]
    assert s["frames"] == 16 and s["frames_with_floor"] == 16
    assert s["height"]["median"] == pytest.approx(height, abs=0.01)
    assert math.degrees(s["pitch"]["median"]) == pytest.approx(pitch_deg, abs=0.2)
    assert math.degrees(s["roll"]["median"]) == pytest.approx(roll_deg, abs=0.2)
    # A constant error: every frame shows it, whatever the base's pitch is doing.
    assert s["height"]["p95_abs"] <= abs(height) + 0.01 and s["height"]["max_abs"] >= s["height"]["p95_abs"]
    assert math.degrees(s["pitch"]["p95_abs"]) <= abs(pitch_deg) + 0.2
    tf_pitch = [f["tf_pitch"] for f in d["frames"]]
    assert math.degrees(max(tf_pitch) - min(tf_pitch)) > 3, "the base pitched"
    for f in d["frames"]:
        assert f["diff_pitch"] == pytest.approx(f["tf_pitch"] - f["floor_pitch"])
    assert plot.stat().st_size > 20000


def test_bag_check_of_an_upside_down_camera_has_no_jump_at_180_deg(tmp_path: Path) -> None:
    """A camera mounted upside down: tf's roll and the floor's lie either side of +-180 deg. The floor's median
    roll is near 180 (not their plain median, about 0), and the plotted rolls are one run, not two lines a turn
    apart; the disagreement is the wrapped difference."""
    from kinect_pipeline.tools.calibrate import TfCheck, on_one_turn, plot_tf_check

    deg = math.radians
    frames = []
    for i in range(6):
        tf_roll = deg(179.8) if i % 3 else deg(-179.9)
        floor_roll = deg(-179.7) if i % 2 else deg(179.9)  # three each side: their plain median is 0.1 deg
        diff = kp._core.wrap_angle(tf_roll - floor_roll)
        frames.append(
            {"stamp": 10.0 + 0.1 * i, "found": True, "floor_height": 1.0, "floor_pitch": 0.2, "floor_roll": floor_roll}
            | {"tf_height": 1.0, "tf_pitch": 0.2, "tf_roll": tf_roll}
            | {"diff_height": 0.0, "diff_pitch": 0.0, "diff_roll": diff, "floor_fraction": 0.5}
        )
    check = TfCheck("x.bag", "/depth", frames)
    s = check.summary()
    assert abs(math.degrees(s["floor"]["roll"])) > 179.5, s["floor"]
    assert abs(math.degrees(s["roll"]["median"])) < 1.0 and math.degrees(s["roll"]["max_abs"]) < 1.0, s["roll"]
    v = check.series()["roll"]
    for key in ("tf", "floor", "floor_all"):
        assert np.ptp(v[key]) < deg(1.0), (key, np.degrees(v[key]))
    assert np.allclose(v["tf"] - v["floor"], v["diff"]) and np.abs(v["diff"]).max() < deg(1.0)
    assert on_one_turn([deg(179.0), deg(-179.0)]) == pytest.approx([deg(179.0), deg(181.0)])
    assert on_one_turn([]) == []
    plot_tf_check(check, tmp_path / "tf.png")
    assert (tmp_path / "tf.png").stat().st_size > 10000


def test_bag_check_text_and_bad_input(
    tf_bags: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["calibrate", "--bag", str(tf_bags["pitch_height"])]) == 0
    text = capsys.readouterr().out
    assert "| pitch [deg] | +0.9" in text and "| height [m] | +0.04" in text and "p95 abs" in text
    assert main(["calibrate", "--bag", str(tmp_path / "none.bag")]) == 1
    assert "none.bag: no such bag" in capsys.readouterr().err
    assert main(["calibrate", "--bag", str(tf_bags["ok"]), "x.png"]) == 1
    assert "give no frame files" in capsys.readouterr().err
    assert main(["calibrate"]) == 1
    assert "--intrinsics" in capsys.readouterr().err
    with pytest.raises(ValueError, match="tf_error"):
        from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag

        write_sequence_bag(tmp_path / "e.bag", Scenario(frames=1, tf_error=(0.0, math.nan, 0.0)))
    from kinect_pipeline.tools.calibrate import check_tf

    with pytest.raises(TypeError, match="bag"):
        check_tf(3)  # type: ignore[arg-type]


def test_bag_check_with_a_base_frame_the_tf_lacks_names_the_frames_there(
    tf_bags: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    """A mistyped --base-frame said "the bag has no tf ... nothing to check", exit 0: nothing was checked."""
    assert main(["calibrate", "--bag", str(tf_bags["ok"]), "--base-frame", "base_footprnt", "--json"]) == 1
    out = capsys.readouterr()
    assert out.out == "" and "has a tf from the base frame 'base_footprnt'" in out.err, out.err
    assert "'base_footprnt' are not connected" in out.err and "base_footprint, base_link" in out.err, out.err
