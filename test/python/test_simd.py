"""The kernels' SIMD target: the benchmark's --simd restricts the dispatch and names the target that ran; the
environment variable does the same for a process; bad names are refused, naming the value and the choices."""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
from collections.abc import Iterator

import numpy as np
import pytest
from clitool import cli

import kinect_pipeline as kp
from kinect_pipeline.cli.bench import bench_binary
from kinect_pipeline.evaluation.real_floors import RS_CAM, calibrated_config, shared_realsense_frames

REAL = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "real")

BENCH = str(bench_binary())


def _bench(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    cmd = [BENCH, "--frames", "3", "--threads", "1", "--encodings", "16UC1", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env={**os.environ, **(env or {})})


@contextlib.contextmanager
def _target_kept() -> Iterator[str]:
    """Gives back the target in force before (KINECT_PIPELINE_SIMD's, or the CPU's best) whatever the body does."""
    before = kp.simd_target()
    try:
        yield before
    finally:
        kp.restrict_simd("native" if before == kp.simd_targets()[0] else before)


def _targets_ran(out: str) -> list[str]:
    return [m.group(1) for m in re.finditer(r"^16UC1\s+(native \(\w+\)|\w+)\s+1\s", out, re.M)]


def test_each_target_named_runs_and_is_named_in_the_table() -> None:
    r = _bench("--simd", "native,scalar")
    assert r.returncode == 0, r.stderr
    ran = _targets_ran(r.stdout)
    assert len(ran) == 2 and ran[0].startswith("native (") and ran[1] == "scalar", r.stdout
    assert ran[0] != "native (scalar)", "a vector target is expected on x86-64 and aarch64"
    best = ran[0][len("native (") : -1]
    r = _bench("--simd", best)
    assert r.returncode == 0 and _targets_ran(r.stdout) == [best], r.stdout + r.stderr


@pytest.mark.parametrize("how", ["flag", "env"])
def test_a_target_this_cpu_lacks_or_no_target_is_refused(how: str) -> None:
    r = _bench("--simd", "mmx") if how == "flag" else _bench(env={"KINECT_PIPELINE_SIMD": "mmx"})
    assert r.returncode != 0
    assert "'mmx'" in r.stderr and "scalar" in r.stderr, r.stderr
    assert not _targets_ran(r.stdout)


def test_the_environment_variable_restricts_the_dispatch() -> None:
    r = _bench(env={"KINECT_PIPELINE_SIMD": "scalar"})
    assert r.returncode == 0, r.stderr
    assert _targets_ran(r.stdout) == ["scalar"], r.stdout


@pytest.mark.parametrize("env", ["scalar", "mmx"])
def test_the_bench_command_takes_the_environment_variable_unless_simd_is_given(env: str) -> None:
    """`kinect-pipeline bench` passed --simd native whatever the variable said: it measured the CPU's best target
    under KINECT_PIPELINE_SIMD=scalar, and a bad value went unnoticed."""
    base = [sys.executable, "-m", "kinect_pipeline.cli", "bench", "--frames", "2", "--threads", "1"]
    run = {"capture_output": True, "text": True, "timeout": 300, "env": {**os.environ, "KINECT_PIPELINE_SIMD": env}}
    r = subprocess.run([*base, "--encodings", "16UC1"], **run)
    if env == "mmx":
        assert r.returncode == 2 and "KINECT_PIPELINE_SIMD" in r.stderr and "'mmx'" in r.stderr, r.stdout + r.stderr
    else:
        assert r.returncode == 0 and _targets_ran(r.stdout) == ["scalar"], r.stdout + r.stderr
    r = subprocess.run([*base, "--encodings", "16UC1", "--simd", "native"], **run)  # the option wins
    assert r.returncode == 0 and _targets_ran(r.stdout)[0].startswith("native ("), r.stdout + r.stderr


@pytest.mark.parametrize("env", ["sse4", "mmx"])
def test_an_explicit_restriction_wins_over_the_environment_variable(env: str) -> None:
    """The variable took effect at the first simd_target() or Pipeline(), and then undid a restrict_simd() made
    before it; a bad value refused every Pipeline for good, even after a good restrict_simd()."""
    code = (
        "import kinect_pipeline as kp\n"
        "kp.restrict_simd('scalar')\n"
        "cam = kp.Camera(64, 48, 60.0, 60.0, 32.0, 24.0)\n"
        "kp.Pipeline(cam, kp.Config(sensor_height=1.0, sensor_pitch=0.3))\n"
        "print(kp.simd_target())\n"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "KINECT_PIPELINE_SIMD": env},
    )
    assert r.returncode == 0 and r.stdout.strip() == "scalar", r.stdout + r.stderr


