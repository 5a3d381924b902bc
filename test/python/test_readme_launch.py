"""The README's driver launch examples are the rostests' (test/ros/driver_topics.test, ARGS in CMakeLists.txt),
and its sensor preset table is the core's."""

from __future__ import annotations

import re
from pathlib import Path

import kinect_pipeline as kp

ROOT = Path(__file__).resolve().parents[2]
README = (ROOT / "README.md").read_text()


def _args(text: str) -> dict[str, str]:
    return dict(a.split(":=", 1) for a in text.split() if ":=" in a)


def test_every_driver_example_is_a_rostest() -> None:
    examples = [
        _args(line.split("#")[0])
        for line in README.splitlines()
        if line.startswith("roslaunch kinect_pipeline kinect_pipeline.launch") and "sensor_model:=" in line
    ]
    assert len(examples) >= 4
    cmake = (ROOT / "CMakeLists.txt").read_text().replace("\n    ARGS", " ARGS")
    tests = [_args(m) for m in re.findall(r"add_rostest\(test/ros/driver_topics\.test ARGS ([^)]*)\)", cmake)]
    keys = ("camera", "image", "sensor_model")
    tested = {tuple(t[k] for k in keys) for t in tests}
    for e in examples:
        assert tuple(e[k] for k in keys) in tested, f"README example {e} has no rostest"
    for name in kp.sensor_models():
        d = kp.sensor_model(name)
        e = next(x for x in examples if x["sensor_model"] == name)
        prefix = "/" + e["camera"].strip("/") if e["camera"].strip("/") else ""
        assert f"{prefix}/{e['image']}" == d["depth_topic"], (name, e)


def test_the_preset_table_is_the_cores() -> None:
    rows = [line for line in README.splitlines() if re.match(r"\| `(kinect_v|realsense|azure|orbbec)", line)]
    assert len(rows) == len(kp.sensor_models())
    for row in rows:
        cells = [c.strip() for c in row.strip("|").split("|")]
        name = cells[0].split("`")[1]
        d = kp.sensor_model(name)
        want = " / ".join(f"{100 * kp.evaluate_curve(d['threshold_curve'], z):.1f}" for z in (1.0, 2.0, 4.0))
        assert cells[2] == want, (name, cells[2], want)
        assert float(cells[3]) == d["range_max"] and int(cells[4]) == d["cliff_min_pixels"]
        assert float(cells[5]) == d["speckle_jump"]
        assert cells[6] == f"`{d['depth_topic']}`"
