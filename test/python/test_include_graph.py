"""The C++ house keeps its layers (docs/core_design.md, "Layers"): no #include points up, and the node's and the
nodelet's libraries hold none of the offline tools (the synthetic renderer, the floor calibration).

The layer order is read from docs/core_design.md's line ``Layers, lowest first: ...``: the one place it is written.
A file's layer is its folder: src/core/<layer>/, include/kinect_pipeline/<layer>/, src/tools (tools), src/ros and
include/kinect_pipeline/ros (ros); the top-level public headers are named in TOP_LEVEL below.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DESIGN = ROOT / "docs" / "core_design.md"
INCLUDE = ROOT / "include"
PUBLIC = INCLUDE / "kinect_pipeline"
CORE = ROOT / "src" / "core"
#: The public headers outside a layer's folder, and their layer.
TOP_LEVEL = {"types.h": "base", "simd.h": "base", "pipeline.h": "pipeline", "settings_exchange.h": "pipeline"}
#: Headers generated at build time (dynamic_reconfigure), not in the tree, and the layer they belong to.
GENERATED = {"kinect_pipeline/KinectPipelineConfig.h": "ros"}
LIB = ROOT / "build" / "devel" / "lib"
#: Symbols of the offline tools (src/tools): the renderer and the calibration.
TOOL_SYMBOLS = ("kinect_pipeline::renderScene(", "kinect_pipeline::calibrateFromFloor(")


def layer_order() -> list[list[str]]:
    """The ranks, lowest first; layers of one rank (``ros, tools``) may not include each other."""
    m = re.search(r"^Layers, lowest first: (.+)$", DESIGN.read_text(), re.MULTILINE)
    assert m, f"{DESIGN}: no line 'Layers, lowest first: base -> model -> ...'"
    return [[name.strip(" `") for name in rank.split(",")] for rank in m.group(1).rstrip(".").split("->")]


def rank_of() -> dict[str, int]:
    return {name: i for i, rank in enumerate(layer_order()) for name in rank}


def layer_of(path: Path) -> str:
    rel = path.relative_to(ROOT)
    parts = rel.parts
    if parts[:2] == ("src", "core"):
        return parts[2]
    if parts[:2] == ("src", "tools"):
        return "tools"
    if parts[:2] == ("src", "ros"):
        return "ros"
    if parts[:2] == ("include", "kinect_pipeline"):
        return TOP_LEVEL[parts[2]] if len(parts) == 3 else parts[2]
    raise AssertionError(f"{rel}: not in a layer")


def sources() -> list[Path]:
    roots = [CORE, ROOT / "src" / "tools", ROOT / "src" / "ros", PUBLIC]
    return sorted(p for r in roots for p in r.rglob("*") if p.suffix in (".h", ".cpp"))


def resolve(name: str, including: Path) -> Path | None:
    for base in (including.parent, CORE, INCLUDE):
        if (base / name).is_file():
            return (base / name).resolve()
    return None


def edges() -> list[tuple[Path, str, str, str]]:
    """(file, included name, file's layer, included file's layer) of every quoted #include."""
    out = []
    for f in sources():
        for name in re.findall(r'^\s*#\s*include\s+"([^"]+)"', f.read_text(), re.MULTILINE):
            target = resolve(name, f)
            if target is None:
                assert name in GENERATED, f'{f.relative_to(ROOT)}: #include "{name}" is not in the tree'
                out.append((f, name, layer_of(f), GENERATED[name]))
            else:
                out.append((f, name, layer_of(f), layer_of(target)))
    return out


def test_every_layer_is_ranked_and_every_folder_is_a_layer() -> None:
    ranks = rank_of()
    assert {"base", "model", "io", "stages", "pipeline", "tools", "ros"} <= set(ranks), ranks
    folders = {p.name for p in CORE.iterdir() if p.is_dir()} | {p.name for p in PUBLIC.iterdir() if p.is_dir()}
    assert folders <= set(ranks), f"folders that are no layer of {DESIGN.name}: {sorted(folders - set(ranks))}"


def points_up(a: str, b: str, ranks: dict[str, int]) -> bool:
    """Whether a file of layer a including one of layer b points up (or sideways, between layers of one rank)."""
    return ranks[b] > ranks[a] or (ranks[b] == ranks[a] and a != b)


def test_no_include_points_up() -> None:
    ranks = rank_of()
    found = edges()
    assert len(found) > 100, "the parse found too few includes to mean anything"
    up = [f"{f.relative_to(ROOT)} ({a}) includes {name} ({b})" for f, name, a, b in found if points_up(a, b, ranks)]
    assert not up, "includes pointing up the layers:\n" + "\n".join(up)


def test_the_rule_reports_an_include_pointing_up() -> None:
    ranks = rank_of()
    for a, b in [("stages", "pipeline"), ("model", "stages"), ("base", "model"), ("ros", "tools"), ("tools", "ros")]:
        assert points_up(a, b, ranks), f"{a} including {b}"
    for a, b in [("pipeline", "stages"), ("tools", "pipeline"), ("ros", "pipeline"), ("stages", "stages")]:
        assert not points_up(a, b, ranks), f"{a} including {b}"
    assert layer_of(CORE / "stages" / "floor_fit.cpp") == "stages"
    assert layer_of(PUBLIC / "pipeline.h") == "pipeline"
    assert layer_of(PUBLIC / "tools" / "synthetic.h") == "tools"


def _nm_defined(lib: Path) -> str:
    return subprocess.run(
        ["nm", "-DC", "--defined-only", str(lib)], capture_output=True, text=True, check=True, timeout=60
    ).stdout


def _needed(lib: Path) -> list[str]:
    out = subprocess.run(["readelf", "-d", str(lib)], capture_output=True, text=True, check=True, timeout=60).stdout
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", out)


@pytest.mark.skipif(shutil.which("nm") is None or shutil.which("readelf") is None, reason="binutils not installed")
def test_the_node_and_nodelet_do_not_link_the_offline_tools() -> None:
    tools = LIB / "libkinect_pipeline_tools.so"
    if not tools.is_file():
        pytest.skip(f"{tools} not built (scripts/quickstart.sh build)")
    defined = _nm_defined(tools)
    for sym in TOOL_SYMBOLS:  # the check looks for what is there
        assert sym in defined, f"{tools.name} does not define {sym}: the check would look for nothing"
    per_frame = [
        LIB / "libkinect_pipeline_core.so",
        LIB / "libkinect_pipeline_ros.so",
        LIB / "libkinect_pipeline_nodelet.so",
        LIB / "kinect_pipeline" / "kinect_pipeline_node",
    ]
    for lib in per_frame:
        assert lib.is_file(), f"{lib} not built beside {tools}"
        assert tools.name not in _needed(lib), f"{lib.name} links {tools.name}"
        defined = _nm_defined(lib)
        held = [s for s in TOOL_SYMBOLS if s in defined]
        assert not held, f"{lib.name} holds offline tools' code: {held}"
