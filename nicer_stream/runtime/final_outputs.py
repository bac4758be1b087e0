"""The end of a `run`: trajectory, scene, summary, renders and mesh, cheapest and most valuable
first, so a stop during the renders or the mesh keeps what came before."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import torch

from nicer_stream.io.scene_file import save_scene
from nicer_stream.render.renderer import render_image
from nicer_stream.runtime.live_outputs import MESH_RESOLUTION, coarse_mesh
from nicer_stream.runtime.run_outputs import write_mesh, write_trajectory
from nicer_stream.runtime.run_state import RunState
from nicer_stream.runtime.run_summary import write_run_summary
from nicer_stream.runtime.scene_export import MeshAborted, save_render, scene_mesh

if TYPE_CHECKING:
    import trimesh


def write_outputs(s: RunState) -> None:
    """Every output of the run (summary.json once before the renders, again by the caller after)."""
    slam = s.slam
    times, poses = slam.trajectory()
    write_trajectory(s.out, times, poses)
    if slam.model is not None:
        save_scene(s.out, s.cfg, slam.model, slam.beta)
    write_run_summary(s)
    mapped = slam.mapped_iters > 0  # otherwise the scene is the initial sphere: no renders, no mesh
    n_renders = s.book.renders() if mapped and not s.early else 0
    print(f"writing outputs: {n_renders} renders{' and the mesh' if mapped else ''}", flush=True)
    with s.timer.stage("sinks"):
        poses_np = np.stack(poses) if poses else np.zeros((0, 4, 4))
        _write_renders(s, list(zip(slam.order, times, poses)), n_renders)
        mesh = _mesh(s, poses_np) if mapped and len(poses) else None
        write_mesh(s.out, mesh)
        if s.sink is not None:
            _log_final_map(s, poses_np, mesh, mapped)


def _write_renders(s: RunState, order: list, n_renders: int) -> None:
    """The kept frames rendered at full size; with a sink, the last frame's render first (the
    sink's view of the final map, which the closing update did not render live)."""
    slam, book = s.slam, s.book
    if s.sink is not None and order:
        order.insert(0, order.pop())
    done = 0
    for i, t, T in order:
        if n_renders and book.kept.get(i) is not None and not s.stop.requested:
            done += 1  # seconds each at full size: a line for each
            s.say(f"writing outputs: render {done}/{n_renders} (frame {i})")
            view = render_image(slam.model, slam.beta, torch.as_tensor(T, dtype=torch.float32), book.intr, s.cfg.render)
            save_render(s.out, i, view, book.kept[i], t)
            if s.sink is not None and i == slam.order[-1]:
                s.sink.log_map_render(i, view.rgb, view.depth, view.normal, book.intr, np.asarray(T, dtype=np.float64))


def _mesh(s: RunState, poses_np: np.ndarray) -> trimesh.Trimesh:
    """The final mesh; a stop during its extraction gives a coarse one in a second or two."""
    s.say(f"writing outputs: the mesh ({s.cfg.mesh.resolution}^3 grid)")
    intr = s.book.intr
    try:
        return scene_mesh(s.slam.model, s.slam.beta, poses_np, intr, s.cfg, should_stop=lambda: s.stop.requested,
                          measured=s.slam.measured_views(intr))
    except MeshAborted:
        print(f"mesh extraction stopped: writing a coarse mesh ({MESH_RESOLUTION}^3) instead", flush=True)
        return coarse_mesh(s.slam, poses_np, intr)


def _log_final_map(s: RunState, poses_np: np.ndarray, mesh: trimesh.Trimesh | None, mapped: bool) -> None:
    """The trajectory, the mesh and the beta voxels to the sink."""
    sink, slam = s.sink, s.slam
    if len(poses_np):
        sink.log_trajectory(poses_np[:, :3, 3], rotations=poses_np[:, :3, :3])
    if mesh is not None and len(mesh.faces):
        sink.log_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), np.asarray(mesh.visual.vertex_colors)[:, :3])
    if mapped:
        centres, betas = slam.beta.voxel_betas()
        world = slam.model.bound.denormalise(centres.to(torch.float32)).cpu().numpy()
        sink.log_beta_voxels(world, betas.cpu().numpy(), 2 * slam.model.bound.half_extent / slam.cfg.render.beta_voxels)
