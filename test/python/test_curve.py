"""kinect-pipeline curve: the threshold curve from floor frames and from a noise model."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.cli import main
from kinect_pipeline.simulation.scenes import Scene, lab_scene
from kinect_pipeline.tools.curve import compare_with_constant, curve_from_model, fit_curve, generated_floor_frames

CAM = kp.kinect_v2_camera()


def floor_frames(n: int = 3, scene: Scene | None = None) -> list[tuple[str, np.ndarray]]:
    return generated_floor_frames(n, scene)


def test_fit_recovers_the_sensor_noise_and_gives_a_valid_curve() -> None:
    fit = fit_curve(floor_frames(), CAM, false_obstacle_rate=1e-3, margin=0.01)
    assert fit.sigma0 == pytest.approx(0.0015, abs=0.0008)
    assert fit.k_quad == pytest.approx(0.0019, rel=0.15)
    assert fit.k == pytest.approx(3.09, abs=0.01)
    cfg = kp.Config(threshold_curve=fit.text)  # the pipeline accepts it as it is
    assert len(cfg.threshold_curve) == len(fit.points)
    t = [p[1] for p in fit.points]
    assert all(b >= a for a, b in itertools.pairwise(t))


def test_fit_works_with_obstacles_in_view() -> None:
    fit = fit_curve(floor_frames(2, lab_scene()), CAM)
    assert fit.k_quad == pytest.approx(0.0019, rel=0.25)


def test_a_lower_false_obstacle_rate_gives_a_wider_curve() -> None:
    a = curve_from_model(0.0015, 0.0019, 1e-2, 0.01)
    b = curve_from_model(0.0015, 0.0019, 1e-4, 0.01)
    assert all(pb[1] > pa[1] for pa, pb in zip(a.points, b.points, strict=False))


def test_cli_writes_yaml_and_plot(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import cv2

    paths = []
    for i, (_, m) in enumerate(floor_frames(2)):
        p = tmp_path / f"f{i}.png"
        cv2.imwrite(str(p), np.round(m * 1000).astype(np.uint16))
        paths.append(str(p))
    intr = [str(v) for v in (CAM.fx, CAM.fy, CAM.cx, CAM.cy)]
    assert (
        main(
            ["curve", *paths, "--intrinsics", *intr, "-o", str(tmp_path / "c.yaml"), "--plot", str(tmp_path / "c.png")]
        )
        == 0
    )
    text = (tmp_path / "c.yaml").read_text()
    line = next(x for x in text.splitlines() if x.startswith("threshold_curve:"))
    kp.Config(threshold_curve=line.split('"')[1])
    assert (tmp_path / "c.png").stat().st_size > 10000
    assert main(["curve"]) == 1
    assert "--from-model" in capsys.readouterr().err


def test_fitted_curve_meets_the_phantom_goal_and_removes_fewer_obstacle_pixels_than_a_constant_margin() -> None:
    fit = fit_curve(floor_frames(), CAM)  # the default false-obstacle rate (1e-4 per floor pixel)
    c = compare_with_constant(fit, frames=8)
    f = c.fitted
    assert f.phantom <= 0.002, "the phantom-beam goal (<= 0.2 % of beams)"
    # The constants are matched from below: no more floor kept / phantom beams than the fitted curve ...
    assert c.same_rate.false_obstacle <= f.false_obstacle
    assert c.same_phantom.phantom <= f.phantom
    # ... and the largest constant tried with more phantom beams than the fitted curve still removes more.
    assert c.more_phantom is not None and c.more_phantom.phantom > f.phantom
    for const in (c.same_rate, c.same_phantom, c.more_phantom):
        assert const.removed[0] > 10 * max(f.removed[0], 1e-4), ("5-10 cm", const, f)
        assert const.removed[1] > f.removed[1], ("10-30 cm", const, f)
    with pytest.raises(TypeError, match="CurveFit"):
        compare_with_constant("0.5:0.1")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="frames = 0"):
        compare_with_constant(fit, frames=0)


def test_cli_compare_prints_the_table_and_a_picture(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "cmp.png"
    assert main(["curve", "--compare", "--compare-frames", "3", "--compare-plot", str(png)]) == 0
    out = capsys.readouterr().out
    for row in ("| fitted t(d) |", "| constant, same false-obstacle rate |", "| constant, same phantom-beam rate |"):
        assert row in out
    assert "removed 5–10 cm %" in out and png.stat().st_size > 20000


def test_set_node_sets_the_curve_on_a_running_node(tmp_path: Path) -> None:
    """`kinect-pipeline curve --set-node` through dynamic_reconfigure on the real node (own roscore, stopped by PID)."""
    import os
    import shutil
    import subprocess
    import sys
    import time

    if shutil.which("roscore") is None or shutil.which("roslaunch") is None:
        pytest.skip("roscore / roslaunch not installed")
    rosgraph = pytest.importorskip("rosgraph")
    from kinect_pipeline.tools.bench_ros import _free_port, _stop

    port = _free_port()
    uri = f"http://127.0.0.1:{port}"
    env = dict(os.environ, ROS_MASTER_URI=uri, ROS_IP="127.0.0.1", ROS_HOME=str(tmp_path))
    procs: list[subprocess.Popen[bytes]] = []

    def start(cmd: list[str]) -> None:
        procs.append(
            subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        )

    def wait(what: str, ok: object) -> None:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                if ok():  # type: ignore[operator]
                    return
            except Exception:
                pass
            time.sleep(0.1)
        raise AssertionError(f"{what}: not within 60 s")

    master = rosgraph.Master("/test_curve", master_uri=uri)
    node = "/kinect2/kinect_pipeline"
    try:
        start(["roscore", "-p", str(port)])
        wait("roscore", master.is_online)
        start(["roslaunch", "kinect_pipeline", "kinect_pipeline.launch", "pose_source:=static"])
        wait("the node's dynamic_reconfigure", lambda: master.lookupService(f"{node}/set_parameters"))
        cmd = [sys.executable, "-m", "kinect_pipeline.cli", "curve", "--from-model", "0.002", "0.003"]
        r = subprocess.run(
            [*cmd, "--rate", "1e-4", "--set-node", node],
            env=env,
            capture_output=True,
            text=True,
            timeout=90,
        )
        assert r.returncode == 0, r.stderr
        want = curve_from_model(0.002, 0.003, 1e-4, 0.01)
        assert f"set on {node}:" in r.stdout
        param = rosgraph.masterapi.Master("/test_curve", master_uri=uri).getParam(f"{node}/threshold_curve")
        got = kp.Config(threshold_curve=param).threshold_curve
        assert got == pytest.approx(want.points, abs=1e-6), (param, want.text)
    finally:
        for p in reversed(procs):
            _stop(p)  # SIGINT to its own process group, SIGKILL after a deadline


def test_set_node_without_a_master_says_so(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("rosgraph")
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nothing listens there once closed
    monkeypatch.setenv("ROS_MASTER_URI", f"http://127.0.0.1:{port}")
    assert main(["curve", "--from-model", "0.0015", "0.0019", "--set-node", "/kinect2/kinect_pipeline"]) == 1
    assert f"no ROS master at http://127.0.0.1:{port}" in capsys.readouterr().err