def test_the_environment_variable_holds_for_the_core_tests_after_an_every_target_test() -> None:
    test_core = os.path.join(os.path.dirname(BENCH), "test_core")
    assert os.path.exists(test_core), "the core's gtests are built with the package (scripts/quickstart.sh build)"
    name = "PipelineEdge.EveryTargetRunGivesBackTheTargetInForce"
    r = subprocess.run(
        [test_core, f"--gtest_filter={name}"],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "KINECT_PIPELINE_SIMD": "scalar"},
    )
    assert r.returncode == 0, r.stdout[-3000:]
    assert f"[       OK ] {name}" in r.stdout and "[  PASSED  ] 1 test" in r.stdout, r.stdout[-3000:]


def test_the_bench_measures_reference_paths_beside_the_fast_paths() -> None:
    r = _bench("--simd", "native", "--reference", "none,all,labels+opening")
    assert r.returncode == 0, r.stderr
    rows = re.findall(r"^16UC1\s+native \(\w+\)\s+1\s+(\S+)\s", r.stdout, re.M)
    assert rows == ["none", "all", "labels+opening"], r.stdout


@pytest.mark.parametrize("name", ["fast", "labels+", "labels+simd"])
def test_a_reference_path_the_pipeline_lacks_is_refused(name: str) -> None:
    r = _bench("--reference", f"none,{name}")
    assert r.returncode == 2
    assert f"'{name}'" in r.stderr and "binning" in r.stderr and "portable" in r.stderr, r.stderr
    assert not _targets_ran(r.stdout)


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--frames", "0"], "--frames: '0' is not a frame count"),
        (["--frames", "3x"], "--frames: '3x' is not a frame count"),
        (["--kernel", "4"], "Config.open_kernel_size = 4: expected"),
        (["--kernel", "abc"], "--kernel: 'abc' is not an opening kernel size"),
        (["--surface-band", "-1"], "Config.surface_band = -1: expected"),
        (["--projection", "diagonal"], "--projection: 'diagonal' is not horizontal or column"),
        (["--simd", ""], "--simd: names nothing to measure"),
        (["--simd", ","], "--simd: names nothing to measure"),
        (["--reference", ""], "--reference: names nothing to measure"),
        (["--encodings", ""], "--encodings: names nothing to measure"),
        (["--threads", ""], "--threads: names nothing to measure"),
        (["--roll", "abc"], "--roll: 'abc' is not a number [rad]"),
        (["--roll", "4"], "Config.sensor_roll = 4: expected a value in [-3.14159, 3.14159]"),
    ],
)
def test_the_bench_refuses_options_it_cannot_honour_naming_the_value(args: list[str], says: str) -> None:
    """Before, a frame count of 0 or an empty list printed a table of nothing (or of NaN) with exit 0, and a kernel
    the pipeline refuses ended in an uncaught exception."""
    r = _bench(*args)  # the options given last win over _bench's own
    assert r.returncode == 2, r.stdout + r.stderr
    assert says in r.stderr, r.stderr
    assert not _targets_ran(r.stdout) and "terminate" not in r.stderr


def test_the_bench_cli_refuses_an_empty_list_and_passes_one_naming_nothing_through() -> None:
    r = cli("bench", "--frames", "2", "--encodings", "")
    assert r.returncode == 2 and "argument --encodings: an empty value" in r.stderr, r.stdout + r.stderr
    r = cli("bench", "--frames", "2", "--threads", ",")
    assert r.returncode == 2 and "--threads: names nothing to measure" in r.stderr, r.stdout + r.stderr


def test_the_bench_at_a_roll_renders_and_processes_its_frames_there_and_says_so() -> None:
    r = cli("bench", "--frames", "2", "--threads", "1", "--encodings", "8UC1", "--roll", "0.001")
    assert r.returncode == 0, r.stderr
    assert "pitch changing every frame, roll 0.001 rad" in r.stdout and re.search(r"^8UC1\s", r.stdout, re.M), r.stdout


