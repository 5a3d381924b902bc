"""No tool ever writes over one of its inputs; outputs appear whole or not at all; errors name the user's paths and
a failed run leaves no folder behind (kinect_pipeline.outputs, used by every command)."""

from __future__ import annotations

import hashlib
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest
from clitool import cli

import kinect_pipeline as kp
from kinect_pipeline.outputs import OutputError, atomic_file, atomic_new, check_outputs, output_folder

cv2 = pytest.importorskip("cv2")
pytest.importorskip("rosbags")

REAL = Path(__file__).resolve().parents[3] / "shared" / "data" / "real"
CAM = kp.kinect_v2_camera()
INTR = [str(CAM.fx), str(CAM.fy), str(CAM.cx), str(CAM.cy)]


def sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def frame(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 16-bit PNG of a rendered floor the calibration finds."""
    from kinect_pipeline.simulation.scenes import lab_scene, render_frame

    path = tmp_path_factory.mktemp("frames") / "F.png"
    assert cv2.imwrite(str(path), render_frame(CAM, lab_scene(), 1.1, 0.26, 0.0, "16UC1", seed=3).depth)
    return path


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from kinect_pipeline.simulation.sequence_bag import Scenario, write_sequence_bag

    path = tmp_path_factory.mktemp("bags") / "B.bag"
    write_sequence_bag(path, Scenario(frames=3, encoding="16UC1", seed=2))
    return path


def _refused(r: subprocess.CompletedProcess[str], *paths: object) -> None:
    assert r.returncode == 1, r.stdout + r.stderr
    line = r.stderr.strip()
    assert len(line.splitlines()) == 1, line
    assert "never overwrites its inputs" in line or "never writes into its inputs" in line, line
    for p in paths:
        assert str(p) in line, (p, line)


CASES = {
    # what the issue names
    "calibrate --plot F": lambda f, b, t: (["calibrate", str(f), "--intrinsics", *INTR, "--plot", str(f)], f),
    "curve -o F": lambda f, b, t: (["curve", str(f), "--intrinsics", *INTR, "-o", str(f)], f),
    "curve --plot F": lambda f, b, t: (["curve", str(f), "--intrinsics", *INTR, "--plot", str(f)], f),
    "calibrate --bag B --plot B": lambda f, b, t: (["calibrate", "--bag", str(b), "--plot", str(b)], b),
    "report B -o B": lambda f, b, t: (["report", str(b), "-o", str(b), "--quiet"], b),
    "replay B -o B": lambda f, b, t: (["replay", str(b), "-o", str(b), "--quiet"], b),
    # and more
    "curve --compare-plot F": lambda f, b, t: (
        ["curve", str(f), "--intrinsics", *INTR, "--compare", "--compare-plot", str(f)],
        f,
    ),
    "calibrate folder --plot F": lambda f, b, t: (
        ["calibrate", str(f.parent), "--intrinsics", *INTR, "--plot", str(f)],
        f,
    ),
    "report B -o folder/.. (B named as a report file)": lambda f, b, t: (
        ["report", str(t / "index.html"), "-o", str(t), "--quiet"],
        t / "index.html",
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_no_command_writes_over_its_input(frame: Path, bag: Path, tmp_path: Path, case: str) -> None:
    victim_dir = tmp_path / "victims"
    victim_dir.mkdir()
    (victim_dir / "index.html").write_bytes(bag.read_bytes())  # a bag that happens to share a report file's name
    args, victim = CASES[case](frame, bag, victim_dir)
    before = sha(victim)
    r = cli(*args)
    _refused(r, victim)
    assert sha(victim) == before, "the input changed"


@pytest.mark.parametrize("kind", ["symlink", "hardlink"])
def test_links_to_an_input_are_refused_naming_both(frame: Path, bag: Path, tmp_path: Path, kind: str) -> None:
    for inp, make in ((frame, "calibrate"), (bag, "report")):
        link = tmp_path / f"{kind}-{inp.name}"
        link.unlink(missing_ok=True)
        (link.symlink_to if kind == "symlink" else link.hardlink_to)(inp)
        before = sha(inp)
        if make == "calibrate":
            r = cli("calibrate", str(frame), "--intrinsics", *INTR, "--plot", str(link))
        else:
            r = cli("replay", str(bag), "-o", str(link), "--quiet")
        _refused(r, inp, link)
        assert sha(inp) == before


def test_an_output_inside_an_input_folder_is_refused(tmp_path: Path, frame: Path) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    (frames / "a.png").write_bytes(frame.read_bytes())
    r = cli("calibrate", str(frames), "--intrinsics", *INTR, "--plot", str(frames / "plot.png"))
    _refused(r, frames)
    assert sorted(p.name for p in frames.iterdir()) == ["a.png"]


def test_a_missing_output_folder_is_named_before_any_work(frame: Path, tmp_path: Path) -> None:
    r = cli("calibrate", str(frame), "--intrinsics", *INTR, "--plot", str(tmp_path / "no" / "p.png"))
    assert r.returncode == 1 and f"its folder {tmp_path / 'no'} does not exist" in r.stderr, r.stderr
    assert r.stdout == "" and not (tmp_path / "no").exists()


@pytest.mark.parametrize(
    "args",
    [
        ["curve", "{frame}", "--intrinsics", *INTR, "-o", "{out}/c.yaml", "--plot", "{out}/c.png"],
        ["calibrate", "{frame}", "--intrinsics", *INTR, "--plot", "{out}/c.png"],
    ],
    ids=["curve", "calibrate"],
)
def test_a_failed_write_names_the_users_path_and_leaves_nothing(frame: Path, tmp_path: Path, args: list[str]) -> None:
    out = tmp_path / "out"
    out.mkdir()
    r = cli(*(a.format(frame=frame, out=out) for a in args), fsize=2000)  # the PNG cannot be written
    assert r.returncode == 1, r.stdout
    line = r.stderr.strip().splitlines()[-1]
    assert f"cannot write {out / 'c.png'}: File too large" in line, line
    assert not list(out.iterdir()) or [p.name for p in out.iterdir()] == ["c.yaml"], "no temporary file left"


def test_a_failed_report_leaves_no_folder_behind(tmp_path: Path) -> None:
    bad = tmp_path / "bad.bag"
    bad.write_bytes(b"#ROSBAG V2.0\n" + bytes(100))
    out = tmp_path / "new" / "deeper" / "report"
    r = cli("report", str(bad), "-o", str(out), "--quiet")
    assert r.returncode == 1 and str(bad) in r.stderr
    assert not (tmp_path / "new").exists()


def test_a_full_disk_on_replay_names_the_output_not_its_partial_file(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "o.bag"
    r = cli("replay", str(bag), "-o", str(out), "--quiet", fsize=300_000)
    assert r.returncode == 1
    line = r.stderr.strip()
    assert f"cannot write {out}: File too large" in line and ".partial" not in line, line
    assert not list(tmp_path.iterdir())


# -- the helper itself ------------------------------------------------------------------------------------------


def test_atomic_file_appears_whole_or_not_at_all(tmp_path: Path) -> None:
    target = tmp_path / "x.png"
    target.write_bytes(b"old")
    with pytest.raises(RuntimeError), atomic_file(target) as tmp:
        tmp.write_bytes(b"half")
        raise RuntimeError("stopped")
    assert target.read_bytes() == b"old" and sorted(tmp_path.iterdir()) == [target]
    with atomic_file(target) as tmp:
        assert tmp.suffix == ".png" and tmp.parent == tmp_path and tmp.name.startswith(".x.png.")
        tmp.write_bytes(b"new")
    assert target.read_bytes() == b"new" and sorted(tmp_path.iterdir()) == [target]


@pytest.mark.parametrize("umask", [0o022, 0o027])
def test_outputs_get_the_mode_of_any_file_the_user_writes(frame: Path, bag: Path, tmp_path: Path, umask: int) -> None:
    """Outputs are 0666 less the umask (0644 as a rule), as a shell redirect or cp makes them: never the 0600 of
    the temporary file they are written to first."""
    old = os.umask(umask)
    try:
        runs = [
            ["report", str(bag), "-o", str(tmp_path / "rep"), "--quiet"],
            ["replay", str(bag), "-o", str(tmp_path / "r.bag"), "--quiet"],
            ["calibrate", str(frame), "--intrinsics", *INTR, "--plot", str(tmp_path / "cal.png")],
            ["curve", str(frame), "--intrinsics", *INTR, "-o", str(tmp_path / "c.yaml")],
        ]
        for args in runs:
            r = cli(*args)
            assert r.returncode == 0, (args, r.stderr)
        with atomic_file(tmp_path / "direct.txt") as tmp:
            tmp.write_text("x")
    finally:
        os.umask(old)
    files = [p for p in tmp_path.rglob("*") if p.is_file()]
    assert len(files) >= 9, files
    modes = {p.relative_to(tmp_path).as_posix(): oct(p.stat().st_mode & 0o777) for p in files}
    assert set(modes.values()) == {oct(0o666 & ~umask)}, modes


def test_atomic_new_gives_a_fresh_path_and_renames_folders(tmp_path: Path) -> None:
    target = tmp_path / "bag2"
    with atomic_new(target) as tmp:
        assert not tmp.exists()
        tmp.mkdir()
        (tmp / "metadata.yaml").write_text("x")
    assert (target / "metadata.yaml").read_text() == "x"
    with pytest.raises(OutputError, match=r"cannot write .*other: disk gone"), atomic_new(tmp_path / "other") as tmp:
        tmp.mkdir()
        raise OSError("disk gone")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag2"]


def test_output_folder_removes_only_what_it_made(tmp_path: Path) -> None:
    keep = tmp_path / "keep"
    keep.mkdir()
    with pytest.raises(ValueError), output_folder(keep / "a" / "b"):
        raise ValueError("failed")
    assert sorted(tmp_path.rglob("*")) == [keep]
    with output_folder(keep / "a") as d:
        (d / "f").write_text("x")
    assert (keep / "a" / "f").exists()
    # A mark made first goes with a new folder its run failed to fill; an old folder keeps its mark.
    with pytest.raises(ValueError), output_folder(keep / "m", mark=".mark"):
        raise ValueError("failed")
    assert not (keep / "m").exists()
    with pytest.raises(ValueError), output_folder(keep / "a", mark=".mark"):
        raise ValueError("failed")
    assert (keep / "a" / ".mark").exists() and (keep / "a" / "f").exists()


def test_check_outputs_compares_resolved_paths(tmp_path: Path) -> None:
    f = tmp_path / "in.png"
    f.write_bytes(b"x")
    os.symlink(f, tmp_path / "l.png")
    with pytest.raises(OutputError, match=r"through links, both are"):
        check_outputs([f], [tmp_path / "l.png"])
    with pytest.raises(OutputError, match="is the input"):
        check_outputs([tmp_path / "." / "in.png"], [f])
    check_outputs([f], [tmp_path / "other.png"], [])  # fine
    if (REAL / "slambook2").exists():
        with pytest.raises(OutputError, match="inside the input folder"):
            check_outputs([REAL / "slambook2"], [REAL / "slambook2" / "ch7" / "x.png"])


def test_python_m_and_the_script_are_the_same_cli() -> None:
    r = cli("--help")
    assert r.returncode == 0 and "usage: kinect-pipeline" in r.stdout
    assert "``" not in r.stdout and ":func:" not in r.stdout, "no raw RST markup in the top-level help"
    np.testing.assert_equal(r.stderr, "")


def test_one_file_named_for_two_outputs_is_refused_before_any_work(frame: Path, tmp_path: Path) -> None:
    """curve -o c.yaml --plot c.yaml wrote the PNG over the YAML and said "YAML: c.yaml", exit 0."""
    out = tmp_path / "c.yaml"
    r = cli("curve", str(frame), "--intrinsics", *INTR, "-o", str(out), "--plot", str(out))
    assert r.returncode == 1 and f"outputs -o {out} and --plot {out} are the same file" in r.stderr, r.stderr
    assert r.stdout == "" and not out.exists()
    with pytest.raises(OutputError, match="are the same file"):
        check_outputs([], [tmp_path / "a.png", tmp_path / "." / "a.png"])


def test_a_folder_that_takes_no_file_is_named_as_the_user_named_the_output() -> None:
    """A temporary could not be made in /proc: the error named it (/proc/.x.yaml.6wfrew93.yaml), not -o's path."""
    with pytest.raises(OutputError, match=r"^cannot write /proc/x\.yaml: ") as e, atomic_file("/proc/x.yaml"):
        pass
    assert ".x.yaml." not in str(e.value)
    r = cli("curve", "--from-model", "0.0015", "0.0019", "-o", "/proc/x.yaml")
    assert r.returncode == 1 and r.stderr.strip().endswith(
        "output -o /proc/x.yaml: cannot make a file in /proc (No such file or directory)"
    )


def test_a_folder_that_takes_no_file_is_told_before_the_work(tmp_path: Path) -> None:
    """curve --compare-plot /proc/x.png compared the curves on generated frames, then failed writing the plot."""
    r = cli("curve", "--from-model", "0.0015", "0.0019", "--compare", "--compare-plot", "/proc/x.png")
    assert r.returncode == 1 and r.stdout == "", r.stdout
    assert "output --compare-plot /proc/x.png: cannot make a file in /proc" in r.stderr
    check_outputs([], [tmp_path / "a.png"])  # a folder that takes files: the probe leaves nothing behind
    assert not list(tmp_path.iterdir())


def test_a_folder_of_the_users_files_is_not_written_over_but_an_earlier_run_is(bag: Path, tmp_path: Path) -> None:
    """report -o DIR and demo --out DIR wrote over files of their names in any folder (a user's demo.bag too);
    a folder of their own earlier run is still written again (the demo is run twice by the quick start)."""
    user = tmp_path / "user"
    user.mkdir()
    (user / "frame.png").write_text("mine")
    (user / "demo.bag").write_text("my bag")
    r = cli("report", str(bag), "-o", str(user), "--quiet")
    assert r.returncode == 1 and f"{user} holds frame.png but no index.html" in r.stderr, r.stderr
    r = cli("demo", "--out", str(user), "--frames", "2")
    assert r.returncode == 1 and "holds frame.png, demo.bag but no .kinect-pipeline-demo or quality.json" in r.stderr
    assert (user / "frame.png").read_text() == "mine" and (user / "demo.bag").read_text() == "my bag"
    assert sorted(p.name for p in user.iterdir()) == ["demo.bag", "frame.png"]
    rep = tmp_path / "rep"
    for _ in range(2):
        r = cli("report", str(bag), "-o", str(rep), "--quiet")
        assert r.returncode == 0, r.stderr
    demo = tmp_path / "demo"
    for _ in range(2):
        r = cli("demo", "--out", str(demo), "--frames", "2")
        assert r.returncode == 0, r.stderr
    (demo / ".kinect-pipeline-demo").unlink()  # a demo folder of a version before the mark
    assert cli("demo", "--out", str(demo), "--frames", "2").returncode == 0
