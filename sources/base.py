"""What every frame source shares: options, the iteration protocol, resizing."""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Iterator

import cv2
import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.grey import to_grey_u8
from nicer_stream.types import DetailImage, Frame


@dataclass(frozen=True)
class SourceOptions:
    """Options shared by all sources (CLI: --start, --stride, --drop, --max-frames, --max-side, --scale, --intrinsics)."""

    start: int = 0
    """Skip this many input frames first."""
    stride: int = 1
    """Keep every `stride`-th frame after `start`."""
    drop: tuple[int, int] | None = None
    """Drop raw input frames `a`..`b-1` (`(a, b)`, counted like `start`, before stride), to simulate a jump.
    The stride pattern and the frames' GT are unchanged (frames are numbered as with --stride alone);
    `max_frames` counts the frames kept after dropping."""
    max_frames: int | None = None
    """Stop after this many kept frames (None: all)."""
    max_side: int | None = None
    """Resize so that the longer image side is at most this many pixels (intrinsics follow)."""
    scale: float | None = None
    """Resize by this factor (intrinsics follow); exclusive with max_side."""
    intrinsics: tuple[float, float, float, float] | None = None
    """Override `fx, fy, cx, cy` (at the original image size)."""
    detail_side: int | None = None
    """Also keep a grey copy of each image with its longer side up to this many pixels (never above
    the original) where that is larger than the resized image: `Frame.detail`, the frontend's input."""
    undistort: bool = True
    """Undo the lens distortion a source knows (sources.undistort); False yields the images as
    recorded, with the calibration's own K (for writing them out with their distortion)."""

    def __post_init__(self) -> None:
        if self.stride < 1 or self.start < 0:
            raise SourceError("--stride must be >= 1 and --start >= 0")
        if self.max_frames is not None and self.max_frames < 1:
            raise SourceError("--max-frames must be >= 1")
        if self.drop is not None and not 0 <= self.drop[0] < self.drop[1]:
            a, b = self.drop
            raise SourceError(f"--drop {a}:{b} is empty or negative: give A:B with 0 <= A < B (drops input frames A..B-1)")
        if self.max_side is not None and self.scale is not None:
            raise SourceError("give either --max-side or --scale, not both")
        if self.detail_side is not None and self.detail_side < 1:
            raise SourceError(f"detail_side must be a positive number of pixels, got {self.detail_side}")

    def keeps(self, raw_index: int) -> bool:
        """Whether input frame number `raw_index` (0-based) passes start/stride/drop."""
        if self.drop is not None and self.drop[0] <= raw_index < self.drop[1]:
            return False
        return raw_index >= self.start and (raw_index - self.start) % self.stride == 0

    def selected(self, n: int) -> list[int]:
        """Indices of the kept frames out of `n` input frames."""
        idx = [i for i in range(self.start, n, self.stride) if self.keeps(i)]
        return idx if self.max_frames is None else idx[: self.max_frames]

    def target_size(self, width: int, height: int) -> tuple[int, int]:
        """Output (width, height) for an input of `width` x `height`."""
        if self.scale is not None:
            f = self.scale
        elif self.max_side is not None and max(width, height) > self.max_side:
            f = self.max_side / max(width, height)
        else:
            return width, height
        return max(1, round(width * f)), max(1, round(height * f))


def detail_image(frame: Frame, side: int, smaller: tuple[int, int]) -> DetailImage | None:
    """A grey copy of `frame`'s image with its longer side up to `side` pixels (never above the
    original), or None when that is no larger than `smaller` (width, height)."""
    w, h = SourceOptions(max_side=side).target_size(frame.width, frame.height)
    if w <= smaller[0] and h <= smaller[1]:
        return None
    rgb = frame.rgb if (w, h) == (frame.width, frame.height) else cv2.resize(frame.rgb, (w, h), interpolation=cv2.INTER_AREA)
    return DetailImage(to_grey_u8(rgb), frame.intrinsics.resized(w, h))


def resize_frame(frame: Frame, opts: SourceOptions) -> Frame:
    """Apply the options' resize to RGB, GT depth and intrinsics; keep a `detail` image when
    `opts.detail_side` asks for one larger than the result."""
    w, h = opts.target_size(frame.width, frame.height)
    if opts.detail_side is not None:
        frame = replace(frame, detail=detail_image(frame, opts.detail_side, (w, h)))
    if (w, h) == (frame.width, frame.height):
        return frame
    rgb = cv2.resize(frame.rgb, (w, h), interpolation=cv2.INTER_AREA)
    depth = None
    if frame.gt_depth is not None:
        # Nearest keeps depth edges honest (no mixing of foreground and background).
        depth = cv2.resize(frame.gt_depth, (w, h), interpolation=cv2.INTER_NEAREST)
    # replace() keeps every other field (name, timestamp_ns, ...).
    return replace(frame, rgb=rgb, intrinsics=frame.intrinsics.resized(w, h), gt_depth=depth)


def read_rgb(path) -> np.ndarray:
    """Read an image file -> (H, W, 3) float32 RGB in [0, 1]. Raises SourceError if unreadable."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise SourceError(f"cannot read image {path}: missing or corrupt file")
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0


def read_depth_png(path, scale: float) -> np.ndarray:
    """Read a uint16 depth PNG -> (H, W) float32 metres (value / scale); 0 = invalid."""
    d = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if d is None:
        raise SourceError(f"cannot read depth image {path}: missing or corrupt file")
    return d.astype(np.float32) / scale


class FrameSource:
    """A stream of Frames. Subclasses implement `_frames()`; options are applied here.

    Attributes: `uri` (what the user typed), `name` (short label), `has_gt_pose`.
    """

    uri: str = ""
    name: str = ""
    has_gt_pose: bool = False
    skipped_frames: int = 0
    """Frames that were corrupt or unreadable and were skipped (reported at the end)."""
    calibration = None
    """The lens as recorded (sources.undistort.CameraCalibration: K at the input size, distortion)
    where the source knows it, else None."""

    def __init__(self, opts: SourceOptions | None = None) -> None:
        self.opts = opts or SourceOptions()

    def _frames(self) -> Iterator[Frame]:  # pragma: no cover - abstract
        raise NotImplementedError

    def __iter__(self) -> Iterator[Frame]:
        for frame in self._frames():
            yield resize_frame(frame, self.opts)

    def __len__(self) -> int:
        """Number of frames when known up-front (raises TypeError otherwise)."""
        raise TypeError(f"{type(self).__name__} does not know its length in advance")

    def expected_frames(self) -> int | None:
        """Frames this source will give after start/stride/drop/max_frames when known up-front
        (file lists, a video's announced count, an indexed MCAP's message count), else None."""
        try:
            return len(self)
        except TypeError:
            return None
