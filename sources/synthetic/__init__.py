"""Procedural synthetic scenes as a frame source: `synthetic:NAME[?frames=N&seed=S&width=W&height=H&grey=1]`.

Frames are ray-cast lazily, one per iteration step, with exact GT pose
(`T_world_cam`, OpenCV axes, world z up) and GT z-depth (0 where a ray sees the sky).
Scenes: `room`, `tabletop` (room.py) and `street` (street.py). Defaults: scene `room`,
120 frames at 30 fps, 320x240, 70 degree horizontal field of view, colour
(`grey=1`: luminance in all three channels).
"""
from __future__ import annotations

from typing import Iterator

import numpy as np

from nicer_stream.errors import SourceError
from nicer_stream.types import Frame, Intrinsics
from sources.base import FrameSource, SourceOptions
from sources.intrinsics_files import from_options
from sources.synthetic.render import RenderedView
from sources.synthetic.room import room_scene, tabletop_scene
from sources.synthetic.scene import SyntheticScene
from sources.synthetic.street import street_scene
from sources.video import fov_intrinsics

__all__ = ["FPS", "SCENES", "RenderedView", "SyntheticScene", "SyntheticSource", "default_intrinsics", "make_scene", "open", "to_grey"]

FPS = 30.0
HFOV_DEG = 70.0
_LIMITS = {
    "frames": (1, 100_000, 120),
    "seed": (0, 2**31 - 1, 0),
    "width": (8, 8192, 320),
    "height": (8, 8192, 240),
    "grey": (0, 1, 0),
}
_BUILDERS = {"room": room_scene, "tabletop": tabletop_scene, "street": street_scene}
SCENES = tuple(_BUILDERS)
LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)
"""RGB weights of the luminance of `grey=1` frames (ITU-R BT.601, as OpenCV's RGB2GRAY)."""


def make_scene(name: str = "room", seed: int = 0) -> SyntheticScene:
    """Build scene `name` (one of SCENES) deterministically from `seed`."""
    if name not in _BUILDERS:
        raise SourceError(f"unknown synthetic scene '{name}': use one of {', '.join(SCENES)} (synthetic:room)")
    return _BUILDERS[name](np.random.default_rng([seed, SCENES.index(name)]), seed)


def to_grey(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) RGB -> (H, W, 3) float32 with the luminance in every channel."""
    y = rgb[..., 0] * LUMA[0] + rgb[..., 1] * LUMA[1] + rgb[..., 2] * LUMA[2]
    return np.repeat(y[..., None], 3, axis=-1).astype(np.float32)


def default_intrinsics(width: int, height: int, hfov_deg: float = HFOV_DEG) -> Intrinsics:
    """Square-pixel pinhole with horizontal FoV `hfov_deg`, principal point at the image centre."""
    return fov_intrinsics(width, height, hfov_deg)


class SyntheticSource(FrameSource):
    """Renders `n_frames` views of `scene` along its trajectory (only the frames the options keep), grey if `grey`."""

    has_gt_pose = True

    def __init__(
        self, scene: SyntheticScene, n_frames: int, intr: Intrinsics, opts: SourceOptions | None = None, grey: bool = False
    ) -> None:
        super().__init__(opts)
        self.scene = scene
        self.n_frames = n_frames
        self.intrinsics = intr
        self.grey = grey
        self.poses = scene.trajectory(n_frames)
        self.name = f"synthetic-{scene.name}-s{scene.seed}" + ("-grey" if grey else "")

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
                rgb=to_grey(view.rgb) if self.grey else view.rgb,
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
    """Open `synthetic:NAME?frames=&seed=&width=&height=&grey=` (empty NAME = room)."""
    unknown = sorted(set(query) - set(_LIMITS))
    if unknown:
        raise SourceError(f"synthetic source: unknown parameter(s) {', '.join(unknown)}: use {', '.join(_LIMITS)}")
    n, seed, w, h, grey = (_int_param(query, k) for k in _LIMITS)
    scene = make_scene(path or "room", seed)
    override = from_options(opts)
    intr = override.for_image(w, h) if override is not None else default_intrinsics(w, h)
    return SyntheticSource(scene, n, intr, opts, grey=bool(grey))
