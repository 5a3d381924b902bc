"""The golden-output regression check passes on main and fails, naming what moved, when the pipeline changes."""

from __future__ import annotations

import pytest

pytest.importorskip("rosbags")

import kinect_pipeline as kp
from kinect_pipeline.cli import main
from kinect_pipeline.evaluation.regress import CASES, GOLDEN_DIR


def test_golden_files_are_small_and_present() -> None:
    for case in CASES:
        path = GOLDEN_DIR / f"{case.name}.npz"
        assert path.exists(), f"{path}: run 'kinect-pipeline regress --update'"
        assert path.stat().st_size < 200_000


def test_regress_passes_on_the_current_pipeline(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["regress"]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.count(": ok") == len(CASES)


@pytest.mark.parametrize("target", kp.simd_targets()[1:])
def test_regress_passes_on_every_other_simd_target(target: str, capsys: pytest.CaptureFixture[str]) -> None:
    # The golden outputs hold on every SIMD target (the exact cases bit for bit), not only on the best one.
    before = kp.simd_target()
    kp.restrict_simd(target)
    try:
        assert kp.simd_target() == target
        assert main(["regress"]) == 0, capsys.readouterr().err
    finally:
        kp.restrict_simd("native" if before == kp.simd_targets()[0] else before)
    assert capsys.readouterr().out.count(": ok") == len(CASES)


def test_regress_fails_and_says_what_moved_when_the_pipeline_changes(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["regress", "--param", "range_max=3.0"]) == 1
    err = capsys.readouterr().err
    assert "ranges:" in err and "beam(s) moved" in err and "deg)" in err
    assert main(["regress", "--param", 'threshold_curve="1:0.02, 3:0.05, 6:0.2"']) == 1
    err = capsys.readouterr().err
    assert "labels:" in err and "% of pixels changed" in err and "label moves" in err
