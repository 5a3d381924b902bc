"""What every tool writes goes through here: no output ever lands on one of the tool's inputs, outputs appear
atomically (written to a hidden temporary beside them, then renamed), errors name the user's paths, and a failed
run leaves no folder it created behind.

A tool first calls :func:`check_outputs` with all of its inputs and outputs, before it writes anything; then it
writes each file through :func:`atomic_file` (or :func:`atomic_folder` for a folder such as a rosbag2 bag), inside
:func:`output_folder` when it fills a folder of several files.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any


class OutputError(ValueError):
    """An output the tool refuses to write (it would overwrite an input, its folder is missing) or could not
    write; the message names the user's paths."""


@dataclass(frozen=True)
class Named:
    """A path and how the user named it on the command line (e.g. ``--plot``), for messages."""

    path: Path
    name: str = ""

    def __str__(self) -> str:
        return f"{self.name} {self.path}" if self.name else str(self.path)


PathLike = str | os.PathLike[str] | Named


def _named(p: PathLike) -> Named:
    return p if isinstance(p, Named) else Named(Path(p))


def _same(a: Path, b: Path) -> bool:
    """The same file or folder, through symbolic links (resolved) and hard links (same inode)."""
    if a.resolve() == b.resolve():
        return True
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return False


def _inside(child: Path, folder: Path) -> bool:
    return child.resolve().is_relative_to(folder.resolve()) and child.resolve() != folder.resolve()


def _via_links(out: Named, inp: Named) -> str:
    real = out.path.resolve()
    plain = {Path(os.path.abspath(out.path)), Path(os.path.abspath(inp.path))}
    return "" if plain == {real} else f" (through links, both are {real})"


def check_outputs(inputs: Iterable[PathLike], outputs: Iterable[PathLike], folders: Iterable[PathLike] = ()) -> None:
    """Refuses, before anything is written, every output that would write over an input.

    An output conflicts with an input when it is the same file or folder (also through symbolic or hard links) or
    when it lies inside an input folder (a rosbag2 bag, a folder of frames). ``outputs`` are the files the tool
    writes (name every file it writes into a folder), ``folders`` the folders it fills. Also refused: a file output
    whose folder does not exist and is not one of ``folders``, and two outputs that are the same file. Raises
    :class:`OutputError` naming both paths."""
    ins = [_named(p) for p in inputs]
    files = [_named(p) for p in outputs]
    dirs = [_named(p) for p in folders]
    for out in files + dirs:
        for inp in ins:
            if _same(out.path, inp.path):
                raise OutputError(
                    f"output {out} is the input {inp}{_via_links(out, inp)}: a tool never overwrites its inputs; "
                    "choose another output name"
                )
            if inp.path.is_dir() and _inside(out.path, inp.path):
                raise OutputError(
                    f"output {out} lies inside the input folder {inp}: a tool never writes into its inputs; "
                    "choose an output outside it"
                )
    for i, out in enumerate(files):
        for other in files[:i]:
            if _same(out.path, other.path):
                raise OutputError(f"outputs {other} and {out} are the same file: expected one name for each output")
    for out in files:
        parent = out.path.parent
        if not parent.is_dir() and not any(_inside(out.path, d.path) or _same(parent, d.path) for d in dirs):
            raise OutputError(f"output {out}: its folder {parent} does not exist")
        if parent.is_dir():
            _probe(out, parent)


def _probe(out: Named, folder: Path) -> None:
    """A folder that takes no new file (read-only, /proc, no permission) is told before any work, by making and
    removing a hidden file there (as root, os.access says yes even for /proc): before, it was found after the
    work, when the output was written."""
    try:
        fd, name = tempfile.mkstemp(dir=folder, prefix=".kinect-pipeline-probe-")
    except OSError as exc:
        raise OutputError(f"output {out}: cannot make a file in {folder} ({exc.strerror or exc})") from exc
    os.close(fd)
    os.unlink(name)


def check_rewrite(folder: PathLike, names: Iterable[str], markers: tuple[str, ...], what: str) -> None:
    """A folder that holds files of the names a tool writes into it may be written again only where it is the
    tool's own earlier output, which holds one of ``markers``: a user's files of those names are never written
    over. Raises :class:`OutputError` naming the files."""
    path = Path(_named(folder).path)
    there = [n for n in names if (path / n).exists()]
    if there and not any((path / m).exists() for m in markers):
        raise OutputError(
            f"{path} holds {', '.join(there)} but no {' or '.join(markers)}: not {what} of an earlier run, so not "
            "written over: expected a new folder, or one of an earlier run"
        )


