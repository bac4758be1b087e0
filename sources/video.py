"""`video:FILE[?calib=FILE&fov=DEG]`: frames of a video file read with OpenCV.

Timestamps are the container's presentation times (CAP_PROP_POS_MSEC), in seconds.
Intrinsics, first found wins: `--intrinsics fx,fy,cx,cy`; `?calib=FILE`
(sources.calibration_file: intrinsics.txt, OpenCV/ROS YAML, JSON; lens distortion is
undone by sources.undistort, and the frames carry its new K); `<video>.intrinsics.txt`,
`<stem>.intrinsics.txt` or `intrinsics.txt` next to the video; else a guess from a
horizontal field of view (`?fov=DEG`, default 60 deg), with a warning.
"""
from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Iterator

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Frame, Intrinsics
from sources.base import FrameSource, SourceOptions
from sources.calibration_file import read_calibration_file
from sources.mcap_calibration import calibration_from_flag, calibration_from_values
from sources.undistort import CameraCalibration, Undistorter

log = logging.getLogger(__name__)
DEFAULT_FOV_DEG = 60.0


def fov_intrinsics(width: int, height: int, hfov_deg: float) -> Intrinsics:
    """Pinhole intrinsics with horizontal field of view `hfov_deg`, square pixels, centred.

    fx = fy = (W / 2) / tan(hfov / 2); the principal point is the image centre
    ((W - 1) / 2, (H - 1) / 2) under the pixel-centre convention.
    """
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2.0)
    return Intrinsics(f, f, (width - 1) / 2.0, (height - 1) / 2.0, width, height)


def sidecar_calibration(video: Path) -> Path | None:
    """An intrinsics file next to the video: `<video>.intrinsics.txt`, `<stem>.intrinsics.txt`, `intrinsics.txt`."""
    names = (video.name + ".intrinsics.txt", video.stem + ".intrinsics.txt", "intrinsics.txt")
    return next((c for c in map(video.with_name, names) if c.is_file()), None)


class VideoSource(FrameSource):
    """Frames of a video file; see the module docstring for timestamps and intrinsics."""

    def __init__(self, path: Path, calib: CameraCalibration, opts: SourceOptions, announced: int = 0) -> None:
        super().__init__(opts)
        self.path, self.calibration, self.announced = path, calib, announced  # the container's frame count
        self.name = path.stem
        self.undistort = Undistorter(calib, enabled=opts.undistort)

    def expected_frames(self) -> int | None:
        """The container's announced frame count after start/stride/drop/max_frames, or None when
        it announces none (some containers estimate it: for progress, not for indexing)."""
        return len(self.opts.selected(self.announced)) if self.announced > 0 else None

    def _frames(self) -> Iterator[Frame]:
        cap = cv2.VideoCapture(str(self.path))
        raw, kept, ended = -1, 0, False
        try:
            while self.opts.max_frames is None or kept < self.opts.max_frames:
                if not cap.grab():  # end of stream (or an undecodable rest)
                    ended = True
                    break
                raw += 1
                if not self.opts.keeps(raw):
                    continue  # grabbed, not converted: cheaper than read()
                t_ms = cap.get(cv2.CAP_PROP_POS_MSEC)  # presentation time of the grabbed frame
                ok, bgr = cap.retrieve()
                if not ok or bgr is None:
                    self.skipped_frames += 1
                    log.warning("skipping undecodable frame %d of %s", raw, self.path)
                    continue
                rgb = cv2.cvtColor(bgr, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
                rgb = self.undistort(rgb)
                h, w = rgb.shape[:2]
                yield Frame(index=kept, timestamp=t_ms / 1000.0, rgb=rgb,
                            intrinsics=self.undistort.intrinsics(w, h), name=f"{self.path.stem}#{raw}")
                kept += 1
        finally:
            cap.release()
        # Reached only when the iteration ends (not when the consumer stops early).
        if self.skipped_frames:
            log.warning("%s: skipped %d undecodable frame(s)", self.path, self.skipped_frames)
        announced = self.announced
        if ended and announced and raw + 1 < announced - 1:
            log.warning("%s ended after %d of the %d frames its container announces: the file may be truncated",
                            self.path, raw + 1, announced)


def _parse_fov(query: dict[str, str]) -> float | None:
    if "fov" not in query:
        return None
    try:
        fov = float(query["fov"])
    except ValueError:
        fov = -1.0
    if not 0.0 < fov < 180.0:
        raise SourceError(f"?fov={query['fov']} must be a horizontal field of view in degrees, between 0 and 180")
    return fov


def _calibration(path: Path, query: dict[str, str], opts: SourceOptions, width: int, height: int) -> CameraCalibration:
    """Intrinsics for this video, in the order given in the module docstring."""
    if opts.intrinsics is not None:
        return calibration_from_flag(opts.intrinsics)
    fov = _parse_fov(query)
    if query.get("calib"):
        calib_path = Path(query["calib"]).expanduser()
        if not calib_path.is_absolute() and not calib_path.is_file():
            calib_path = path.parent / calib_path  # also accept a path relative to the video
        return read_calibration_file(calib_path)
    sidecar = sidecar_calibration(path)
    if sidecar is not None:
        log.info("intrinsics for %s from %s", path, sidecar)
        return read_calibration_file(sidecar)
    if fov is None:
        fov = DEFAULT_FOV_DEG
        log.warning(
            "no intrinsics for %s: guessing a %.0f deg horizontal field of view; pass --intrinsics fx,fy,cx,cy, "
            "video:%s?calib=FILE, an intrinsics.txt next to the video, or ?fov=DEG", path, fov, path)
    i = fov_intrinsics(width, height, fov)
    return calibration_from_values(i.matrix().reshape(-1), None, "plumb_bob", width, height, origin=f"{fov} deg guess")


def open(path: str, query: dict[str, str], opts: SourceOptions) -> VideoSource:
    """Open `video:path[?calib=FILE&fov=DEG]`. Raises SourceError with what to do."""
    p = Path(path).expanduser()
    if not p.is_file():
        raise SourceError(f"video file {path} not found{' (it is a directory)' if p.is_dir() else ''}: check the path")
    cap = cv2.VideoCapture(str(p))
    try:
        if not cap.isOpened():
            raise SourceError(f"OpenCV cannot open video {path} (corrupt file or unsupported codec): "
                              f"re-encode it (e.g. ffmpeg -i {path} -c:v libx264 out.mp4) or extract frames and use folder:DIR")
        width, height = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        announced = int(cap.get(cv2.CAP_PROP_FRAME_COUNT) or 0)
    finally:
        cap.release()
    if width <= 0 or height <= 0:
        raise SourceError(f"video {path} reports no frame size: re-encode it or extract frames and use folder:DIR")
    return VideoSource(p, _calibration(p, query, opts, width, height), opts, announced)
