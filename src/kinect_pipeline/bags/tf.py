"""The bag's /tf and /tf_static, looked up at a stamp by composing the chain between two frames."""

from __future__ import annotations

import bisect
from collections import defaultdict
from collections.abc import Callable
from typing import Any

from .. import _core
from .messages import TF_TOPICS, stamp
from .reader import BagReader, read_side
from .ros1 import Damage

Tf = tuple[tuple[float, float, float, float], tuple[float, float, float]]


class TfBuffer:
    """The bag's /tf and /tf_static, looked up at a stamp by composing the chain between two frames."""

    def __init__(self) -> None:
        self.parent: dict[str, str] = {}
        self.static: dict[str, Tf] = {}
        self.dynamic: dict[str, tuple[list[float], list[Tf]]] = defaultdict(lambda: ([], []))

    def add(self, msg: Any, static: bool) -> None:
        for t in msg.transforms:
            child = t.child_frame_id.lstrip("/")
            self.parent[child] = t.header.frame_id.lstrip("/")
            r, p = t.transform.rotation, t.transform.translation
            tf: Tf = ((r.x, r.y, r.z, r.w), (p.x, p.y, p.z))
            if static:
                self.static[child] = tf
            else:
                stamps, tfs = self.dynamic[child]
                i = bisect.bisect(stamps, stamp(t))
                stamps.insert(i, stamp(t))
                tfs.insert(i, tf)

    def _edge(self, child: str, at: float, tolerance: float) -> Tf:
        if child in self.static:
            return self.static[child]
        stamps, tfs = self.dynamic.get(child, ([], []))
        if not stamps:
            raise LookupError(f"no transform to '{child}'")
        i = bisect.bisect(stamps, at)
        if i == 0:
            if stamps[0] - at > tolerance:
                raise LookupError(f"'{child}': first transform at {stamps[0]:.3f} s, after the frame ({at:.3f} s)")
            return tfs[0]
        if i == len(stamps):
            if at - stamps[-1] > tolerance:
                raise LookupError(f"'{child}': last transform at {stamps[-1]:.3f} s, before the frame ({at:.3f} s)")
            return tfs[-1]
        a, b = stamps[i - 1], stamps[i]
        return _core.interpolate_transform(tfs[i - 1], tfs[i], (at - a) / (b - a) if b > a else 0.0)

    def lookup(self, target: str, source: str, at: float, tolerance: float) -> Tf:
        """target <- source at ``at`` [s], composing the tree through their common ancestor."""
        target, source = target.lstrip("/"), source.lstrip("/")

        def chain(frame: str) -> list[str]:
            out = [frame]
            while out[-1] in self.parent and len(out) < 100:
                out.append(self.parent[out[-1]])
            return out

        up_s, up_t = chain(source), chain(target)
        common = next((f for f in up_s if f in up_t), None)
        if common is None:
            raise LookupError(f"'{source}' and '{target}' are not connected in the bag's tf tree")

        def to_common(up: list[str]) -> Tf:
            out: Tf = ((0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0))
            for f in up[: up.index(common)]:
                out = _core.compose_transforms(self._edge(f, at, tolerance), out)
            return out

        return _core.compose_transforms(_core.invert_transform(to_common(up_t)), to_common(up_s))


def read_tf(bag: BagReader, on_damage: Callable[[Damage], None] | None = None) -> TfBuffer:
    """All of the bag's /tf and /tf_static (a frame may come before the transform at its stamp)."""
    tf = TfBuffer()
    for conn, msg in read_side(bag, TF_TOPICS, on_damage):
        tf.add(msg, static=conn.topic == "/tf_static")
    return tf
