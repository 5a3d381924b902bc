"""A folder of depth frames is accepted wherever a single frame is: calibrate, curve and report."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.simulation.scenes import lab_scene, render_frame

cv2 = pytest.importorskip("cv2")
REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CAM = kp.kinect_v2_camera()
INTR = [str(CAM.fx), str(CAM.fy), str(CAM.cx), str(CAM.cy)]


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three rendered floor frames at 1.1 m, 15 deg: two 16-bit PNGs and a .npy of float metres, and a text file."""
    d = tmp_path_factory.mktemp("frames")
    for i in range(3):
        f = render_frame(CAM, lab_scene(), 1.1, 0.26, 0.0, "16UC1" if i < 2 else "32FC1", seed=40 + i)
        if i < 2:
            assert cv2.imwrite(str(d / f"{i}.png"), f.depth)
        else:
            np.save(d / f"{i}.npy", f.depth)
    (d / "notes.txt").write_text("not a frame")
    return d


def test_calibrate_a_folder_as_its_frames(folder: Path) -> None:
    r = cli("calibrate", str(folder), "--intrinsics", *INTR, "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert [Path(f["file"]).name for f in d["frames"]] == ["0.png", "1.png", "2.npy"]
    assert abs(d["height"] - 1.1) < 0.01


def test_curve_from_a_folder(folder: Path, tmp_path: Path) -> None:
    r = cli("curve", str(folder), "--intrinsics", *INTR, "-o", str(tmp_path / "c.yaml"))
    assert r.returncode == 0, r.stderr
    assert "threshold_curve:" in (tmp_path / "c.yaml").read_text()


def test_report_on_a_folder_of_frames_at_the_calibrated_pose(folder: Path, tmp_path: Path) -> None:
    r = cli("report", str(folder), "--intrinsics", *INTR, "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in (tmp_path / "rep").iterdir())
    assert names == ["confidence.png", "frame.png", "index.html", "scan.png", "timing.png"]
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "3 depth frame(s)" in page and "pose calibrated from the frames" in page


def test_report_on_one_frame_at_a_given_pose(folder: Path, tmp_path: Path) -> None:
    one = folder / "0.png"
    r = cli(
        "report", str(one), "--intrinsics", *INTR, "-o", str(tmp_path / "rep"), "--quiet",
        "--param", "sensor_height=1.1", "--param", "sensor_pitch=0.26",
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "rep").iterdir()) == ["frame.png", "index.html", "scan.png"]
    assert "pose from the parameters" in (tmp_path / "rep" / "index.html").read_text()


def test_frames_without_intrinsics_or_an_empty_folder_are_refused(folder: Path, tmp_path: Path) -> None:
    r = cli("report", str(folder), "-o", str(tmp_path / "rep"), "--quiet")
    assert r.returncode == 1 and "--intrinsics" in r.stderr and not (tmp_path / "rep").exists()
    empty = tmp_path / "empty"
    empty.mkdir()
    r = cli("calibrate", str(empty), "--intrinsics", *INTR)
    assert r.returncode == 1 and f"{empty}: a folder without depth frames" in r.stderr


def test_a_real_folder_of_frames(tmp_path: Path) -> None:
    depth = REAL / "slambook2" / "ch5" / "rgbd" / "depth"
    if not depth.exists():
        pytest.skip(f"{depth} not available")
    r = cli("calibrate", str(depth), "--intrinsics", "518.0", "519.0", "325.5", "253.5", "--json")
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert len(d["frames"]) == 5 and 0.4 < d["height"] < 2.0
