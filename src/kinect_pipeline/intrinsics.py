"""The depth camera's intrinsics where a recording has no CameraInfo (bags of robots often have none, and folders of
frames never do): given as numbers (``FX FY CX CY [W H]``, with or without commas), read from a camera_info YAML as
``camera_calibration`` writes it, or a sensor preset's nominal camera scaled to the image size (a guess: said in a
warning). The cameras themselves are the core's (``_core.Camera``), checked there."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from . import _core

#: How the option is spelt in messages.
HOW = "--intrinsics FX,FY,CX,CY[,W,H] (or FX FY CX CY [W H], or a camera_info YAML as camera_calibration writes it)"


class IntrinsicsError(ValueError):
    """Intrinsics that cannot be used; the message names the value and what was expected."""


@dataclass(frozen=True)
class Intrinsics:
    """fx, fy, cx, cy [px] and the image size they are for (0 x 0: any size the images have)."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int = 0
    height: int = 0
    source: str = "--intrinsics"  #: where they came from, for messages
    # A camera_info YAML's lens and rectified projection (the node's ~camera_info_url takes them too).
    distortion_model: str = ""
    D: tuple[float, ...] = ()
    projection: tuple[float, ...] = ()  #: fx, fy, cx, cy of its P: a rectified image's camera; () where not set

    def lens(self) -> dict[str, Any] | None:
        """Its distortion and projection where it has them (what a replay records of them), else None."""
        if not any(self.D) and not self.projection:
            return None
        return {"distortion_model": self.distortion_model, "D": list(self.D), "projection": list(self.projection)}

    def with_lens(self, lens: dict[str, Any] | None) -> Intrinsics:
        """These intrinsics with the lens :meth:`lens` gave (None: none)."""
        if not lens:
            return self
        return replace(
            self,
            distortion_model=str(lens["distortion_model"]),
            D=tuple(float(x) for x in lens["D"]),
            projection=tuple(float(x) for x in lens["projection"]),
        )

    def rectified_camera(self, width: int, height: int) -> Any:
        """The camera of a rectified image: its projection's (P's) where the YAML set one, as the node takes it."""
        if not self.projection:
            return self.camera(width, height)
        fx, fy, cx, cy = self.projection
        return replace(self, fx=fx, fy=fy, cx=cx, cy=cy, projection=()).camera(width, height)

    def as_list(self) -> list[float]:
        """fx, fy, cx, cy, width, height (what a replay records of them)."""
        return [self.fx, self.fy, self.cx, self.cy, float(self.width), float(self.height)]

    @staticmethod
    def from_list(values: list[float] | tuple[float, ...], source: str = "--intrinsics") -> Intrinsics:
        """Of 4 (fx, fy, cx, cy) or 6 (and width, height) numbers."""
        v = [float(x) for x in values]
        if len(v) not in (4, 6):
            raise IntrinsicsError(f"{source}: {len(v)} numbers: expected FX FY CX CY, or FX FY CX CY W H")
        for name, x in zip(("fx", "fy", "cx", "cy", "width", "height"), v, strict=False):
            if not math.isfinite(x):
                raise IntrinsicsError(f"{source}: {name} = {x}: expected a finite number")
        size = (v[4], v[5]) if len(v) == 6 else (0.0, 0.0)
        if size != (int(size[0]), int(size[1])) or min(size) < 0:
            raise IntrinsicsError(f"{source}: size {size[0]:g}x{size[1]:g}: expected whole pixels")
        return Intrinsics(v[0], v[1], v[2], v[3], int(size[0]), int(size[1]), source)

    def camera(self, width: int, height: int) -> Any:
        """The core's camera for images of ``width`` x ``height``; a size that differs from theirs, or values the
        core refuses, raise IntrinsicsError naming them."""
        if self.width and (self.width, self.height) != (width, height):
            raise IntrinsicsError(
                f"{self.source}: intrinsics for {self.width}x{self.height} images, but the depth images are "
                f"{width}x{height}"
            )
        try:
            return _core.Camera(int(width), int(height), self.fx, self.fy, self.cx, self.cy)
        except (ValueError, TypeError) as exc:
            raise IntrinsicsError(f"{self.source}: {exc}") from exc


def parse_intrinsics(values: list[str]) -> Intrinsics:
    """What ``--intrinsics`` was given: numbers (``213 213 212 120``, ``213,213,212,120,424,240``) or one camera_info
    YAML file. Raises IntrinsicsError naming the value."""
    text = " ".join(values).replace(",", " ").split()
    if len(values) == 1 and not _numbers(text):
        return read_camera_info_yaml(Path(values[0]))
    if not _numbers(text):
        raise IntrinsicsError(
            f"--intrinsics {' '.join(values)}: expected numbers, or one camera_info YAML file ({HOW})"
        )
    where = f"--intrinsics {' '.join(values)}"
    if len(text) == 6 and min(float(text[4]), float(text[5])) < 1:  # 0 x 0 stands for "any size" only inside
        raise IntrinsicsError(f"{where}: size {text[4]}x{text[5]}: expected whole pixels, at least 1x1")
    return Intrinsics.from_list([float(x) for x in text], where)


