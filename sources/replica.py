"""`replica:PATH`: a Replica sequence as rendered for NICE-SLAM.

PATH is the sequence folder (e.g. `Replica/room0`) holding
- `results/frameNNNNNN.jpg` RGB and `results/depthNNNNNN.png` uint16 depth,
  metres = value / scale (scale 6553.5 unless cam_params.json says otherwise);
- `traj.txt`: line NNNNNN = row-major 4x4 T_world_cam (camera-to-world, OpenCV
  axes) of frame NNNNNN; optional (no GT pose without it);
- `cam_params.json` in PATH or up to two parent folders (NICE-SLAM keeps it in
  `Replica/`), unless `--intrinsics fx,fy,cx,cy` is given (that wins).
Replica renders carry no timing: timestamps are frame number / fps with fps
from `?fps=` (default 30).
"""
from __future__ import annotations

import re
from functools import partial
from pathlib import Path

import numpy as np

from nicer_stream.errors import SourceError
from sources.base import FrameSource, SourceOptions, read_depth_png
from sources.folder import FrameFile, ListedFrameSource, existing_dir, fps_from_query
from sources.intrinsics_files import MISSING_HINT, find_upwards, from_options, read_cam_params_json

DEPTH_SCALE = 6553.5
_FRAME = re.compile(r"frame(\d+)\.jpg$")


def read_traj(path: Path) -> np.ndarray:
    """`traj.txt` -> (N, 4, 4) float64 T_world_cam, one row-major matrix per line."""
    try:
        rows = np.loadtxt(path, dtype=np.float64, ndmin=2)
    except ValueError as e:
        raise SourceError(f"{path} is not a list of 16-number lines ({e}): fix or remove it") from None
    if rows.shape[1] != 16:
        raise SourceError(f"{path} must hold 16 numbers per line (row-major 4x4), found {rows.shape[1]}")
    return rows.reshape(-1, 4, 4)


def list_frames(p: Path, fps: float) -> list[FrameFile]:
    """Frames of sequence folder `p`, sorted by frame number, with GT where present."""
    numbered = sorted(
        (int(m.group(1)), f) for f in (p / "results").glob("frame*.jpg") if (m := _FRAME.search(f.name))
    ) if (p / "results").is_dir() else []
    if not numbered:
        raise SourceError(f"no frames in {p}: expected a Replica (NICE-SLAM) folder with results/frameNNNNNN.jpg")
    poses = read_traj(p / "traj.txt") if (p / "traj.txt").is_file() else np.zeros((0, 4, 4))
    files = []
    for num, rgb in numbered:
        depth = p / "results" / f"depth{rgb.stem[len('frame'):]}.png"
        pose = poses[num] if num < len(poses) and np.isfinite(poses[num]).all() else None
        files.append(FrameFile(rgb, num / fps, pose, depth if depth.is_file() else None))
    return files


def open(path: str, query: dict[str, str], opts: SourceOptions) -> FrameSource:
    """Open a NICE-SLAM Replica sequence folder (see module docstring)."""
    p = existing_dir(path)
    files = list_frames(p, fps_from_query(query, "replica"))
    params = from_options(opts)
    scale = DEPTH_SCALE
    cam_file = find_upwards(p, "cam_params.json", levels=2)
    if cam_file is not None:
        cam_params, cam_scale = read_cam_params_json(cam_file)
        params = params or cam_params
        scale = cam_scale or scale
    if params is None:
        raise SourceError(f"no cam_params.json in {path} or its two parent folders: {MISSING_HINT}")
    return ListedFrameSource(files, params, opts, name=p.resolve().name, depth_reader=partial(read_depth_png, scale=scale))
