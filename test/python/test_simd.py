"""The kernels' SIMD target: the benchmark's --simd restricts the dispatch and names the target that ran; the
environment variable does the same for a process; bad names are refused, naming the value and the choices."""

from __future__ import annotations

import os
import re
import subprocess

import pytest

from kinect_pipeline.cli.bench import bench_binary

BENCH = str(bench_binary())


def _bench(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    cmd = [BENCH, "--frames", "3", "--threads", "1", "--encodings", "16UC1", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env={**os.environ, **(env or {})})


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
