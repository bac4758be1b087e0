"""A synthetic scene: textured analytic surfaces, a fixed light, an optional sky and a camera path.

World frame: z up, metres. Poses are `T_world_cam` (camera-to-world) with OpenCV
camera axes (x right, y down, z forward). Builders: `room.py` (room, tabletop),
`street.py` (street).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import trimesh

from nicer_stream.types import Intrinsics
from sources.synthetic.mesh import scene_mesh
from sources.synthetic.render import RenderedView, Surface, render_view
from sources.synthetic.texture import SkyGradient


@dataclass(eq=False)
class SyntheticScene:
    """`surfaces[0]` is the enclosing surface (room box or ground), the rest are the objects."""

    name: str
    seed: int
    surfaces: list[Surface]
    light: np.ndarray
    """(3,) unit world direction towards the light (fixed: shading is view-independent)."""
    path: Callable[[int], np.ndarray]
    """n_frames -> (N, 4, 4) float64 T_world_cam along the camera path (see `trajectory`)."""
    sky: SkyGradient | None = None
    """Colour of rays that hit nothing (their depth is 0); None for closed scenes."""
    mesh_edge: float = 0.05
    """Default longest grid edge of `gt_mesh` in metres (large scenes use coarser grids)."""

    def render(self, T_world_cam: np.ndarray, intr: Intrinsics) -> RenderedView:
        """Exact ray-cast view: rgb (H, W, 3), z-depth (H, W) metres (0 = sky), camera-frame normals (H, W, 3)."""
        return render_view(self.surfaces, self.light, T_world_cam, intr, self.sky)

    def gt_mesh(self, max_edge: float | None = None) -> trimesh.Trimesh:
        """Ground-truth mesh (world frame, metres) with uint8 RGBA vertex colours (default edge: `mesh_edge`)."""
        return scene_mesh(self.surfaces, self.light, max_edge or self.mesh_edge)

    def trajectory(self, n_frames: int) -> np.ndarray:
        """(N, 4, 4) float64 T_world_cam of the first N frames (how N maps onto the path: the builder's docs)."""
        return self.path(n_frames)
