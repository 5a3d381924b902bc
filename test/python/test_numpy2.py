"""The binding with numpy 2 arrays (built with pybind11 >= 2.12), in a venv of its own: Debian's cv_bridge keeps the
tools' numpy < 2, so numpy 2 is installed into build/venv-numpy2 (without the system's packages) for this test."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
VENV = ROOT / "build" / "venv-numpy2"
CORE = next((ROOT / "build" / "devel" / "lib").glob("python3*/dist-packages/kinect_pipeline/_core*.so"), None)

SCRIPT = """
import numpy as np, kinect_pipeline as kp
assert int(np.__version__.split(".")[0]) >= 2, np.__version__
cam = kp.Camera(64, 48, 50.0, 50.0, 31.5, 23.5)
pipe = kp.Pipeline(cam, kp.Config(sensor_height=1.0, sensor_pitch=0.3, refine_floor=False))
for depth in (np.full((48, 64), 1500, np.uint16), np.full((48, 64), 1.5, np.float32), np.full((48, 64), 40, np.uint8)):
    res = pipe.process(depth)
    assert res.depth.dtype == depth.dtype and res.labels.shape == (48, 64) and len(res.ranges) == 64
assert kp.evaluate_curve("0.5:0.1, 2:0.4", np.array([1.25]))[0] == 0.25
try:
    pipe.process(np.zeros((48, 64), np.int32))
except TypeError as e:
    assert "dtype int32" in str(e), e
else:
    raise AssertionError("int32 accepted")
print("numpy", np.__version__, "ok")
"""


@pytest.fixture(scope="module")
def python2() -> Path:
    if CORE is None:
        pytest.skip("no built binding in build/devel: run scripts/quickstart.sh build")
    py = VENV / "bin" / "python3"
    if not py.exists():
        subprocess.run(["/usr/bin/python3", "-m", "venv", str(VENV)], check=True, timeout=120)
    have = subprocess.run([str(py), "-c", "import numpy; print(numpy.__version__)"], capture_output=True, text=True)
    if have.returncode != 0 or not have.stdout.startswith("2"):
        got = subprocess.run(
            [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", "numpy>=2"],
            capture_output=True, text=True, timeout=600,
        )  # fmt: skip
        if got.returncode != 0:
            pytest.skip(f"numpy 2 not installable here: {got.stderr.strip()[-300:]}")
    return py


def test_the_binding_takes_numpy_2_arrays(python2: Path) -> None:
    env = {"PYTHONPATH": str(CORE.parent.parent), "PATH": "/usr/bin:/bin"}  # type: ignore[union-attr]
    r = subprocess.run([str(python2), "-c", SCRIPT], capture_output=True, text=True, timeout=120, env=env)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "ok" in r.stdout


def test_the_tools_keep_numpy_1_for_cv_bridge() -> None:
    import numpy as np

    assert int(np.__version__.split(".")[0]) == 1, f"numpy {np.__version__}: Debian's cv_bridge needs numpy < 2"
    assert sys.prefix != str(VENV)