def test_the_bench_measures_each_roll_given_side_by_side_and_refuses_a_bad_one() -> None:
    r = cli("bench", "--frames", "2", "--threads", "1", "--encodings", "8UC1", "--roll", "0,0.0087", "--markdown")
    assert r.returncode == 0, r.stderr
    assert "roll 0, 0.0087 rad" in r.stdout, r.stdout
    lines = [line.split("|") for line in r.stdout.splitlines() if line.startswith("| ")]
    header = [c.strip() for c in lines[0]]
    rolls = [row[header.index("roll [rad]")].strip() for row in lines[1:]]
    assert rolls == ["0", "0.0087"], r.stdout
    frames = [float(row[header.index("frame [ms]")]) for row in lines[1:]]
    assert all(f > 0 for f in frames), r.stdout
    for bad, says in (("0,x", "--roll: 'x' is not a number [rad]"), ("0,7", "Config.sensor_roll = 7")):
        r = cli("bench", "--frames", "2", "--threads", "1", "--encodings", "8UC1", "--roll", bad)
        assert r.returncode == 2 and says in r.stderr and "8UC1" not in r.stdout, r.stdout + r.stderr


def test_the_bench_without_an_opening_says_so() -> None:
    r = _bench("--kernel", "0")
    assert r.returncode == 0, r.stderr
    assert ", no opening," in r.stdout and len(_targets_ran(r.stdout)) == 1, r.stdout


def test_python_restricts_the_dispatch_and_every_target_gives_the_same_frame() -> None:
    cam = kp.Camera.from_fov(160, 120, kp.KINECT_V2_HFOV, kp.KINECT_V2_VFOV)
    cfg = kp.Config(sensor_height=1.1, sensor_pitch=0.26)
    metres = kp.render_scene(cam, 1.1, 0.26, 0.0, boxes=[(2.0, 2.6, -0.8, 0.6, 0.0, 0.9)])["depth"]
    frame = kp.encode_depth(metres, "16UC1", 12.0)
    targets = kp.simd_targets()
    assert targets[-1] == "scalar" and len(targets) >= 2, targets
    results = {}
    with _target_kept() as before:
        for t in targets:
            kp.restrict_simd(t)
            assert kp.simd_target() == t
            r = kp.Pipeline(cam, cfg).process(frame, 0.0, 0.0)
            results[t] = (np.asarray(r.labels).copy(), np.asarray(r.ranges).copy())
    assert kp.simd_target() == before
    first = results[targets[0]]
    for t, (labels, ranges) in results.items():
        assert np.array_equal(labels, first[0]), t
        assert np.array_equal(ranges, first[1], equal_nan=True), t
    assert np.isfinite(first[1]).sum() > 20


def test_real_realsense_frames_give_the_same_bits_on_every_target() -> None:
    # Real depth, 16-bit: rows labelled by value (no roll) and pixel by pixel (roll), the floor profile learning.
    frames = shared_realsense_frames(os.path.join(REAL, "realsense_lowcam"))[:4]
    assert len(frames) == 4, f"the shared RealSense frames are missing under {REAL}"
    cfg = calibrated_config(frames[0])  # the floor the first frame holds
    assert cfg is not None, "the core's floor calibration finds the first frame's floor"
    outputs: dict[str, list[tuple[np.ndarray, ...]]] = {}
    with _target_kept():
        for t in kp.simd_targets():
            kp.restrict_simd(t)
            pipe = kp.Pipeline(RS_CAM, cfg)
            outputs[t] = []
            for i, depth in enumerate(frames):
                r = pipe.process(depth, 0.0, 0.05 * (i % 2), stamp=0.1 * i)
                outputs[t].append(
                    (
                        np.asarray(r.labels).copy(),
                        np.asarray(r.depth).copy(),
                        np.asarray(r.ranges).copy(),
                        np.asarray(r.cliff_ranges).copy(),
                    )
                )
    first = next(iter(outputs.values()))
    for t, frames_out in outputs.items():
        for i, (got, want) in enumerate(zip(frames_out, first, strict=True)):
            for a, b in zip(got, want, strict=True):
                assert np.array_equal(a, b, equal_nan=True), (t, i)
    assert (first[0][0] == kp.LABELS["floor"]).mean() > 0.05, "the frames' floor is labelled"


def test_python_refuses_a_target_naming_it_and_the_choices() -> None:
    with pytest.raises(ValueError, match=r"'mmx'.*scalar"):
        kp.restrict_simd("mmx")
