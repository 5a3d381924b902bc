#!/usr/bin/env python3
"""How many of the core's lines are fast paths: lines that run with the fast paths on and never on the reference path.

Builds each revision's core and bench in a git worktree with line coverage (``--coverage``, ``-O0``), runs the bench's
frames on every SIMD target this CPU has with the fast paths (and with ``ReferencePaths::portable``: the SIMD
kernels' plain loops exist for speed too) and with ``ReferencePaths::all()``, and sorts the core's executable lines
(``src/core``, ``include/kinect_pipeline`` but ``ros/``) by which of the two reached them. A line the fast runs reach
and the reference run does not exists for speed alone; the bench's lab scene, the same for every revision, decides
what is reached, so a line neither reaches (another architecture's, a bad input's) is counted apart.

    bench/fast_path_lines.py [--roll RAD] [--by-file] [--lines] [REV ...]     (default: HEAD; e.g. a5cd7ea HEAD)

A bench from before ``--reference`` existed (a5cd7ea) is given it here: the worktree's copy builds its Pipeline with
the paths ``KP_REFERENCE`` names (``all``, or ``portable`` alone). Takes a few minutes per revision (a Debug build).
"""

import argparse
import collections
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CORE = re.compile(r"^(src/core/|include/kinect_pipeline/)")
ENCODINGS = "8UC1,16UC1,32FC1"


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, **kw)


def give_old_bench_reference(src):
    """A bench without --reference: its Pipeline takes KP_REFERENCE's paths (all, or portable alone)."""
    path = os.path.join(src, "bench", "bench_core.cpp")
    with open(path) as f:
        text = f.read()
    if "--reference" in text:
        return False
    old = "Pipeline pipe(cam, cfg);"
    if text.count(old) != 1:
        sys.exit(f"fast_path_lines: {path} has neither --reference nor one '{old}' to give it the reference path")
    new = (
        'const char* kp_ref = std::getenv("KP_REFERENCE"); ReferencePaths kp_paths; if (kp_ref) kp_paths = '
        'std::string(kp_ref) == "all" ? ReferencePaths::all() : ReferencePaths{false, false, false, true}; '
        "Pipeline pipe(cam, cfg, kp_paths);"
    )
    with open(path, "w") as f:
        f.write("#include <cstdlib>\n#include <string>\n" + text.replace(old, new))
    return True


def build(src):
    b = os.path.join(src, "build", "cov")
    env = {k: v for k, v in os.environ.items() if k != "CMAKE_PREFIX_PATH"}
    run(
        [
            "cmake", "-S", src, "-B", b, "-DCMAKE_BUILD_TYPE=Debug", "-DCMAKE_CXX_FLAGS=--coverage",
            "-DCMAKE_EXE_LINKER_FLAGS=--coverage", "-DCMAKE_SHARED_LINKER_FLAGS=--coverage",
            f"-DCATKIN_DEVEL_PREFIX={src}/build/devel", "-DPYTHON_EXECUTABLE=/usr/bin/python3",
            "-DPython3_EXECUTABLE=/usr/bin/python3", "-DCATKIN_ENABLE_TESTING=OFF",
        ],
        env=env, stdout=subprocess.DEVNULL,
    )  # fmt: skip
    run(["cmake", "--build", b, f"-j{os.cpu_count()}", "--target", "kinect_pipeline_bench"], env=env,
        stdout=subprocess.DEVNULL)  # fmt: skip
    return b, os.path.join(src, "build", "devel", "lib", "kinect_pipeline", "kinect_pipeline_bench")


def bench_runs(bench, targets, old, reference, roll):
    """The bench's command lines (and environments) of one run, on every SIMD target: the reference path, or the
    fast paths (and their SIMD kernels' plain loops, ReferencePaths::portable, which exist for speed too)."""
    base = [bench, "--frames", "2", "--threads", "1,2", "--encodings", ENCODINGS]
    if roll:
        base += ["--roll", str(roll)]
    if old:
        paths = ["all"] if reference else [None, "portable"]
        return [(base, dict(os.environ, **({"KP_REFERENCE": p} if p else {}))) for p in paths]
    paths = ["all"] if reference else ["none", "portable"]
    return [([*base, "--simd", t, "--reference", p], None) for t in targets for p in paths]


