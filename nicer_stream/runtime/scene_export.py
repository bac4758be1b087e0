"""Turn a fitted scene into files: renders (npz + png), the mesh."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import torch
import trimesh

from nicer_stream.config import SlamConfig
from nicer_stream.io.output_dir import RENDERS_DIR, render_name
from nicer_stream.mesh import cull_to_frustums, extract_mesh
from nicer_stream.mesh.sparse_grid import mixed_voxel_boxes
from nicer_stream.mesh.visibility import DepthView, cull_by_rendered_depth
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.renderer import RenderedImage, render_image
from nicer_stream.types import Intrinsics


def save_render(out_dir: Path, index: int, view: RenderedImage, observed_rgb: np.ndarray | None = None,
                timestamp: float | None = None) -> Path:
    """Write renders/frame_NNNNNN.npz (rgb, depth, normal, frame_index, timestamp [s] when given)
    and a PNG (render | input | depth | normal)."""
    d = Path(out_dir) / RENDERS_DIR
    d.mkdir(parents=True, exist_ok=True)
    path = d / render_name(index)
    np.savez_compressed(path, rgb=view.rgb.astype(np.float32), depth=view.depth.astype(np.float32),
                        normal=view.normal.astype(np.float32), frame_index=np.int64(index),
                        **({} if timestamp is None else {"timestamp": np.float64(timestamp)}))
    cv2.imwrite(str(path.with_suffix(".png")), render_tile(view, observed_rgb))
    return path


def render_tile(view: RenderedImage, observed_rgb: np.ndarray | None = None,
                depth_max: float | None = None) -> np.ndarray:
    """(H, n W, 3) uint8 BGR (OpenCV's order): render | input (when given) | depth (viridis, 0 to
    `depth_max`, default the view's 99th percentile) | normals."""
    top = depth_max or max(float(np.percentile(view.depth, 99)), 1e-6)
    depth = np.clip(view.depth / top, 0, 1)
    depth_rgb = cv2.applyColorMap((depth * 255).astype(np.uint8), cv2.COLORMAP_VIRIDIS)[..., ::-1] / 255.0
    normal_rgb = (1 - view.normal) / 2  # camera-frame normal facing the camera -> bright
    tiles = [view.rgb] + ([observed_rgb] if observed_rgb is not None else []) + [depth_rgb, normal_rgb]
    rgb = (np.clip(np.concatenate(tiles, axis=1), 0, 1) * 255).astype(np.uint8)
    return cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)


def depth_views(model: SceneModel, beta: BetaField, poses: np.ndarray, intr: Intrinsics, cfg: SlamConfig,
                max_views: int = 8, width: int = 80) -> list[DepthView]:
    """Low-resolution rendered depth of up to `max_views` evenly spread poses (for culling)."""
    small = intr.resized(width, max(1, round(intr.height * width / intr.width)))
    idx = np.unique(np.linspace(0, len(poses) - 1, min(max_views, len(poses))).round().astype(int))
    out = []
    for i in idx:
        view = render_image(model, beta, torch.as_tensor(poses[i], dtype=torch.float32), small, cfg.render,
                            depth_only=True)
        out.append(DepthView(np.asarray(poses[i]), small, np.where(view.opacity > 0.5, view.depth, 0.0)))
    return out


class MeshAborted(Exception):
    """`scene_mesh` was asked to stop before its SDF grid was complete."""


def scene_mesh(model: SceneModel, beta: BetaField, poses: np.ndarray, intr: Intrinsics, cfg: SlamConfig,
               should_stop=None, measured: list[DepthView] = ()) -> trimesh.Trimesh:
    """Marching cubes over the bound, evaluating the full SDF only in voxels the mapping
    sampled (elsewhere the map knows nothing: treated as free space), then culled to
    the cameras' frustums and to what the rendered depth says they see (no surfaces
    behind walls, none in space the renders, or the keyframes' `measured` depth, see through:
    `cfg.mesh.measured_through_rel`). Vertex colours from the colour network.
    `should_stop()`, polled between SDF chunks, raises MeshAborted when true. The SDF is evaluated
    densely only near the surface (`extract_mesh`; the same mesh as at every grid point)."""
    resolution = cfg.mesh.resolution
    lo, hi = model.bound.world_min_max()
    observed = beta.counts > 0

    def sdf_fn(x: torch.Tensor) -> torch.Tensor:
        if should_stop is not None and should_stop():
            raise MeshAborted
        xn = model.bound.normalise(x)
        mask = observed[beta.voxel_index(xn)]
        out = torch.full((x.shape[0],), 1.0, dtype=x.dtype)
        if mask.any():
            out[mask] = model.sdf_world(x[mask])
        return out

    n = beta.cfg.beta_voxels

    def jump_fn(box_lo: torch.Tensor, box_hi: torch.Tensor) -> torch.Tensor:
        # sdf_fn jumps to 1 where the observed voxels end; voxel indices grow with the coordinates,
        # so the box's points fall in the voxels between its corners' ones.
        return mixed_voxel_boxes(observed.reshape(n, n, n), beta.voxel_ijk(model.bound.normalise(box_lo)),
                                 beta.voxel_ijk(model.bound.normalise(box_hi)))

    with torch.no_grad():
        mesh = extract_mesh(sdf_fn, model.color_world, lo, hi, resolution, jump_fn=jump_fn)
    if not len(mesh.faces):
        return mesh
    mesh = cull_to_frustums(mesh, poses, intr)
    measured = measured if cfg.mesh.measured_through_rel > 0 else ()
    return cull_by_rendered_depth(mesh, depth_views(model, beta, poses, intr, cfg), margin=cfg.mesh.visibility_margin_m,
                                  measured=measured, measured_rel=cfg.mesh.measured_through_rel)
