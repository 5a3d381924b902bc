"""The README's ROS tables are in step with cfg/KinectPipeline.cfg, the node's source and the core's defaults."""

from __future__ import annotations

import ast
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import kinect_pipeline as kp

ROOT = Path(__file__).resolve().parents[2]
cfg_module = pytest.importorskip("kinect_pipeline.cfg.KinectPipelineConfig")


def cfg_params() -> dict[str, dict[str, Any]]:
    def walk(g: dict[str, Any]) -> Iterator[dict[str, Any]]:
        yield from g.get("parameters", [])
        for sub in g.get("groups", []):
            yield from walk(sub)

    return {p["name"]: p for p in walk(cfg_module.config_description)}


def readme_table(heading: str) -> list[list[str]]:
    text = (ROOT / "README.md").read_text()
    start = text.index(heading)
    rows = []
    for line in text[start:].splitlines()[1:]:
        if line.startswith("#"):
            break
        if line.startswith("|") and not line.startswith("|---"):
            rows.append([c.strip() for c in line.strip().strip("|").split(" | ")])
    return rows[1:]  # without the header row


def test_every_cfg_parameter_is_in_the_readme_with_its_type_default_unit_and_range() -> None:
    params = cfg_params()
    rows = {r[0]: r for r in readme_table("### Parameters")}
    assert set(rows) == set(params), f"README only: {set(rows) - set(params)}, cfg only: {set(params) - set(rows)}"
    for name, p in params.items():
        _, typ, default, unit, rng, _ = rows[name]
        assert typ == p["type"], name
        if p["type"] == "double":
            assert float(default) == pytest.approx(p["default"]), name
            lo, hi = (float(x) for x in rng.split(" – "))
            assert lo == pytest.approx(p["min"], rel=1e-5) and hi == pytest.approx(p["max"], rel=1e-5), name
        elif p["type"] == "int":
            assert int(default) == p["default"], name
            assert rng == f"{p['min']} – {p['max']}", name
        elif p["type"] == "bool":
            assert default == str(p["default"]).lower(), name
        else:
            assert default.strip("`") == p["default"], name
            if p["edit_method"]:
                values = [c["value"] for c in ast.literal_eval(p["edit_method"])["enum"]]
                assert rng == ", ".join(values), name
        m = re.search(r"\[([^\]]+)\]", p["description"])
        assert m, f"{name}: the .cfg description has no [unit]"
        assert unit == m.group(1), name


# Deliberate differences: the node shares the robot's cores with the camera driver, so it runs one thread (no
# idle OpenMP thread spinning after each frame); offline tools use all cores.
ROS_ONLY_DEFAULTS = {"num_threads": (1, 0)}


def test_cfg_defaults_are_the_core_defaults() -> None:
    params = cfg_params()
    core = kp.Config()
    for name, value in core.to_dict().items():
        assert name in params, f"core field {name} is not a ROS parameter"
        default = params[name]["default"]
        if name in ROS_ONLY_DEFAULTS:
            assert (default, value) == ROS_ONLY_DEFAULTS[name], name
            continue
        if isinstance(value, float):
            assert default == pytest.approx(value), name
        else:
            assert default == value, name


CFG_TYPES = {"real": "double", "integer": "int", "flag": "bool", "choice": "str", "curve": "str"}


def test_cfg_declares_every_field_of_the_core_table_with_its_type_and_range() -> None:
    # The .cfg is dynamic_reconfigure's copy of the table (its generator runs before the core is built).
    params = cfg_params()
    for f in kp.CONFIG_FIELDS:
        p = params.get(f["name"])
        assert p is not None, f"core field {f['name']} is not in cfg/KinectPipeline.cfg"
        assert p["type"] == CFG_TYPES[f["kind"]], f["name"]
        assert f"[{f['unit']}]" in p["description"], f"{f['name']}: the .cfg's unit is not [{f['unit']}]"
        if f["kind"] in ("real", "integer"):
            assert (p["min"], p["max"]) == pytest.approx((f["min"], f["max"])), f["name"]
        if f["kind"] == "choice":
            assert sorted(c["value"] for c in eval(p["edit_method"])["enum"]) == sorted(f["choices"]), f["name"]


def test_the_core_table_lists_every_member_of_config() -> None:
    header = (ROOT / "include/kinect_pipeline/model/config.h").read_text()
    body = header[header.index("struct Config\n{") : header.index("std::vector<std::string> problems() const")]
    members = re.findall(r"^  [\w:<>]+ (\w+) = ", body, re.M)
    assert members == [f["name"] for f in kp.CONFIG_FIELDS]


def test_topic_tables_match_the_node() -> None:
    src = (ROOT / "src/ros/kinect_pipeline_ros.cpp").read_text()
    advertised = set(re.findall(r'advertise(?:<[^>]*>)?\("([^"]+)"', src))
    subscribed = set(re.findall(r'subscribe(?:Camera)?\("([^"]+)"', src))
    pub_rows = {r[0].split()[0].strip("`") for r in readme_table("### Published topics")}
    sub_rows = {r[0].split()[0].strip("`").rstrip(",") for r in readme_table("### Subscribed topics")}
    assert advertised <= pub_rows, f"not in the README: {advertised - pub_rows}"
    assert subscribed | {"camera_info"} <= sub_rows, f"not in the README: {subscribed - sub_rows}"
    launch = (ROOT / "launch/kinect_pipeline.launch").read_text()
    for row in readme_table("### Published topics") + readme_table("### Subscribed topics"):
        m = re.match(r"`([^`]+)` \(`([^`]+)`\)", row[0])
        if m and m.group(1) in ("image_processed", "image_labels"):
            assert f'from="{m.group(1)}"' in launch, m.group(1)
