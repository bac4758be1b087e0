"""`tum:PATH`: a TUM RGB-D sequence folder.

- `rgb.txt`: `t path` lines (`#` comments), t in seconds; these are the frames
  and their timestamps (kept as in the file, so trajectories match the GT clock).
- `depth.txt` (optional): same format, PNGs with metres = value / 5000.
- `groundtruth.txt` (optional): `t tx ty tz qx qy qz qw`, T_world_cam.
Depth and GT pose are associated to each RGB timestamp by the nearest timestamp
within 0.02 s; frames without a match get None.
Intrinsics: `--intrinsics` > `intrinsics.txt` (`fx fy cx cy`) > the published
values when the folder name says freiburg1/2/3 (fr1/fr2/fr3) > error. The first two
mean a pinhole camera; the published fr1 and fr2 calibrations carry lens distortion,
which is undone (sources.undistort: RGB and GT depth, and the frames carry the
undistorted camera's K).
"""
from __future__ import annotations

import logging
from functools import partial
from pathlib import Path

import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.io.trajectory import read_tum
from sources.base import FrameSource, SourceOptions, read_depth_png
from sources.folder import FrameFile, ListedFrameSource, existing_dir
from sources.intrinsics_files import MISSING_HINT, TUM_DISTORTION, TUM_PUBLISHED, from_options, read_intrinsics_txt, tum_camera
from sources.undistort import CameraCalibration, pinhole

log = logging.getLogger(__name__)

DEPTH_SCALE = 5000.0
MAX_DT = 0.02
"""Largest RGB-to-GT/depth timestamp difference accepted by association, seconds."""


def read_list(path: Path) -> tuple[np.ndarray, list[Path]]:
    """`t path` list file -> ((N,) float64 timestamps, N paths relative to its folder)."""
    times, paths = [], []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        try:
            times.append(float(parts[0]))
            paths.append(path.parent / parts[1])
        except (ValueError, IndexError):
            raise SourceError(f"{path}:{n}: expected 't path', got '{line}'") from None
    return np.asarray(times, dtype=np.float64), paths


def associate(query_t: np.ndarray, ref_t: np.ndarray, max_dt: float = MAX_DT) -> np.ndarray:
    """For each query time, the index of the nearest reference time within `max_dt`, else -1.

    query_t: (N,) seconds; ref_t: (M,) seconds, any order. Returns (N,) int64.
    """
    if len(ref_t) == 0:
        return np.full(len(query_t), -1, dtype=np.int64)
    order = np.argsort(ref_t, kind="stable")
    s = ref_t[order]
    hi = np.clip(np.searchsorted(s, query_t), 1, len(s) - 1) if len(s) > 1 else np.zeros(len(query_t), dtype=np.int64)
    lo = np.maximum(hi - 1, 0)
    pick = np.where(np.abs(s[lo] - query_t) <= np.abs(s[hi] - query_t), lo, hi)
    out = order[pick]
    return np.where(np.abs(ref_t[out] - query_t) <= max_dt, out, -1).astype(np.int64)


def resolve_calibration(p: Path, opts: SourceOptions) -> CameraCalibration:
    """The camera by the precedence in the module docstring."""
    params = from_options(opts)
    if params is None and (p / "intrinsics.txt").is_file():
        params = read_intrinsics_txt(p / "intrinsics.txt")
    if params is not None:
        return pinhole(params)
    cam = tum_camera(p.resolve().name)
    if cam is None:
        raise SourceError(
            f"no intrinsics for {p}: add intrinsics.txt ('fx fy cx cy'), name the folder after freiburg1/2/3, or {MISSING_HINT}"
        )
    log.info("%s: using %s intrinsics and distortion", p, TUM_PUBLISHED[cam].origin)
    return CameraCalibration(TUM_PUBLISHED[cam], np.asarray(TUM_DISTORTION[cam], dtype=np.float64))


def list_frames(p: Path) -> list[FrameFile]:
    """Frames from rgb.txt with associated GT pose and depth file."""
    if not (p / "rgb.txt").is_file():
        raise SourceError(f"no frames in {p}: expected a TUM RGB-D folder with rgb.txt ('t rgb/xxx.png' lines)")
    t_rgb, rgb_paths = read_list(p / "rgb.txt")
    if len(t_rgb) == 0:
        raise SourceError(f"no frames in {p}: rgb.txt lists no images")
    poses, pose_idx = None, np.full(len(t_rgb), -1)
    if (p / "groundtruth.txt").is_file():
        try:
            t_gt, poses = read_tum(p / "groundtruth.txt")
        except ValueError as e:
            raise SourceError(f"{e}: fix or remove groundtruth.txt") from None
        pose_idx = associate(t_rgb, t_gt)
    depth_paths, depth_idx = [], np.full(len(t_rgb), -1)
    if (p / "depth.txt").is_file():
        t_depth, depth_paths = read_list(p / "depth.txt")
        depth_idx = associate(t_rgb, t_depth)
    return [
        FrameFile(
            rgb_path=rgb_paths[i],
            timestamp=float(t_rgb[i]),
            gt_pose=poses[pose_idx[i]] if pose_idx[i] >= 0 else None,
            depth_path=depth_paths[depth_idx[i]] if depth_idx[i] >= 0 else None,
        )
        for i in range(len(t_rgb))
    ]


def open(path: str, query: dict[str, str], opts: SourceOptions) -> FrameSource:
    """Open a TUM RGB-D sequence folder (see module docstring)."""
    if query:
        raise SourceError(f"tum takes no ?options, got {', '.join(sorted(query))}")
    p = existing_dir(path)
    files = list_frames(p)
    return ListedFrameSource(files, resolve_calibration(p, opts), opts, name=p.resolve().name, depth_reader=partial(read_depth_png, scale=DEPTH_SCALE))
