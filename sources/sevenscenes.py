"""`7scenes:PATH`: one Microsoft 7-Scenes sequence folder (e.g. `chess/seq-01`).

- `frame-NNNNNN.color.png` or `.color.jpg` (as some copies store it): RGB, 640x480.
- `frame-NNNNNN.depth.png`: uint16 millimetres, 65535 = invalid (-> 0). The
  Kinect depth is not registered to the colour camera; treat it as approximate.
- `frame-NNNNNN.pose.txt`: 4x4 T_world_cam (camera-to-world), metres.
Intrinsics: `--intrinsics fx,fy,cx,cy` > `camera-intrinsics.txt` (a 3x3 K, as
KinectFusion-style copies ship it) > fx = fy = 585, cx = 320, cy = 240 at 640x480
(the values the dataset authors give).
Timestamps: frame number / fps with fps from `?fps=` (default 30, Kinect rate).
"""
from __future__ import annotations

import re
from pathlib import Path

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from sources.base import FrameSource, SourceOptions
from sources.folder import FrameFile, ListedFrameSource, existing_dir, fps_from_query
from sources.intrinsics_files import PinholeParams, from_options, read_intrinsics_matrix

DEFAULT_INTRINSICS = PinholeParams(585.0, 585.0, 320.0, 240.0, 640, 480, "7-Scenes default")
INVALID_DEPTH = 65535
_FRAME = re.compile(r"frame-(\d+)\.color\.(?:png|jpg)$")
INTRINSICS_FILE = "camera-intrinsics.txt"


def read_depth_mm(path: Path) -> np.ndarray:
    """uint16 millimetre PNG -> (H, W) float32 metres, 65535 and 0 -> 0 (invalid)."""
    d = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if d is None or d.ndim != 2:
        raise SourceError(f"cannot read depth image {path}: missing or corrupt file")
    d = d.astype(np.float32)
    d[d == INVALID_DEPTH] = 0.0
    return d / 1000.0


def read_pose(path: Path) -> np.ndarray | None:
    """4x4 text matrix -> (4, 4) float64, or None if absent or not finite."""
    if not path.is_file():
        return None
    try:
        T = np.loadtxt(path, dtype=np.float64)
    except ValueError:
        raise SourceError(f"{path} is not a 4x4 matrix: fix or remove it") from None
    if T.shape != (4, 4):
        raise SourceError(f"{path} holds a {T.shape} array, expected a 4x4 matrix")
    return T if np.isfinite(T).all() else None


def list_frames(p: Path, fps: float) -> list[FrameFile]:
    """Frames of sequence folder `p` sorted by number, with pose and depth files."""
    numbered = sorted((int(m.group(1)), f) for f in p.glob("frame-*.color.*") if (m := _FRAME.search(f.name)))
    if not numbered:
        raise SourceError(f"no frames in {p}: expected a 7-Scenes sequence folder with frame-NNNNNN.color.png (or .jpg)")
    if len({num for num, _ in numbered}) < len(numbered):
        raise SourceError(f"{p} holds both frame-NNNNNN.color.png and .jpg for the same frames: keep one of them")
    files = []
    for num, rgb in numbered:
        stem = rgb.name.split(".color.")[0]
        depth = p / f"{stem}.depth.png"
        files.append(FrameFile(rgb, num / fps, read_pose(p / f"{stem}.pose.txt"), depth if depth.is_file() else None))
    return files


def open(path: str, query: dict[str, str], opts: SourceOptions) -> FrameSource:
    """Open a 7-Scenes sequence folder (see module docstring)."""
    p = existing_dir(path)
    files = list_frames(p, fps_from_query(query, "7scenes"))
    params = from_options(opts)
    if params is None and (p / INTRINSICS_FILE).is_file():
        params = read_intrinsics_matrix(p / INTRINSICS_FILE)
    params = params or DEFAULT_INTRINSICS
    return ListedFrameSource(files, params, opts, name=p.resolve().name, depth_reader=read_depth_mm)
