"""What a sink receives at each map update, while the run goes on: the map's render of the
frame just mapped, every keyframe's pose, the adaptive-beta voxels, the mapping loss terms,
and every `mesh_every` updates a coarse mesh (the full one comes at the end)."""
from __future__ import annotations

import dataclasses

import numpy as np
import torch

from nicer_stream.render.renderer import render_image
from nicer_stream.runtime.scene_export import scene_mesh
from nicer_stream.slam.events import MapUpdated
from nicer_stream.slam.system import SlamSystem
from nicer_stream.types import Intrinsics
from sinks.base import Sink

# Live renders at this fraction of the input size, live meshes at this grid resolution:
# a few seconds per map update on this CPU instead of the final outputs' tens.
RENDER_SCALE = 0.5
MESH_RESOLUTION = 64


def coarse_mesh(slam: SlamSystem, poses: np.ndarray, intr: Intrinsics):
    """`scene_mesh` at MESH_RESOLUTION: a second or two."""
    coarse = dataclasses.replace(slam.cfg, mesh=dataclasses.replace(slam.cfg.mesh, resolution=MESH_RESOLUTION))
    return scene_mesh(*slam.map_view(), poses, intr, coarse)


class LiveMapOutputs:
    """Logs a map update's state to `sink`; `mesh_every` 0 leaves meshes to the end of the run."""

    def __init__(self, sink: Sink, slam: SlamSystem, mesh_every: int = 5) -> None:
        self.sink, self.slam, self.mesh_every = sink, slam, mesh_every
        self.updates = 0

    def __call__(self, event: MapUpdated, intr: Intrinsics) -> None:
        slam = self.slam
        if event.iters == 0 or slam.model is None:
            return  # nothing changed (a stop before the first iteration)
        self.updates += 1
        small = intr.scaled(RENDER_SCALE)
        T = slam.poses[event.index]
        model, beta = slam.map_view()  # the published map: mapping may be changing the live one
        view = render_image(model, beta, T, small, slam.cfg.render)
        self.sink.log_map_render(event.index, view.rgb, view.depth, view.normal, small, T.double().cpu().numpy())
        kf = [k for k in slam.keyframes if k in slam.poses]
        if kf:
            self.sink.log_keyframes(np.stack([slam.poses[k].double().cpu().numpy() for k in kf]))
        centres, betas = beta.voxel_betas()
        if len(centres):
            world = model.bound.denormalise(centres.to(torch.float32)).cpu().numpy()
            self.sink.log_beta_voxels(world, betas.cpu().numpy(),
                                      2 * model.bound.half_extent / slam.cfg.render.beta_voxels)
        self.sink.log_scalars(event.index, {"mapping_loss": event.loss,
                                            **{f"mapping_{k}": v for k, v in event.terms.items()}})
        if self.mesh_every and self.updates % self.mesh_every == 0:
            _, poses = slam.trajectory()
            mesh = coarse_mesh(slam, np.stack(poses), intr)
            if len(mesh.faces):
                self.sink.log_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces),
                                   np.asarray(mesh.visual.vertex_colors)[:, :3])
