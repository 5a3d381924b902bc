"""The binding stays thin (issue 26): src/python/*.cpp only bind, split by area, every function short enough to read.

The measure is simple: comments, string literals and preprocessor lines are dropped, then each brace block whose
header has a parameter list and which does not lie inside another function is a function (free or member); its
length is the number of lines from its header's first line to its closing brace, lambdas in it included.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
BINDING = ROOT / "src" / "python"
MAX_LINES = 150  # issue 26: the binding's longest function under 150 lines

_TOKEN = re.compile(
    r'R"(?P<delim>[^(\s]*)\(.*?\)(?P=delim)"'  # raw string literal
    r'|"(?:\\.|[^"\\\n])*"'  # string literal
    r"|'(?:\\.|[^'\\\n])+'"  # character literal
    r"|//[^\n]*"  # line comment
    r"|/\*.*?\*/"  # block comment
    r"|^[ \t]*#[^\n]*(?:\\\n[^\n]*)*",  # preprocessor line (with continuations)
    re.DOTALL | re.MULTILINE,
)


def _code(text: str) -> str:
    """The C++ text without comments, literals and preprocessor lines; line breaks kept where they were."""
    return _TOKEN.sub(lambda m: "\n" * m.group(0).count("\n") + ("0" if m.group(0)[0] in "\"'R" else " "), text)


def function_lengths(text: str) -> dict[str, int]:
    """Lines of each function of a C++ file by name (the identifier before its parameter list; repeats numbered)."""
    code = _code(text)
    lengths: dict[str, int] = {}
    stack: list[tuple[str, int, str]] = []  # (kind, first line, name) of each open block
    boundary = 0  # where the current block's header starts
    for i, ch in enumerate(code):
        if ch not in "{};":
            continue
        if ch == "{":
            header = code[boundary:i]
            inside_function = any(kind in ("function", "body") for kind, _, _ in stack)
            kind = "other"
            if inside_function:
                kind = "body"
            elif re.match(r"\s*(namespace\b|extern\b)", header):
                kind = "namespace"
            elif "(" in header and not re.match(r"\s*(struct|class|enum|union)\b", header):
                kind = "function"
            first_line = code.count("\n", 0, boundary + len(header) - len(header.lstrip()))
            names = re.findall(r"([A-Za-z_][\w:~]*)\s*\(", header)
            stack.append((kind, first_line, names[0] if names else "?"))
        elif ch == "}" and stack:
            kind, first_line, name = stack.pop()
            if kind == "function":
                key, n = name, 2
                while key in lengths:
                    key, n = f"{name}#{n}", n + 1
                lengths[key] = code.count("\n", 0, i) - first_line + 1
        boundary = i + 1
    return lengths


def test_the_measure_finds_functions_and_counts_their_lines() -> None:
    long_body = "\n".join(
        f'  m.def("f{k}", [](int x) {{ return x + {k}; }}, "a {{ brace }} in a string");' for k in range(160)
    )
    text = (
        "// a comment with a { brace\n#include <x.h>\nnamespace a::b\n{\nnamespace\n{\n"
        "struct S\n{\n  int x;\n  S(int v) : x(v) {}\n};\n"
        "int shortOne(int v)\n{\n  return v;\n}\n}  // namespace\n\n"
        f"void longOne(py::module_& m)\n{{\n{long_body}\n  const char c = '{{';\n}}\n}}  // namespace a::b\n"
    )
    lengths = function_lengths(text)
    assert lengths == {"S": 1, "shortOne": 4, "longOne": 164}, lengths


def test_the_binding_is_split_by_area_and_its_functions_are_short() -> None:
    files = sorted(BINDING.glob("*.cpp"))
    names = {f.name for f in files}
    assert {"module.cpp", "bind_pipeline.cpp", "bind_config.cpp", "bind_codecs.cpp", "bind_simulation.cpp"} <= names
    longest: list[tuple[int, str]] = []
    for f in files:
        lengths = function_lengths(f.read_text())
        assert lengths, f"{f.name}: no function found"
        longest += [(n, f"{f.name}: {name}") for name, n in lengths.items()]
    assert len(longest) > 20, longest  # the measure sees the binding's functions, not one block per file
    n, where = max(longest)
    assert n < MAX_LINES, f"{where} is {n} lines: split it (at most {MAX_LINES - 1})"
    module = function_lengths((BINDING / "module.cpp").read_text())
    assert set(module) == {"PYBIND11_MODULE"} and module["PYBIND11_MODULE"] < 20, module
