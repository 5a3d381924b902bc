"""The fleet at a glance: ``OUT/index.html`` from ``OUT/fleet.json``, the worst recordings first, with the learned
floor correction of each recording over time (``learned.png``): a mount that moved shows as a correction far from
zero, a mount that is moving as one that drifts."""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

from ..outputs import save_figure, write_text

SHOWN = 12  #: recordings drawn (the worst)


def badness(row: dict[str, Any]) -> float:
    """How far the learned correction is from zero: |pitch| + |roll| [deg] + |height| [cm]; rows that are not ok
    come before all."""
    if row.get("status") != "ok":
        return math.inf
    vals = [row.get("learned_pitch_deg"), row.get("learned_roll_deg"), (row.get("learned_height_m") or 0) * 100]
    return sum(abs(v) for v in vals if isinstance(v, (int, float)) and math.isfinite(v))


def worst_first(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return sorted(rows, key=lambda r: (-badness(r), r["recording"], r["config"]))


def _plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    for r in rows:
        s = r.get("series") or []
        if not s:
            continue
        t = [p[0] for p in s]
        label = f"{Path(r['recording']).name} [{r['config']}]"
        axes[0].plot(t, [p[1] * 1000 for p in s], label=label)
        axes[1].plot(t, [math.degrees(p[2]) for p in s])
        axes[2].plot(t, [math.degrees(p[3]) for p in s])
    for ax, what in zip(axes, ("height [mm]", "pitch [deg]", "roll [deg]"), strict=True):
        ax.set_ylabel(f"learned {what}")
        ax.axhline(0, color="0.6", lw=0.8)
        ax.grid(alpha=0.3)
    axes[2].set_xlabel("time since the recording's first frame [s]")
    if any(r.get("series") for r in rows):
        axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"learned floor correction over each recording (the {len(rows)} worst)")
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _cell(v: Any) -> str:
    if isinstance(v, float):
        return "" if not math.isfinite(v) else f"{v:.4g}"
    return html.escape("" if v is None else str(v))


def write_index(out: Path) -> None:
    """``out/index.html`` (and ``learned.png``) from ``out/fleet.json``."""
    rows = worst_first(json.loads((out / "fleet.json").read_text())["rows"])
    first = {r["config"] for r in rows if not r.get("vs_config")}
    _plot([r for r in rows if r["config"] in first and r.get("series")][:SHOWN], out / "learned.png")
    cols = [
        "recording", "config", "status", "frames", "dropped", "damaged", "ms_per_frame", "fit_accepted",
        "learned_height_m", "learned_pitch_deg", "learned_roll_deg", "drift_pitch_deg", "cliff_beams",
        "phantom_proxy", "scan_change", "vs_config", "beams_moved", "fit_changed",
    ]  # fmt: skip
    bad = sum(r["status"] != "ok" for r in rows)
    head = "".join(f"<th>{c}</th>" for c in cols)
    body = "\n".join(
        "<tr" + (' class="bad"' if r["status"] != "ok" else "") + ">"
        + "".join(f"<td>{_cell(r.get(c))}</td>" for c in cols) + "</tr>"
        for r in rows
    )  # fmt: skip
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>kinect-pipeline fleet</title>
<style>body{{font-family:sans-serif}} td,th{{padding:2px 6px;font-size:12px}} tr.bad{{background:#fdd}}
table{{border-collapse:collapse}} tr:nth-child(even){{background:#f4f4f4}}</style></head><body>
<h1>Fleet: {len({r["recording"] for r in rows})} recordings, {len(rows)} rows, {bad} not ok</h1>
<p>Worst first: rows that are not ok, then by how far the floor refinement's learned correction is from zero
(|pitch| + |roll| in degrees + |height| in cm): a camera mount that moved. Table: <a href="fleet.csv">fleet.csv</a>,
<a href="fleet.json">fleet.json</a>.</p>
<img src="learned.png" alt="learned correction over time per recording">
<p><i>The learned floor correction (height, pitch, roll) over each of the worst recordings: flat near zero is a
mount as configured; an offset is a mount that moved; a slope or steps within a recording is one that is moving.</i></p>
<table><tr>{head}</tr>
{body}
</table></body></html>
"""
    write_text(out / "index.html", page)
