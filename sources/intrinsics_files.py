"""Where dataset sources get pinhole intrinsics from: files, published values, --intrinsics.

Formats:
- `intrinsics.txt`: one line `fx fy cx cy` in pixels (`#` starts a comment), for
  the images next to it, at their stored size.
- `camera-intrinsics.txt` (7-Scenes as KinectFusion tools write it): a 3x3 K, three rows of
  three numbers.
- `cam_params.json` (NICE-SLAM Replica): `{"camera": {"w", "h", "fx", "fy", "cx", "cy", "scale"}}`,
  `scale` being the depth PNG divisor (value / scale = metres).
- Published TUM RGB-D values (https://cvg.cit.tum.de/data/datasets/rgbd-dataset/file_formats)
  for 640x480 images of freiburg1/2/3, with their radial-tangential distortion (fr3's images
  were undistorted before publication: zero).
"""
from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Intrinsics
from sources.base import SourceOptions


@dataclass(frozen=True)
class PinholeParams:
    """`fx, fy, cx, cy` in pixels for images of `width` x `height`.

    `width`/`height` None means "whatever size the images have" (intrinsics.txt,
    --intrinsics). `origin` says where the values came from (for messages).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int | None = None
    height: int | None = None
    origin: str = ""

    def for_image(self, width: int, height: int) -> Intrinsics:
        """Intrinsics of an image of `width` x `height`; rescaled (pixel-centre rule) if the
        values were given for another size, assuming the image was resized as a whole."""
        if self.width is None or self.height is None:
            return Intrinsics(self.fx, self.fy, self.cx, self.cy, width, height)
        base = Intrinsics(self.fx, self.fy, self.cx, self.cy, self.width, self.height)
        return base if (width, height) == (self.width, self.height) else base.resized(width, height)


TUM_PUBLISHED: dict[int, PinholeParams] = {
    1: PinholeParams(517.3, 516.5, 318.6, 255.3, 640, 480, "published TUM freiburg1"),
    2: PinholeParams(520.9, 521.0, 325.1, 249.7, 640, 480, "published TUM freiburg2"),
    3: PinholeParams(535.4, 539.2, 320.1, 247.6, 640, 480, "published TUM freiburg3"),
}

TUM_DISTORTION: dict[int, tuple[float, ...]] = {
    # k1, k2, p1, p2, k3 (OpenCV plumb_bob), from the same page.
    1: (0.2624, -0.9531, -0.0054, 0.0026, 1.1633),
    2: (0.2312, -0.7849, -0.0033, -0.0001, 0.9172),
    3: (0.0, 0.0, 0.0, 0.0, 0.0),
}

_TUM_NAME = re.compile(r"(?:freiburg|(?<![a-z])fr)_?([123])(?!\d)")

MISSING_HINT = "pass --intrinsics fx,fy,cx,cy"


def from_options(opts: SourceOptions) -> PinholeParams | None:
    """The `--intrinsics` override (at the original image size), or None."""
    if opts.intrinsics is None:
        return None
    fx, fy, cx, cy = opts.intrinsics
    return PinholeParams(fx, fy, cx, cy, origin="--intrinsics")


def read_intrinsics_txt(path: str | Path) -> PinholeParams:
    """Parse `fx fy cx cy` (whitespace or comma separated, `#` comments)."""
    path = Path(path)
    values: list[str] = []
    for line in path.read_text().splitlines():
        values += line.split("#", 1)[0].replace(",", " ").split()
    try:
        fx, fy, cx, cy = (float(v) for v in values)
    except ValueError:
        raise SourceError(f"{path} must hold four numbers 'fx fy cx cy', found {len(values)} values: fix it or {MISSING_HINT}") from None
    if fx <= 0 or fy <= 0:
        raise SourceError(f"{path}: focal lengths must be positive: fix it or {MISSING_HINT}")
    return PinholeParams(fx, fy, cx, cy, origin=str(path))


def read_intrinsics_matrix(path: str | Path) -> PinholeParams:
    """Parse a 3x3 K written as three rows of three numbers (7-Scenes `camera-intrinsics.txt`)."""
    path = Path(path)
    try:
        K = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError:
        K = np.zeros(0)
    if K.shape != (3, 3) or K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0, 0, 1]):
        raise SourceError(f"{path} must hold a 3x3 camera matrix [[fx 0 cx] [0 fy cy] [0 0 1]]: fix it or {MISSING_HINT}")
    return PinholeParams(float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), origin=str(path))


def read_cam_params_json(path: str | Path) -> tuple[PinholeParams, float | None]:
    """Parse a NICE-SLAM `cam_params.json` -> (intrinsics at w x h, depth scale or None)."""
    path = Path(path)
    try:
        cam = json.loads(path.read_text())["camera"]
        params = PinholeParams(
            float(cam["fx"]), float(cam["fy"]), float(cam["cx"]), float(cam["cy"]),
            int(cam["w"]), int(cam["h"]), str(path),
        )
    except (ValueError, KeyError, TypeError) as e:
        raise SourceError(f"{path} is not a valid cam_params.json ({type(e).__name__}: {e}): fix it or {MISSING_HINT}") from None
    scale = cam.get("scale")
    return params, (float(scale) if scale else None)


def find_upwards(start: Path, name: str, levels: int = 2) -> Path | None:
    """First `name` in `start` or up to `levels` parent folders, or None."""
    folder = start.resolve()
    for _ in range(levels + 1):
        if (folder / name).is_file():
            return folder / name
        folder = folder.parent
    return None


def tum_camera(folder_name: str) -> int | None:
    """1, 2 or 3 if `folder_name` names freiburg1/2/3 (also fr1/fr2/fr3), else None."""
    m = _TUM_NAME.search(folder_name.lower())
    return int(m.group(1)) if m else None
