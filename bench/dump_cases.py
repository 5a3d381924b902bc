#!/usr/bin/env python3
"""Runs a large matrix of rendered frames through the core and records every output, to check that a change of the
core's code (not of its rules) leaves every output bit for bit as it was.

    python3 bench/dump_cases.py dump OUT [--arrays] [--only REGEX] [--list]
    python3 bench/dump_cases.py compare BEFORE AFTER

``dump`` writes OUT/digests.jsonl: per case and frame the SHA-256 of the labels, the cleaned depth, the ranges,
the intensities and the cliff ranges (their bytes, NaN payloads included), the label counts and the pose the frame
was processed at (its floats in hex). With ``--arrays`` it also writes each case's arrays to OUT/arrays/CASE.npz, so
that ``compare`` can say where they differ. ``compare`` prints ``bit-identical: N cases`` and exits 0, or lists the
cases and outputs that differ (how many elements, the first one, with values where both sides have arrays) and
exits 1. A case missing on one side is a difference too.

The matrix (2880 cases, and 192 extra ones): 3 encodings x 4 scenes (lab, boxes, stair, hole of
kinect_pipeline.simulation.scenes) x 5 poses (two with roll, one told off by centimetres and degrees so that the floor
refinement moves it) x both projections x both geometries x opening kernels 0, 3, 5 x 1 and 2 threads x
refine_floor on and off, each case two noisy frames through one Pipeline (the confidence's window holds both), with
the cliff scan on. The extra cases vary what the matrix holds fixed: surface_band, the cross and ellipse kernels,
cliff_in_scan, few and many beams, the intensity filter, a steep threshold curve.

Run it with the package importable (``. ./env.sh``). To check a change: dump before it (a build of the commit
before, or its library and binding, see bench/README.md), dump after, compare.
"""

from __future__ import annotations

import argparse
import hashlib
import itertools
import json
import os
import re
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import kinect_pipeline as kp
from kinect_pipeline.simulation import scenes

ENCODINGS = ("8UC1", "16UC1", "32FC1")
SCENES = {"lab": scenes.lab_scene, "boxes": scenes.boxes_scene, "stair": scenes.stair_scene, "hole": scenes.hole_scene}


@dataclass(frozen=True)
class Pose:
    """Where the frame is rendered from, and what the pipeline is told (height [m], pitch, roll [rad])."""

    name: str
    true: tuple[float, float, float]
    told: tuple[float, float, float]


POSES = (
    Pose("p26", (1.1, 0.26, 0.0), (1.1, 0.26, 0.0)),
    Pose("p35r35", (1.1, 0.35, 0.035), (1.1, 0.35, 0.035)),
    Pose("low", (0.6, 0.12, 0.0), (0.6, 0.12, 0.0)),
    Pose("steep_roll", (1.3, 0.6, -0.05), (1.3, 0.6, -0.05)),
    Pose("told_off", (1.0, 0.30, 0.02), (1.04, 0.28, 0.0)),
)
OUTPUTS = ("labels", "depth", "ranges", "intensities", "cliff")


@dataclass
class Case:
    name: str
    encoding: str
    scene: str
    pose: Pose
    config: dict = field(default_factory=dict)


def matrix() -> list[Case]:
    out = []
    for enc, scene, pose, proj, geo, kernel, threads, refine in itertools.product(
        ENCODINGS, SCENES, POSES, ("horizontal", "column"), ("exact", "thesis"), (0, 3, 5), (1, 2), (True, False)
    ):
        cfg = dict(projection=proj, geometry=geo, open_kernel_size=kernel, num_threads=threads, refine_floor=refine)
        name = f"{enc}_{scene}_{pose.name}_{proj}_{geo}_k{kernel}_t{threads}_{'refine' if refine else 'fixed'}"
        out.append(Case(name, enc, scene, pose, cfg))
    extras = {
        "band": dict(surface_band=1.0),
        "cross3": dict(open_kernel_shape="cross", open_kernel_size=3),
        "ellipse5": dict(open_kernel_shape="ellipse", open_kernel_size=5),
        "cliff_in_scan": dict(cliff_in_scan=True),
        "beams60": dict(scan_beams=60),
        "beams1500": dict(scan_beams=1500),
        "filter": dict(intensity_filter=True, min_intensity=0.5, confidence_distance=0.05),
        "steep_curve": dict(threshold_curve="0.5:0.02, 12:3.0"),
    }
    for enc, (extra, cfg), pose, threads, refine in itertools.product(
        ENCODINGS, extras.items(), (POSES[1], POSES[4]), (1, 2), (True, False)
    ):
        c = dict(cfg, num_threads=threads, refine_floor=refine)
        name = f"{enc}_lab_{pose.name}_{extra}_t{threads}_{'refine' if refine else 'fixed'}"
        out.append(Case(name, enc, "lab", pose, c))
    return out


