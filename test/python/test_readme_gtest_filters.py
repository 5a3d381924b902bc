"""Every gtest command test/README.md shows runs the tests it names: each --gtest_filter matches at least one test
of its binary (a filter that matches nothing runs 0 tests and still prints PASSED)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "test" / "README.md"


def commands() -> list[tuple[str, str]]:
    """(binary, filter) of each command line of the README that runs a gtest binary with --gtest_filter."""
    found = re.findall(r"^(build/\S+)\s+--gtest_filter='([^']+)'", README.read_text(), re.MULTILINE)
    assert found, f"{README}: no gtest command with --gtest_filter='...' (this test checks them)"
    return found


@pytest.mark.parametrize(("binary", "pattern"), commands())
def test_the_filter_runs_tests(binary: str, pattern: str) -> None:
    exe = ROOT / binary
    if not exe.is_file():
        pytest.skip(f"{binary} not built (cmake --build build/cmake --target tests)")
    out = subprocess.run(
        [str(exe), "--gtest_list_tests", f"--gtest_filter={pattern}"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    ).stdout
    tests = [line for line in out.splitlines() if line.startswith("  ")]
    assert tests, f"test/README.md: {binary} --gtest_filter='{pattern}' matches no test"
