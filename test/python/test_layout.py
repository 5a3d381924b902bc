"""The Python package's layout (docs/tools.md, "The Python package"): its modules are the ones the tree names, and the
imports go one way: bags <- simulation <- evaluation / tools <- cli."""

from __future__ import annotations

import ast
import re
from pathlib import Path

PKG = Path(__file__).resolve().parents[2] / "src" / "kinect_pipeline"
DOC = Path(__file__).resolve().parents[2] / "docs" / "tools.md"

#: What each part may not import (below it may not use above it; nothing in the library uses the command line).
FORBIDDEN = {
    "bags": {"simulation", "evaluation", "tools", "cli", "figures"},
    "simulation": {"evaluation", "tools", "cli", "figures"},
    "evaluation": {"cli"},
    "tools": {"cli"},
    "outputs": {"bags", "simulation", "evaluation", "tools", "cli", "figures"},
    "intrinsics": {"bags", "simulation", "evaluation", "tools", "cli", "figures", "outputs"},
    "figures": {"bags", "simulation", "evaluation", "tools", "cli"},
}


def _part(path: Path) -> str:
    rel = path.relative_to(PKG)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _imported_parts(path: Path) -> set[tuple[str, int]]:
    """(first part of the package, line) of every import of the package in ``path``, at any depth of the file."""
    out = set()
    depth = len(path.relative_to(PKG).parts) - 1  # 0: a top-level module
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level == 0:
                mod = node.module or ""
                if mod.startswith("kinect_pipeline."):
                    out.add((mod.split(".")[1], node.lineno))
                continue
            if node.level == 1 and depth == 1:  # a sibling in the same sub-package
                continue
            names = (node.module or "").split(".") if node.module else [a.name for a in node.names]
            out |= {(names[0], node.lineno)} if node.module else {(n.split(".")[0], node.lineno) for n in names}
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("kinect_pipeline."):
                    out.add((a.name.split(".")[1], node.lineno))
    return out


def test_imports_go_one_way() -> None:
    bad = []
    files = sorted(PKG.rglob("*.py"))
    assert len(files) > 30, files
    for f in files:
        part = _part(f)
        for name, line in _imported_parts(f):
            if name in FORBIDDEN.get(part, set()):
                bad.append(f"{f.relative_to(PKG)}:{line} imports {name} ({part} may not use {name})")
    assert not bad, "\n".join(bad)


def test_the_documented_tree_is_the_package() -> None:
    tree = re.search(r"## The Python package\n.*?```\n(.*?)```", DOC.read_text(), re.S)
    assert tree, "docs/tools.md has no tree under 'The Python package'"
    named, folder = set(), ""
    for line in tree.group(1).splitlines():
        entry = line.split()[0]
        if not line.startswith(" "):
            folder = entry if entry.endswith("/") else ""
            named.add(entry)
        else:
            named.add(folder + entry)
    have = {str(f.relative_to(PKG)) for f in PKG.glob("*.py*")} | {
        str(f.relative_to(PKG)) for f in PKG.glob("*/*.py") if f.parent.name != "cli" and f.name != "__init__.py"
    }
    have |= {d.name + "/" for d in PKG.iterdir() if d.is_dir() and (d / "__init__.py").exists()}
    assert have - named == set(), f"modules the tree in docs/tools.md does not name: {sorted(have - named)}"
    assert named - have == set(), f"docs/tools.md names modules that are not there: {sorted(named - have)}"