def digest(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def frames_for(case: Case, cache: dict, camera) -> list[np.ndarray]:
    key = (case.scene, case.pose.name, case.encoding)
    if key not in cache:
        h, p, r = case.pose.true
        cache[key] = [
            scenes.render_frame(camera, SCENES[case.scene](), h, p, r, case.encoding, seed=seed).depth
            for seed in (1, 2)
        ]
    return cache[key]


def run_case(case: Case, camera, cache: dict) -> list[dict]:
    h, p, r = case.pose.told
    cfg = kp.Config(sensor_height=h, sensor_pitch=p, sensor_roll=r, cliff_scan=True, **case.config)
    pipe = kp.Pipeline(camera, cfg)
    records = []
    for i, frame in enumerate(frames_for(case, cache, camera)):
        res = pipe.process(frame, stamp=i / 30.0)
        arrays = {
            "labels": res.labels,
            "depth": res.depth,
            "ranges": res.ranges,
            "intensities": res.intensities,
            "cliff": res.cliff_ranges,
        }
        rec = {"case": case.name, "frame": i}
        rec.update({k: digest(v) for k, v in arrays.items()})
        rec["counts"] = dict(sorted(res.counts.items()))
        rec["pose"] = [float(x).hex() for x in res.pose]
        records.append((rec, arrays))
    return records


def dump(out: Path, arrays: bool, only: str | None) -> int:
    camera = kp.kinect_v2_camera()
    cases = [c for c in matrix() if only is None or re.search(only, c.name)]
    if not cases:
        print(f"dump: no case matches --only {only!r}", file=sys.stderr)
        return 2
    out.mkdir(parents=True, exist_ok=True)
    if arrays:
        (out / "arrays").mkdir(exist_ok=True)
    cache: dict = {}
    # Cases sorted by their frames, so that each rendering is made once and dropped when no longer needed.
    cases.sort(key=lambda c: (c.scene, c.pose.name, c.encoding))
    lines = []
    last_key = None
    for n, case in enumerate(cases, 1):
        key = (case.scene, case.pose.name, case.encoding)
        if key != last_key:
            cache.clear()
            last_key = key
        records = run_case(case, camera, cache)
        lines.extend(json.dumps(rec, sort_keys=True) for rec, _ in records)
        if arrays:
            npz = {f"{k}_{rec['frame']}": v for rec, arr in records for k, v in arr.items()}
            np.savez_compressed(out / "arrays" / f"{case.name}.npz", **npz)
        if n % 100 == 0 or n == len(cases):
            print(f"\r{n}/{len(cases)} cases", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    # Atomically: a half-written digest file is never taken for a dump.
    fd, tmp = tempfile.mkstemp(dir=out, prefix=".digests.")
    with os.fdopen(fd, "w") as f:
        f.write("\n".join(lines) + "\n")
    os.replace(tmp, out / "digests.jsonl")
    print(f"dump: {len(cases)} cases ({len(lines)} frames) -> {out / 'digests.jsonl'}")
    return 0


def load(d: Path) -> dict:
    path = d / "digests.jsonl"
    if not path.is_file():
        raise SystemExit(f"compare: {path} not found: expected the output folder of 'dump_cases.py dump'")
    recs = {}
    for line in path.read_text().splitlines():
        rec = json.loads(line)
        recs[(rec["case"], rec["frame"])] = rec
    return recs


def where(a: np.ndarray, b: np.ndarray) -> str:
    if a.shape != b.shape or a.dtype != b.dtype:
        return f"shape/dtype {a.shape} {a.dtype} vs {b.shape} {b.dtype}"
    x, y = a.view(np.uint8).reshape((*a.shape, -1)), b.view(np.uint8).reshape((*b.shape, -1))
    diff = np.any(x != y, axis=-1)
    idx = np.argwhere(diff)
    first = tuple(int(i) for i in idx[0])
    return f"{len(idx)} of {a.size} elements differ, first at {first}: {a[first]!r} vs {b[first]!r}"


def compare(before: Path, after: Path) -> int:
    a, b = load(before), load(after)
    bad = 0
    for key in sorted(set(a) | set(b)):
        if key not in a or key not in b:
            print(f"{key[0]} frame {key[1]}: only in {after if key in b else before}")
            bad += 1
            continue
        ra, rb = a[key], b[key]
        fields = [k for k in (*OUTPUTS, "counts", "pose") if ra[k] != rb[k]]
        if not fields:
            continue
        bad += 1
        print(f"{key[0]} frame {key[1]}: {', '.join(fields)} differ")
        for k in fields:
            if k in ("counts", "pose"):
                print(f"  {k}: {ra[k]} vs {rb[k]}")
                continue
            fa, fb = before / "arrays" / f"{key[0]}.npz", after / "arrays" / f"{key[0]}.npz"
            if fa.is_file() and fb.is_file():
                with np.load(fa) as za, np.load(fb) as zb:
                    print(f"  {k}: {where(za[f'{k}_{key[1]}'], zb[f'{k}_{key[1]}'])}")
    cases = {k[0] for k in set(a) | set(b)}
    if bad:
        print(f"DIFFERENT: {bad} of {len(set(a) | set(b))} frames ({len(cases)} cases)")
        return 1
    print(f"bit-identical: {len(cases)} cases ({len(a)} frames)")
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dump", help="run the matrix, write OUT/digests.jsonl (and with --arrays the arrays)")
    d.add_argument("out", type=Path)
    d.add_argument("--arrays", action="store_true", help="also write OUT/arrays/CASE.npz (about 1 MB a case)")
    d.add_argument("--only", help="only the cases whose name matches this regular expression")
    d.add_argument("--list", action="store_true", help="print the cases' names and do nothing else")
    c = sub.add_parser("compare", help="compare two dumps: bit-identical or what differs")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = ap.parse_args(argv)
    if args.cmd == "compare":
        return compare(args.before, args.after)
    if args.list:
        for case in matrix():
            if args.only is None or re.search(args.only, case.name):
                print(case.name)
        return 0
    return dump(args.out, args.arrays, args.only)


if __name__ == "__main__":
    sys.exit(main())