def _translate(exc: BaseException, tmp: Path, path: Path) -> OutputError:
    """The error of writing ``tmp``, told as the user's ``path``."""
    if isinstance(exc, OSError) and exc.strerror:
        return OutputError(f"cannot write {path}: {exc.strerror}")
    return OutputError(f"cannot write {path}: {str(exc).replace(str(tmp), str(path))}")


@contextmanager
def _as_users(tmp: Path, path: Path) -> Iterator[None]:
    """Errors of writing the temporary ``tmp`` (OSError, or any naming it) raised as OutputError naming ``path``."""
    try:
        yield
    except Exception as exc:
        if isinstance(exc, OSError) or str(tmp) in str(exc):
            raise _translate(exc, tmp, path) from exc
        raise


def _umask() -> int:
    """The process's umask (read by setting it and setting it back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def as_user_file(path: Path) -> None:
    """Gives ``path`` the mode any file the user writes gets (0666 less the umask: 0644 as a rule), not the 0600 of
    a temporary file."""
    os.chmod(path, 0o666 & ~_umask())


def temporary_name(path: Path, tag: str = "tmp") -> Path:
    """A hidden name beside ``path`` for writing it (unique per process)."""
    return path.with_name(f".{path.name}.{tag}-{os.getpid()}")


@contextmanager
def atomic_file(path: PathLike, keep_suffix: bool = True) -> Iterator[Path]:
    """Yields a temporary path beside ``path`` to write; on success it is renamed to ``path`` (which then appears
    whole or not at all), on failure removed. ``keep_suffix``: the temporary ends as ``path`` does (for writers
    that choose the format by the suffix, as matplotlib and OpenCV do). The file gets the mode of any file the user
    writes (0644 under the usual umask), not the temporary's 0600. An error names ``path``, never the temporary."""
    path = Path(_named(path).path)
    try:
        fd, name = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=(path.suffix if keep_suffix else ".tmp"), dir=path.parent or Path(".")
        )
    except OSError as exc:  # the folder cannot take a file (/proc, read-only): the temporary's name is not the user's
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from exc
    os.close(fd)
    tmp = Path(name)
    try:
        with _as_users(tmp, path):
            yield tmp
            as_user_file(tmp)
            os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def atomic_new(path: PathLike) -> Iterator[Path]:
    """As :func:`atomic_file` for writers that create their output themselves (a ROS 1 bag, a rosbag2 folder):
    yields a temporary path beside ``path`` that does not exist yet; on success renamed to ``path``, on failure
    removed with whatever was written there."""
    path = Path(_named(path).path)
    tmp = temporary_name(path)
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        with _as_users(tmp, path):
            yield tmp
            if path.exists():
                raise OutputError(f"{path} appeared while it was written: not replacing it")
            os.replace(tmp, path)
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)
        elif tmp.exists():
            tmp.unlink()


@contextmanager
def output_folder(path: PathLike, mark: str | None = None) -> Iterator[Path]:
    """Yields ``path`` as a folder, created with its missing parents; if the block fails, the folders it created
    are removed again when they are empty (a failed run leaves no empty folders). ``mark``: a file made in it
    first, saying the tool's files there are its own (:func:`check_rewrite`); a failed run that wrote nothing
    else into a folder it created takes it away again."""
    path = Path(_named(path).path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{path} exists and is not a folder: expected a folder for the outputs")
    created: list[Path] = []
    p = path
    while not p.exists():
        created.append(p)
        p = p.parent
    try:
        for d in reversed(created):
            d.mkdir()
    except OSError as exc:
        _remove_empty(created)
        raise OutputError(f"cannot make the folder {path}: {exc.strerror}") from exc
    if mark:
        (path / mark).touch()
    try:
        yield path
    except BaseException:
        if mark and path in created and [p.name for p in path.iterdir()] == [mark]:
            (path / mark).unlink()
        _remove_empty(created)
        raise


def _remove_empty(folders: list[Path]) -> None:
    for d in folders:  # innermost first
        try:
            d.rmdir()
        except OSError:
            return


def write_text(path: PathLike, text: str) -> None:
    """``text`` to ``path``, atomically."""
    with atomic_file(path) as tmp:
        tmp.write_text(text)


def save_figure(fig: object, path: PathLike, dpi: int = 110) -> None:
    """A matplotlib figure as a PNG at ``path``, atomically."""
    with atomic_file(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")  # type: ignore[attr-defined]


def progress(items: Iterable[Any], total: int, desc: str) -> Iterator[Any]:
    """A tqdm progress bar with frames/s when tqdm is there and stderr is a terminal or CI log."""
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is in requirements.txt
        yield from items
        return
    yield from tqdm(items, total=total, desc=desc, unit="frame", dynamic_ncols=True, mininterval=0.5)
