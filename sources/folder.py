"""`folder:PATH`: a folder of images, and the file-list source the dataset layouts share.

If PATH looks like a known layout it is opened as that layout:
Replica (`results/frame*.jpg`), TUM (`rgb.txt`), 7-Scenes (`frame-*.color.png|jpg`).
Otherwise every `*.png|*.jpg|*.jpeg` in PATH, sorted naturally (`img2` before
`img10`), is a frame; intrinsics come from `intrinsics.txt` in PATH or
`--intrinsics`. No ground truth. Timestamps are frame number / fps, fps from
the `?fps=` query (default 30), since a bare folder has no timing.
"""
from __future__ import annotations

import importlib
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Frame
from sources import SCHEMES
from sources.base import FrameSource, SourceOptions, read_rgb
from sources.intrinsics_files import MISSING_HINT, PinholeParams, from_options, read_intrinsics_txt
from sources.undistort import CameraCalibration, Undistorter, pinhole

log = logging.getLogger(__name__)

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
DEFAULT_FPS = 30.0


@dataclass(frozen=True)
class FrameFile:
    """One input frame on disk.

    timestamp: seconds. gt_pose: (4, 4) float64 T_world_cam or None.
    depth_path: GT depth image or None (decoded by the source's depth reader).
    """

    rgb_path: Path
    timestamp: float
    gt_pose: np.ndarray | None = None
    depth_path: Path | None = None


DepthReader = Callable[[Path], np.ndarray]
"""Path -> (H, W) float32 z-depth in metres (0 = invalid); raises SourceError if unreadable."""


class ListedFrameSource(FrameSource):
    """Frames listed up-front as files, read lazily one at a time.

    `files` are all input frames; start/stride/max_frames select from them.
    `camera`: pinhole intrinsics, or a calibration with lens distortion: then RGB and GT depth
    are undistorted (sources.undistort) and the frames carry the undistorted camera's K.
    Unreadable RGB files are skipped (counted in `skipped_frames`, warned);
    unreadable depth gives `gt_depth=None` with a warning.
    """

    def __init__(
        self,
        files: list[FrameFile],
        camera: PinholeParams | CameraCalibration,
        opts: SourceOptions,
        name: str,
        depth_reader: DepthReader | None = None,
    ) -> None:
        super().__init__(opts)
        self.files = [files[i] for i in opts.selected(len(files))]
        self.calibration = camera if isinstance(camera, CameraCalibration) else pinhole(camera)
        self.undistort = Undistorter(self.calibration, enabled=opts.undistort)
        self.name = name
        self.depth_reader = depth_reader
        self.has_gt_pose = any(f.gt_pose is not None for f in self.files)

    def __len__(self) -> int:
        return len(self.files)

    def _frames(self) -> Iterator[Frame]:
        self.skipped_frames = 0
        index = 0
        for f in self.files:
            try:
                rgb = read_rgb(f.rgb_path)
            except SourceError as e:
                self.skipped_frames += 1
                log.warning("skipping frame: %s", e)
                continue
            h, w = rgb.shape[:2]
            depth = self._depth(f, (h, w))
            yield Frame(
                index=index,
                timestamp=f.timestamp,
                rgb=self.undistort(rgb),
                intrinsics=self.undistort.intrinsics(w, h),
                gt_pose=None if f.gt_pose is None else f.gt_pose.copy(),
                gt_depth=None if depth is None else self.undistort(depth, nearest=True),
                name=f.rgb_path.stem,
            )
            index += 1

    def _depth(self, f: FrameFile, shape: tuple[int, int]) -> np.ndarray | None:
        if f.depth_path is None or self.depth_reader is None:
            return None
        try:
            depth = self.depth_reader(f.depth_path)
        except SourceError as e:
            log.warning("frame %s without GT depth: %s", f.rgb_path.name, e)
            return None
        if depth.shape != shape:
            log.warning("frame %s: depth %s and RGB %s differ in size, GT depth dropped", f.rgb_path.name, depth.shape, shape)
            return None
        return depth


def existing_dir(path: str) -> Path:
    """`path` as a Path, or SourceError if it does not exist / is not a folder."""
    p = Path(path).expanduser()
    if not p.exists():
        raise SourceError(f"source path {path} does not exist")
    if not p.is_dir():
        raise SourceError(f"source path {path} is not a folder: give the dataset folder")
    return p


def fps_from_query(query: dict[str, str], scheme: str) -> float:
    """`?fps=` (frames per second used for timestamps), default 30; rejects other keys."""
    unknown = set(query) - {"fps"}
    if unknown:
        raise SourceError(f"unknown option(s) {', '.join(sorted(unknown))} for {scheme}: only ?fps=N is accepted")
    try:
        fps = float(query.get("fps", DEFAULT_FPS))
    except ValueError:
        fps = -1.0
    if not fps > 0:
        raise SourceError(f"{scheme}: ?fps= must be a positive number, got '{query['fps']}'")
    return fps


def natural_key(name: str) -> list:
    """Sort key splitting digit runs: 'img2' < 'img10'."""
    return [int(t) if t.isdigit() else t.lower() for t in re.split(r"(\d+)", name)]


def detect_layout(p: Path) -> str | None:
    """Scheme of the dataset layout at folder `p` ('replica', 'tum', '7scenes'), or None."""
    if (p / "results").is_dir() and any((p / "results").glob("frame*.jpg")):
        return "replica"
    if (p / "rgb.txt").is_file():
        return "tum"
    if any(p.glob("frame-*.color.png")) or any(p.glob("frame-*.color.jpg")):
        return "7scenes"
    return None


def open(path: str, query: dict[str, str], opts: SourceOptions) -> FrameSource:
    """Open a folder: delegate to a detected dataset layout, else a plain image folder."""
    p = existing_dir(path)
    layout = detect_layout(p)
    if layout is not None:
        log.info("folder %s looks like a %s sequence", p, layout)
        return importlib.import_module(SCHEMES[layout]).open(path, query, opts)
    fps = fps_from_query(query, "folder")
    images = sorted((f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES), key=lambda f: natural_key(f.name))
    if not images:
        raise SourceError(f"no frames in {path}: expected *.png/*.jpg images (or a replica/tum/7scenes layout)")
    params = from_options(opts)
    if params is None and (p / "intrinsics.txt").is_file():
        params = read_intrinsics_txt(p / "intrinsics.txt")
    if params is None:
        raise SourceError(f"no intrinsics for {path}: add intrinsics.txt ('fx fy cx cy') or {MISSING_HINT}")
    files = [FrameFile(f, i / fps) for i, f in enumerate(images)]
    return ListedFrameSource(files, params, opts, name=p.resolve().name)
