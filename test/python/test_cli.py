"""The command line: one module per command, help with unit and default for every option, one-line errors."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

import kinect_pipeline as kp
from kinect_pipeline.cli import COMMANDS, build_parser, main


def _subparsers() -> dict[str, argparse.ArgumentParser]:
    p = build_parser()
    action = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_one_module_per_command() -> None:
    subs = _subparsers()
    assert sorted(subs) == sorted(m.NAME for m in COMMANDS)
    for mod in COMMANDS:
        assert mod.__name__ == "kinect_pipeline.cli." + mod.NAME.replace("-", "_")
        func = subs[mod.NAME].get_default("func")
        assert func.__module__ == mod.__name__
        lines = Path(mod.__file__).read_text().count("\n")
        assert lines < 200, f"{mod.__name__} is {lines} lines: the work belongs in the library"


UNIT = re.compile(r"\[[^\]]+\]")


@pytest.mark.parametrize("command", sorted(m.NAME for m in COMMANDS))
def test_every_option_says_what_it_is_its_unit_and_default(command: str) -> None:
    sub = _subparsers()[command]
    text = sub.format_help()
    for action in sub._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        name = "/".join(action.option_strings) or action.dest
        assert action.help and len(action.help) > 10, f"{command} {name}: no help"
        helptext = sub._get_formatter()._expand_help(action)
        if action.option_strings and not action.required:
            assert "default" in helptext, f"{command} {name}: no default stated: {helptext!r}"
        if action.type in (int, float):
            assert UNIT.search(helptext), f"{command} {name}: no [unit] in {helptext!r}"
    assert "%(" not in text


def test_top_level_help_is_plain_text(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["--help"])
    out = capsys.readouterr().out
    for markup in ("``", ":func:", ":class:", ".. "):
        assert markup not in out
    for mod in COMMANDS:
        assert mod.NAME in out


@pytest.mark.parametrize(
    ("item", "expect"),
    [
        ("sensor_heigth=1.1", "no Config field 'sensor_heigth'; the fields are "),
        ("sensor_height", "expected NAME=VALUE with NAME one of "),
        ("sensor_height=", "expected NAME=VALUE with NAME one of "),
        ("=1.1", "expected NAME=VALUE with NAME one of "),
        ("sensor_height=-1", "--param sensor_height=-1: "),
        ("projection=sideways", "--param projection=sideways: "),
        ("sensor_height=abc", "Config.sensor_height = 'abc' (str): expected a number [m]"),
        ("open_kernel_size=2.5", "Config.open_kernel_size = 2.5 (float): expected an integer [px]"),
        ("threshold_curve=5", "threshold_curve = 5 (int): expected 'd:t, ...' text or (depth, threshold) pairs"),
    ],
)
def test_bad_param_is_one_line_naming_the_valid_fields(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], item: str, expect: str
) -> None:
    rc = main(["replay", str(tmp_path / "none.bag"), "-o", str(tmp_path / "o.bag"), "--param", item, "--quiet"])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and len(err.splitlines()) == 1, err
    assert expect in err, err
    if "field" in expect or "NAME one of" in expect:
        for f in ("sensor_height", "threshold_curve", "cliff_scan", "num_threads"):
            assert f in err
    assert "Traceback" not in err and not (tmp_path / "o.bag").exists()


def test_a_good_param_reaches_the_core(tmp_path: Path) -> None:
    from kinect_pipeline.cli._common import parse_params

    got = parse_params(["sensor_height=0.8", "intensity_filter=true", "threshold_curve=0.5:0.05, 12:1.0"])
    assert got == {"sensor_height": 0.8, "intensity_filter": True, "threshold_curve": "0.5:0.05, 12:1.0"}
    assert kp.Config(**got).sensor_height == 0.8


@pytest.mark.parametrize(
    ("intr", "expect"),
    [
        (["0", "365", "255", "211"], "fx"),
        (["365", "-3", "255", "211"], "fy"),
        (["365", "365", "nan", "211"], "cx"),
        (["365", "365", "255", "211", "0", "0"], "size 0x0: expected whole pixels, at least 1x1"),
    ],
)
def test_bad_intrinsics_name_the_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], intr: list[str], expect: str
) -> None:
    import numpy as np

    f = tmp_path / "f.npy"
    np.save(f, np.full((424, 512), 2.0, np.float32))
    for cmd in ("calibrate", "curve"):
        rc = main([cmd, str(f), "--intrinsics", *intr])
        err = capsys.readouterr().err.strip()
        assert rc == 1 and len(err.splitlines()) == 1, err
        assert err.startswith(f"kinect-pipeline {cmd}: --intrinsics {','.join(intr)}: ") and expect in err, err


@pytest.mark.parametrize(
    ("matrix", "expect"),
    [
        ("365, 4, 255, 0, 365, 211, 0, 0, 1", "K[1] (skew) = 4: "),
        ("365, 0, 255, 0, 365, 211, 0, 0, 0", "expected a pinhole camera's [fx s cx; 0 fy cy; 0 0 1]"),
    ],
)
def test_a_camera_info_yaml_whose_matrix_would_be_misread_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], matrix: str, expect: str
) -> None:
    import numpy as np

    f, y = tmp_path / "f.npy", tmp_path / "cam.yaml"
    np.save(f, np.full((424, 512), 2.0, np.float32))
    y.write_text(f"image_width: 512\nimage_height: 424\ncamera_matrix:\n  rows: 3\n  cols: 3\n  data: [{matrix}]\n")
    assert main(["calibrate", str(f), "--intrinsics", str(y)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"kinect-pipeline calibrate: --intrinsics {y}: ") and expect in err, err


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["quality", "--frames", "0"], "argument --frames: '0': expected a whole number 1..1000000"),
        (["cliff", "--frames", "-1"], "argument --frames: '-1': expected a whole number 1..1000000"),
        (["evaluate", "--frames", "0"], "argument --frames: '0': expected a whole number"),
        (["evaluate", "--pitch", "nan"], "argument --pitch: 'nan': expected a finite number"),
        (["demo", "--frames", "0"], "argument --frames: '0': expected a whole number 1..100000"),
        (["synth", "x.bag", "--seed", "-5"], "argument --seed: '-5': expected a whole number 0.."),
        (["synth", "x.bag", "--frames", "1000000000"], "argument --frames: '1000000000': expected a whole number"),
        (["synth", "x.bag", "--tf-error-pitch", "inf"], "argument --tf-error-pitch: 'inf': expected a finite number"),
        (["soak", "--minutes", "nan"], "argument --minutes: 'nan': expected a finite number > 0"),
        (["bench-ros", "--rate", "0"], "argument --rate: '0': expected a finite number > 0"),
        (["bench", "--frames", "0"], "argument --frames: '0': expected a whole number"),
        (["fleet", "--bench", "--bench-recordings", "0"], "argument --bench-recordings: '0': expected a whole number"),
        (["fleet", "x", "-o", "f", "--frame-rate", "0"], "argument --frame-rate: '0': expected a finite number > 0"),
        (
            ["fleet", "x", "-o", "f", "--threads", "100000"],
            "argument --threads: '100000': expected a whole number 0..1024",
        ),
        (["curve", "--from-model", "nan", "0.0019"], "argument --from-model: 'nan': expected a finite number > 0"),
        (
            ["curve", "--from-model", "0.0015", "0.0019", "--rate", "0.7"],
            "'0.7': expected a finite number > 0 and <= 0.5",
        ),
        (["curve", "--from-model", "0.0015", "0.0019", "--margin", "-1"], "argument --margin: '-1': expected a finite"),
        (["calibrate", "--bag", "x.bag", "--max-tilt", "91"], "argument --max-tilt: '91': expected a finite number"),
        (["calibrate", "f.png", "--depth-scale", "0"], "argument --depth-scale: '0': expected a finite number > 0"),
        (
            ["replay", "in.bag", "-o", "o.bag", "--max-frames", "0"],
            "argument --max-frames: '0': expected a whole number",
        ),
        (["replay", "in.bag", "-o", "o.bag", "--base-frame-height", "nan"], "argument --base-frame-height: 'nan'"),
        (["report", "in.bag", "-o", ""], "argument -o/--out: an empty value"),
        (["demo", "--out", ""], "argument --out: an empty value"),
        (["quality", "--bag", ""], "argument --bag: an empty value"),
        (["replay", "in.bag", "-o", "o.bag", "--info-topic", ""], "argument --info-topic: an empty value"),
        (["replay", "in.bag", "-o", "o.bag", "--intrinsics", ""], "argument --intrinsics: an empty value"),
        (["curve", "--from-model", "0.0015", "0.0019", "--plot", ""], "argument --plot: an empty value"),
        (["fleet", "x", "-o", "f", "--scheduler", ""], "argument --scheduler: an empty value"),
    ],
)
def test_a_bad_number_or_an_empty_value_is_refused_before_anything_runs(
    args: list[str], says: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, these ran: tracebacks (frames 0, a negative seed), tables of NaN with exit 0 (cliff --frames 0, a
    NaN noise model), an empty output folder meaning the current one, an empty topic or file ignored."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as stop:
        main(args)
    err = capsys.readouterr().err
    assert stop.value.code == 2 and says in err, err
    assert not list(tmp_path.iterdir()), "nothing is written"


def test_no_number_option_is_left_unchecked() -> None:
    """Every whole-number and real option parses through count() or number() (their range in the message), but
    the bench's --kernel and --surface-band, which the pipeline's own Config validation checks (as it does each of
    the bench's --roll list)."""
    loose = [
        f"{name} {'/'.join(a.option_strings)}"
        for name, sub in _subparsers().items()
        for a in sub._actions
        if a.type in (int, float)
    ]
    assert loose == ["bench --kernel", "bench --surface-band"], loose


def test_a_contradiction_or_an_option_without_its_work_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each ran with exit 0 and did less than asked: frames beside --from-model were not fitted, --compare-plot
    without --compare was not drawn, a --real-frames folder without frames was left out of the table."""
    f = tmp_path / "f.npy"
    f.write_bytes(b"")
    cases = [
        (["curve", str(f), "--from-model", "0.0015", "0.0019"], "--from-model fits no frames: give it or frames"),
        (["quality", "--frames", "1", "--quiet", "--real-frames", str(tmp_path)], "no depth/*.png in it"),
        (["fleet", "--bench", str(f)], "--bench replays synthetic recordings of its own: give it or IN..., not both"),
    ]
    for args, says in cases:
        assert main(args) == 1
        assert says in capsys.readouterr().err
    assert not (tmp_path / "c.png").exists()


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["curve", "--from-model", "0.0015", "0.0019", "--compare-plot", "c.png"], "--compare-plot: needs --compare"),
        (["curve", "--from-model", "0.0015", "0.0019", "--compare-frames", "3"], "--compare-frames: needs --compare"),
        (["quality", "--frames", "1", "--param", "range_max=3"], "--param: needs --bag"),
        (["quality", "--intrinsics", "1", "1", "1", "1"], "--intrinsics: needs --bag"),
        (["quality", "--base-frame", "base_link"], "--base-frame: needs --bag"),
        (["quality", "--bag", "x.bag", "--frames", "3"], "--frames: not with --bag"),
        (["quality", "--bag", "x.bag", "--enc", "8UC1"], "--encoding: not with --bag"),  # an abbreviation too
        (["quality", "--bag", "x.bag", "--real-frames=/tmp"], "--real-frames: not with --bag"),
        (["fleet", "--bench-frames", "3"], "--bench-frames: needs --bench"),
        (["fleet", "--bench", "--workers", "2"], "--workers: not with --bench"),
        (["fleet", "--bench", "-o", "out"], "-o/--output: not with --bench"),
        (["calibrate", "f.png", "--base-frame-height", "0.3"], "--base-frame-height: needs --bag"),
        (["calibrate", "--bag", "x.bag", "--depth-scale", "0.0002"], "--depth-scale: not with --bag"),
    ],
)
def test_an_option_its_mode_would_ignore_is_refused(
    args: list[str], says: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each was ignored with exit 0: the command did less than asked (quality --bag scored no --frames, fleet
    --bench measured 4 recordings when told 2 workers). Told before any work, as the parser's error (exit 2)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exc:
        main(args)
    assert exc.value.code == 2
    assert f"argument {says} (it would be ignored)" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_an_option_in_its_mode_or_at_its_default_is_taken(capsys: pytest.CaptureFixture[str]) -> None:
    """The check reads what was given, not the values: the default given by hand in the mode is fine."""
    assert main(["curve", "--from-model", "0.0015", "0.0019", "--compare", "--compare-frames", "1"]) == 0
    assert "on 1 generated noisy frames" in capsys.readouterr().out


def test_an_empty_value_that_means_none_or_is_the_default_is_let_be() -> None:
    """quality's --real-frames "" says: no real frames (its help); a default of "" is not the user's."""
    from kinect_pipeline.cli import _parsers
    from kinect_pipeline.cli._common import refuse_empty

    _, commands = _parsers()
    q = commands["quality"]
    refuse_empty(q, q.parse_args(["--real-frames", ""]))
    q.set_defaults(info_topic="")
    refuse_empty(q, q.parse_args([]))
    with pytest.raises(SystemExit):
        refuse_empty(q, q.parse_args(["--bag", ""]))


def test_a_measure_no_frame_could_take_is_a_dash_not_nan(capsys: pytest.CaptureFixture[str]) -> None:
    """evaluate looking straight down: no obstacle and no ceiling in view; it printed nan (with numpy warnings)."""
    assert main(["evaluate", "--frames", "1", "--encodings", "16UC1", "--pitch", "1.5707"]) == 0
    out = capsys.readouterr()
    assert "nan" not in out.out and "| – |" in out.out and "no pixel or beam of that kind" in out.out, out.out
    assert "RuntimeWarning" not in out.err


def test_a_report_of_frames_without_one_depth_pixel_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Frames of nothing but no return (a wrong encoding, an empty recording) gave a report of nothing, exit 0."""
    import numpy as np

    f = tmp_path / "black.npy"
    np.save(f, np.zeros((120, 160), np.float32))
    pose = ["--param", "sensor_height=0.5", "--param", "sensor_pitch=0.4"]
    assert main(["report", str(f), "-o", str(tmp_path / "rep"), "--quiet", "--intrinsics", "100,100,80,60", *pose]) == 1
    assert "no pixel of the 1 frame(s) holds a depth (all are no return)" in capsys.readouterr().err
    assert not (tmp_path / "rep").exists()


def test_a_report_option_its_input_would_ignore_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """report's mode is its input's kind: --depth-topic beside frames, --depth-scale beside a bag were ignored."""
    import numpy as np

    f = tmp_path / "f.npy"
    np.save(f, np.ones((120, 160), np.float32))
    bag = tmp_path / "x.bag"
    bag.write_bytes(b"#ROSBAG V2.0\n")
    for args, says in (
        (
            [str(f), "--intrinsics", "100,100,80,60", "--depth-topic", "/d"],
            "--depth-topic: for a bag only, and the input is depth frames",
        ),
        ([str(bag), "--depth-scale", "0.0002"], "--depth-scale: for depth frames only, and the input is a bag"),
    ):
        assert main(["report", *args, "-o", str(tmp_path / "rep"), "--quiet"]) == 1
        assert says in capsys.readouterr().err
    assert not (tmp_path / "rep").exists()


def test_a_pictures_folder_that_cannot_be_made_fails_before_the_work(capsys: pytest.CaptureFixture[str]) -> None:
    """cliff computed and printed its whole table, then failed on --pictures /proc/x."""
    assert main(["cliff", "--frames", "1", "--quiet", "--pictures", "/proc/x"]) == 1
    out = capsys.readouterr()
    assert out.out == "" and "cannot make the folder /proc/x" in out.err, out
