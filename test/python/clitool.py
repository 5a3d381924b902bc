"""Running the command line as a user does: ``python -m kinect_pipeline.cli ...`` in a child process."""

from __future__ import annotations

import resource
import signal
import subprocess
import sys
from pathlib import Path


def cli(*args: str, fsize: int | None = None, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """The command's result; ``fsize``: a limit on the size of files it writes [bytes] (a full disk)."""

    def limit() -> None:
        if fsize is not None:
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead
            resource.setrlimit(resource.RLIMIT_FSIZE, (fsize, fsize))

    return subprocess.run(
        [sys.executable, "-m", "kinect_pipeline.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        preexec_fn=limit,
    )