def _numbers(items: list[str]) -> bool:
    try:
        [float(x) for x in items]
    except ValueError:
        return False
    return bool(items)


def read_camera_info_yaml(path: Path) -> Intrinsics:
    """fx, fy, cx, cy and the size of a camera_info YAML as ``camera_calibration`` (camera_calibration_parsers)
    writes it: ``image_width``, ``image_height``, ``camera_matrix: {rows: 3, cols: 3, data: [...]}``."""
    import yaml

    where = f"--intrinsics {path}"
    if not path.is_file():
        what = "a folder" if path.is_dir() else "no such file"
        raise IntrinsicsError(f"{where}: {what} (expected numbers or a camera_info YAML file; {HOW})")
    try:
        doc = yaml.safe_load(path.read_text(errors="replace"))
    except yaml.YAMLError as exc:
        raise IntrinsicsError(f"{where}: not YAML ({str(exc).splitlines()[0]})") from exc
    try:
        k = [float(x) for x in doc["camera_matrix"]["data"]]
        width, height = int(doc["image_width"]), int(doc["image_height"])
    except (TypeError, KeyError, ValueError) as exc:
        raise IntrinsicsError(
            f"{where}: not a camera_info YAML: expected image_width, image_height and camera_matrix: data: "
            "[fx, 0, cx, 0, fy, cy, 0, 0, 1] (as camera_calibration writes it)"
        ) from exc
    if len(k) != 9:
        raise IntrinsicsError(f"{where}: camera_matrix has {len(k)} values: expected 9 (3x3, row-major)")
    model, d = _distortion(doc, where)
    try:  # the camera_info's own checks: a pinhole K, a skew within a pixel, a lens the core can take
        cam = _core.camera_from_intrinsics(max(width, 1), max(height, 1), k)
        _core.DepthRectifier(cam, model, list(d))
        p = [float(x) for x in ((doc.get("projection_matrix") or {}).get("data") or [])]
        pk = _core.rectified_intrinsics(p) if len(p) == 12 else None
        if pk is not None:
            _core.camera_from_intrinsics(max(width, 1), max(height, 1), pk)
    except (ValueError, TypeError, AttributeError) as exc:
        raise IntrinsicsError(f"{where}: {exc}") from exc
    projection = () if pk is None or pk == k else (pk[0], pk[4], pk[2], pk[5])
    return Intrinsics(k[0], k[4], k[2], k[5], width, height, where, model, d, projection)


def _distortion(doc: dict[str, Any], where: str) -> tuple[str, tuple[float, ...]]:
    """A camera_info YAML's distortion_model and distortion_coefficients (none: no distortion)."""
    try:
        data = (doc.get("distortion_coefficients") or {}).get("data") or []
        return str(doc.get("distortion_model") or "plumb_bob"), tuple(float(x) for x in data)
    except (AttributeError, TypeError, ValueError) as exc:
        raise IntrinsicsError(
            f"{where}: distortion_coefficients: expected {{rows: 1, cols: N, data: [k1, k2, ...]}} (as "
            "camera_calibration writes it)"
        ) from exc


def nominal_camera(model: str, width: int, height: int) -> tuple[Any, str]:
    """The sensor preset's nominal camera, scaled to ``width`` x ``height`` where the aspect ratio is the same (a
    camera run at half resolution), and the warning that it is only a guess. Another aspect ratio raises
    IntrinsicsError."""
    cam = _core.sensor_model(model)["camera"]
    sx, sy = width / cam.width, height / cam.height
    if abs(sx - sy) > 0.01 * max(sx, sy):
        raise IntrinsicsError(
            f"--sensor-model {model}: its nominal camera is {cam.width}x{cam.height}, the depth images are "
            f"{width}x{height} (another aspect ratio): give {HOW}"
        )
    out = _core.Camera(
        int(width), int(height), cam.fx * sx, cam.fy * sy, (cam.cx + 0.5) * sx - 0.5, (cam.cy + 0.5) * sy - 0.5
    )
    scaled = f" scaled to {width}x{height}" if (sx, sy) != (1.0, 1.0) else ""
    warning = (
        f"no camera intrinsics given: the nominal camera of --sensor-model {model} ({cam.width}x{cam.height}, "
        f"fx {cam.fx:g}){scaled}: {out!r}; ranges and the floor are only as right as this guess: give {HOW}"
    )
    return out, warning
