"""Procedural synthetic scenes as a frame source: `synthetic:NAME[?frames=N&seed=S&width=W&height=H]`.

Frames are ray-cast lazily, one per iteration step, with exact GT pose
(`T_world_cam`, OpenCV axes, world z up) and GT z-depth. Defaults: scene `room`,
120 frames at 30 fps, 320x240, 70 degree horizontal field of view.
"""
from __future__ import annotations

import math
from typing import Iterator

from nicer_stream.errors import SourceError
from nicer_stream.types import Frame, Intrinsics
from sources.base import FrameSource, SourceOptions, intrinsics_from_override
from sources.synthetic.render import RenderedView
from sources.synthetic.room import SCENES, SyntheticScene, make_scene

__all__ = ["FPS", "SCENES", "RenderedView", "SyntheticScene", "SyntheticSource", "default_intrinsics", "make_scene", "open"]

FPS = 30.0
HFOV_DEG = 70.0
_LIMITS = {"frames": (1, 100_000, 120), "seed": (0, 2**31 - 1, 0), "width": (8, 8192, 320), "height": (8, 8192, 240)}


def default_intrinsics(width: int, height: int, hfov_deg: float = HFOV_DEG) -> Intrinsics:
    """Square-pixel pinhole with horizontal FoV `hfov_deg`, principal point at the image centre."""
    f = 0.5 * width / math.tan(math.radians(hfov_deg) / 2)
    return Intrinsics(f, f, (width - 1) / 2, (height - 1) / 2, width, height)


class SyntheticSource(FrameSource):
    """Renders `n_frames` views of `scene` along its trajectory (only the frames the options keep)."""

    has_gt_pose = True

    def __init__(self, scene: SyntheticScene, n_frames: int, intr: Intrinsics, opts: SourceOptions | None = None) -> None:
        super().__init__(opts)
        self.scene = scene
        self.n_frames = n_frames
        self.intrinsics = intr
        self.poses = scene.trajectory(n_frames)
        self.name = f"synthetic-{scene.name}-s{scene.seed}"

    def gt_mesh(self):
        """The scene's ground-truth mesh (trimesh, world metres), for evaluation only."""
        return self.scene.gt_mesh()

    def __len__(self) -> int:
        return len(self.opts.selected(self.n_frames))

    def _frames(self) -> Iterator[Frame]:
        for i in self.opts.selected(self.n_frames):
            view = self.scene.render(self.poses[i], self.intrinsics)
            yield Frame(
                index=i,
                timestamp=i / FPS,
                rgb=view.rgb,
                intrinsics=self.intrinsics,
                gt_pose=self.poses[i].copy(),
                gt_depth=view.depth,
                name=f"{i:06d}",
            )


def _int_param(query: dict[str, str], key: str) -> int:
    lo, hi, default = _LIMITS[key]
    text = query.get(key)
    if text is None:
        return default
    try:
        value = int(text)
    except ValueError:
        value = None
    if value is None or not lo <= value <= hi:
        raise SourceError(f"synthetic source: {key}={text!r} is invalid: give an integer in [{lo}, {hi}]")
    return value


def open(path: str, query: dict[str, str], opts: SourceOptions) -> SyntheticSource:  # noqa: A001 - registry protocol
    """Open `synthetic:NAME?frames=&seed=&width=&height=` (empty NAME = room)."""
    unknown = sorted(set(query) - set(_LIMITS))
    if unknown:
        raise SourceError(f"synthetic source: unknown parameter(s) {', '.join(unknown)}: use {', '.join(_LIMITS)}")
    n, seed, w, h = (_int_param(query, k) for k in ("frames", "seed", "width", "height"))
    scene = make_scene(path or "room", seed)
    intr = intrinsics_from_override(opts, w, h) or default_intrinsics(w, h)
    return SyntheticSource(scene, n, intr, opts)
