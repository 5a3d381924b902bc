"""kinect-pipeline curve: the threshold curve from floor frames and from a noise model."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

import kinect_pipeline as kp
from kinect_pipeline.cli import main
from kinect_pipeline.curve import curve_from_model, fit_curve
from kinect_pipeline.scenes import Scene, lab_scene, render_frame

CAM = kp.kinect_v2_camera()


def floor_frames(n: int = 3, scene: Scene | None = None) -> list[tuple[str, np.ndarray]]:
    out = []
    for i in range(n):
        f = render_frame(CAM, scene or Scene(), 1.1, 0.3, 0.0, "32FC1", seed=60 + i)
        m = f.metres.astype(np.float32)
        m[~np.isfinite(m)] = 0
        out.append((f"f{i}", np.ascontiguousarray(m)))
    return out


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
