"""The scene bound and mesh extraction sections."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from nicer_stream.config.checks import Checked


@dataclass(frozen=True)
class BoundConfig(Checked):
    """Scene bound used to normalise into [-1, 1]^3 (never from ground truth)."""

    mode: Literal["auto", "config"] = "auto"
    """'auto' (SLAM: the first frame's scaled depth prior plus margin; mapping with known
    poses: a cube of `half_extent` in front of the cameras) or 'config' (centre, half_extent)."""
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Bound centre in the world (first camera) frame, metres, for mode 'config'."""
    half_extent: float = 4.0
    """Half side of the cube, metres, for mode 'config'."""
    margin: float = 1.5
    """Multiplier on the prior-derived extent (room for the unseen)."""
    max_depth_m: float = 8.0
    """Depths beyond this are ignored when estimating the bound."""
    camera_margin: float = 0.25
    """SLAM 'auto': the first camera at least this fraction of the half side inside the cube, which
    slides away from a near face as far as keeps the points inside; 0: centred (docs/decisions.md)."""
    points_edge: float = 0.05
    """With `camera_margin`: the points' 1-99 percentile box, grown by this fraction of its
    longest side, stays inside the cube."""


@dataclass(frozen=True)
class MeshConfig(Checked):
    """Mesh extraction."""

    resolution: int = 512
    """Marching-cubes grid resolution per axis."""
    visibility_margin_m: float = 0.1
    """Faces further than this behind every rendered depth map are culled (never seen), and
    so are faces this far in front of some rendered depth map (seen through: free space)."""
    measured_through_rel: float = 0.07
    """Faces further in front of a keyframe's measured stereo depth than this fraction of it are
    culled too (stereo runs only); 0: off (docs/decisions.md)."""
