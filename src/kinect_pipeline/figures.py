"""Pictures of processed frames: the raw depth, the cleaned depth and the labels side by side."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import _core
from .outputs import save_figure


def to_metres(depth: np.ndarray, max_depth: float) -> np.ndarray:
    """Encoded depth -> float metres for display (unknown and removed values -> NaN)."""
    if depth.dtype == np.uint8:
        m = depth.astype(np.float32) / 255.0 * max_depth
        m[(depth < 2) | (depth == 255)] = np.nan
    elif depth.dtype == np.uint16:
        m = depth.astype(np.float32) / 1000.0
        m[depth == 0] = np.nan
    else:
        m = depth.astype(np.float32).copy()
        m[~np.isfinite(m) | (m <= 0)] = np.nan
    return m


def plot_frame(depth: np.ndarray, res: _core.Result, max_depth: float, path: Path, title: str) -> None:
    """Raw depth (the encoded input), cleaned depth and labels side by side (thesis figs 4.11, 4.17a/b)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    raw = to_metres(depth, max_depth)
    clean = to_metres(res.depth, max_depth)
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.6))
    for a, img, name in ((ax[0], raw, "raw depth"), (ax[1], clean, "cleaned depth (for the human detector)")):
        im = a.imshow(img, cmap="viridis", vmin=0, vmax=min(max_depth, 8.0))
        a.set_title(name)
        a.axis("off")
    fig.colorbar(im, ax=ax[:2].tolist(), shrink=0.8, label="depth [m]")
    ax[2].imshow(_core.colour_labels(res.depth, res.labels, max_depth))
    ax[2].set_title("labels")
    ax[2].axis("off")
    names = {1: "invalid", 2: "floor", 3: "above ceiling plane", 4: "below floor"}
    ax[2].legend(
        handles=[
            Patch(
                color=np.array(_core.colour_labels(np.zeros((1, 1), np.uint16), np.full((1, 1), k, np.uint8)))[0, 0]
                / 255,
                label=v,
            )
            for k, v in names.items()
        ]
        + [Patch(color="0.6", label="kept")],
        loc="lower center",
        bbox_to_anchor=(0.5, -0.22),
        ncol=3,
        fontsize=8,
    )
    fig.suptitle(title)
    save_figure(fig, path)
    plt.close(fig)
