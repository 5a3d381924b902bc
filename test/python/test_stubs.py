"""The binding's type stubs (src/kinect_pipeline/_core.pyi): they name what the module has, and mypy uses them."""

from __future__ import annotations

import ast
import shutil
import subprocess
from pathlib import Path

import pytest

import kinect_pipeline as kp
from kinect_pipeline import _core

ROOT = Path(__file__).resolve().parents[2]
STUB = ROOT / "src" / "kinect_pipeline" / "_core.pyi"


def _stub() -> tuple[set[str], dict[str, set[str]]]:
    tree = ast.parse(STUB.read_text())
    names, members = set(), {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            names.add(node.name)
            members[node.name] = {
                n.target.id if isinstance(n, ast.AnnAssign) else n.name
                for n in node.body
                if isinstance(n, (ast.AnnAssign, ast.FunctionDef)) and not getattr(n, "name", "").startswith("__")
            }
        elif isinstance(node, ast.FunctionDef):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)  # a module attribute (LABELS)
    return names, members


def test_the_stubs_name_everything_the_binding_has() -> None:
    names, members = _stub()
    public = {n for n in dir(_core) if not n.startswith("_")}
    assert public == names, f"missing in the stub: {public - names}; not in the binding: {names - public}"
    for cls, have in members.items():
        real = {a for a in vars(getattr(_core, cls)) if not a.startswith("_")}
        assert real == have, f"{cls}: missing in the stub: {real - have}; not in the binding: {have - real}"


def test_config_fields_have_docstrings_with_their_defaults() -> None:
    c = kp.Config()
    for name, value in c.to_dict().items():
        doc = (getattr(kp.Config, name).__doc__ or "").strip()
        assert len(doc) > 20, f"Config.{name}: no docstring"
        if isinstance(value, (int, float)) and not isinstance(value, bool) and "(default " in doc:
            stated = doc.split("(default ")[1].split(")")[0]
            assert float(stated) == pytest.approx(value), f"Config.{name}: doc says {stated}, default is {value}"


@pytest.mark.skipif(shutil.which("mypy") is None, reason="mypy not installed (requirements.txt)")
def test_mypy_checks_calls_of_the_binding(tmp_path: Path) -> None:
    good = tmp_path / "good.py"
    good.write_text(
        "import numpy as np\nimport kinect_pipeline as kp\n"
        "cam: kp.Camera = kp.Camera(512, 424, 365.5, 365.5, 255.5, 211.5)\n"
        "res = kp.Pipeline(cam, kp.Config(sensor_height=1.1)).process(np.zeros((424, 512), np.uint16))\n"
        "r: float = res.angle_min\nt: float = kp.evaluate_curve('0.5:0.1, 2:0.4', 1.0)\n"
    )
    bad = tmp_path / "bad.py"
    bad.write_text("import kinect_pipeline as kp\ncam = kp.Camera('512', 424, 365.5, 365.5, 255.5, 211.5)\n")
    env = {"MYPYPATH": str(ROOT / "src"), "PATH": "/usr/bin:/bin"}
    mypy = shutil.which("mypy")
    assert mypy
    ok = subprocess.run([mypy, "--no-incremental", str(good)], capture_output=True, text=True, env=env, timeout=300)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    no = subprocess.run([mypy, "--no-incremental", str(bad)], capture_output=True, text=True, env=env, timeout=300)
    assert no.returncode == 1 and 'Argument 1 to "Camera" has incompatible type "str"' in no.stdout, no.stdout


def test_result_repr_and_millimetre_floats() -> None:
    import numpy as np

    from kinect_pipeline.simulation.scenes import lab_scene, render_frame

    cam = kp.kinect_v2_camera()
    f = render_frame(cam, lab_scene(), 1.1, 0.26, 0.0, "16UC1", seed=5)
    pipe = kp.Pipeline(cam, kp.Config(sensor_pitch=0.26))
    text = repr(pipe.process(f.depth))
    assert text.startswith("Result(512x424 uint16, 512 beams: ") and " floor " in text and " ms)" in text
    with pytest.raises(ValueError, match=r"float32 with a median of \d+ .*millimetres, not metres"):
        pipe.process(f.depth.astype(np.float32))
    pipe.process(f.depth.astype(np.float32) / 1000)  # metres are fine