def simd_targets(bench):
    """The targets this CPU has, as the bench names them (it refuses the others, naming those it has)."""
    have = []
    for t in ("avx512", "avx2", "sse4", "scalar"):
        r = subprocess.run([bench, "--frames", "1", "--threads", "1", "--encodings", "8UC1", "--simd", t],
                           capture_output=True, text=True)  # fmt: skip
        if r.returncode == 0:
            have.append(t)
    return have


def reached(b, src):
    """{(file, line): count} of the core's lines in the .gcda files under the build folder b."""
    counts: collections.Counter[tuple[str, int]] = collections.Counter()
    for gcda in glob.glob(os.path.join(b, "**", "*.gcda"), recursive=True):
        out = subprocess.run(["gcov", "-j", "-t", gcda], capture_output=True, text=True, cwd=b).stdout
        for doc in out.splitlines():
            if not doc.startswith("{"):
                continue
            for f in json.loads(doc)["files"]:
                path = os.path.relpath(os.path.realpath(os.path.join(b, f["file"])), os.path.realpath(src))
                if not CORE.match(path) or "/ros/" in path:
                    continue
                for line in f["lines"]:
                    counts[(path, line["line_number"])] += line["count"]
    return counts


def measure(rev, roll):
    src = tempfile.mkdtemp(prefix="fpl-")
    os.rmdir(src)
    run(["git", "-C", ROOT, "worktree", "add", "--detach", "-f", src, rev], stdout=subprocess.DEVNULL)
    try:
        old = give_old_bench_reference(src)
        b, bench = build(src)
        targets = [] if old else simd_targets(bench)  # before the runs: the probes' frames take the fast paths
        sets = {}
        for reference in (False, True):
            for gcda in glob.glob(os.path.join(b, "**", "*.gcda"), recursive=True):
                os.remove(gcda)
            for cmd, env in bench_runs(bench, targets, old, reference, roll):
                run(cmd, env=env, stdout=subprocess.DEVNULL)
            sets[reference] = reached(b, src)
        return sets
    finally:
        run(["git", "-C", ROOT, "worktree", "remove", "--force", src])
        shutil.rmtree(src, ignore_errors=True)


def print_lines(rev, keys):
    """Each fast-path line of revision rev, as file:line and the line's text at that revision."""
    texts = {}
    for path, number in keys:
        if path not in texts:
            show = subprocess.run(["git", "-C", ROOT, "show", f"{rev}:{path}"], capture_output=True, text=True)
            texts[path] = show.stdout.splitlines()
        text = texts[path][number - 1] if number <= len(texts[path]) else ""
        print(f"{rev} {path}:{number}: {text}")
    print(flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("revs", nargs="*", default=["HEAD"], help="revisions to count (default: HEAD)")
    ap.add_argument("--roll", type=float, default=0.0, help="the bench's --roll [rad] (revisions that have it)")
    ap.add_argument("--by-file", action="store_true", help="also the fast paths' lines of each file")
    ap.add_argument("--lines", action="store_true", help="also each fast-path line itself (file:line and its text)")
    a = ap.parse_args()
    for rev in a.revs:
        ok = subprocess.run(["git", "-C", ROOT, "rev-parse", "--verify", "-q", rev + "^{commit}"], capture_output=True)
        if ok.returncode != 0:
            sys.exit(f"fast_path_lines: revision '{rev}': expected a commit of {ROOT}")
    per_file = {}
    print("| revision | executable core lines | fast paths only | reference only | both | neither |")
    print("|---|---|---|---|---|---|")
    for rev in a.revs:
        sets = measure(rev, a.roll)
        lines = set(sets[False]) | set(sets[True])
        fast = {k for k in lines if sets[False][k] > 0}
        ref = {k for k in lines if sets[True][k] > 0}
        print(f"| {rev} | {len(lines)} | {len(fast - ref)} | {len(ref - fast)} | {len(fast & ref)} | "
              f"{len(lines - fast - ref)} |", flush=True)  # fmt: skip
        per_file[rev] = collections.Counter(path for path, _ in fast - ref)
        if a.lines:
            print_lines(rev, sorted(fast - ref))
    if a.by_file:
        print("\n| file (fast paths' lines) | " + " | ".join(a.revs) + " |")
        print("|---|" + "---|" * len(a.revs))
        for path in sorted(set().union(*per_file.values())):
            print(f"| {path} | " + " | ".join(str(per_file[r][path]) for r in a.revs) + " |")


if __name__ == "__main__":
    main()
