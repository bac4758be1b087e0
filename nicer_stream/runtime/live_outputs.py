"""What a sink receives at each map update, while the run goes on: the map's render of the
frame just mapped, every keyframe's pose, the mapping loss terms, every `beta_every` updates
the sharpest adaptive-beta voxels (LIVE_VOXELS) and every `mesh_every` updates a coarse mesh
(all voxels and the full mesh come at the end).

The state is taken in the SLAM thread (poses, the published map) and the renders are made
where `submit` runs them: on the sink worker in the asynchronous runtime."""
from __future__ import annotations

import dataclasses
from typing import Callable

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
# Live beta voxels: the sharpest (most sampled: the surfaces) this many. All ~10^5 counted ones
# were ~2 MB per log, most of a recording; the run's end logs them all.
LIVE_VOXELS = 20_000


def coarse_mesh(slam: SlamSystem, poses: np.ndarray, intr: Intrinsics, model=None, beta=None, measured=None):
    """`scene_mesh` at MESH_RESOLUTION: a second or two (of `model`, default the published map;
    `measured` views default to the SLAM's, taken here: pass them from the SLAM thread)."""
    coarse = dataclasses.replace(slam.cfg, mesh=dataclasses.replace(slam.cfg.mesh, resolution=MESH_RESOLUTION))
    if model is None:
        model, beta = slam.map_view()
    return scene_mesh(model, beta, poses, intr, coarse,
                      measured=slam.measured_views(intr) if measured is None else measured)


class LiveMapOutputs:
    """Logs a map update's state to `sink`; `mesh_every` 0 leaves meshes to the end of the run,
    `beta_every` 0 the beta voxels (from the first update on, every `beta_every`-th).
    `submit(fn)` runs the rendering and logging (default: at once); an update still queued when
    a newer one arrives is skipped there, so a slow sink skips map updates, never the SLAM."""

    def __init__(self, sink: Sink, slam: SlamSystem, mesh_every: int = 5,
                 submit: Callable[[Callable[[], None]], None] | None = None, beta_every: int = 5) -> None:
        # The voxels were most of a recording when all were logged at every update (the synthetic
        # room at 60 frames: 27 of 29 MB, ~2 MB each time): like the mesh, they come every few.
        self.sink, self.slam, self.mesh_every, self.beta_every = sink, slam, mesh_every, beta_every
        self.submit = submit or (lambda fn: fn())
        self.updates = 0
        self.skipped = 0  # updates a newer one overtook before the sink worker got to them
        self._queued: list = []  # the newest update's state while it waits for the worker (or [])

    def __call__(self, event: MapUpdated, intr: Intrinsics, render: bool = True) -> None:
        """`render` False: no live render of this update (the run's final outputs render its map
        at full size and log that instead); the keyframes, voxels, losses and mesh as usual."""
        slam = self.slam
        if event.iters == 0 or slam.model is None:
            return  # nothing changed (a stop before the first iteration)
        self.updates += 1
        model, beta = slam.map_view()  # the published map: mapping may be changing the live one
        T = slam.poses[event.index].clone()
        kf = [slam.poses[k].double().cpu().numpy() for k in slam.keyframes if k in slam.poses]
        poses = np.stack(slam.trajectory()[1]) if self.mesh_every and self.updates % self.mesh_every == 0 else None
        measured = slam.measured_views(intr) if poses is not None else []

        # An update still queued when a newer one comes is emptied here: its map snapshot (tens of
        # MB) goes now rather than when the worker reaches it. list.pop is atomic across threads.
        try:
            self._queued.pop()
        except IndexError:
            pass
        voxels = self.beta_every > 0 and (self.updates - 1) % self.beta_every == 0
        job = self._queued = [(event, intr, model, beta, T, kf, poses, measured, render, voxels)]

        def emit() -> None:
            try:
                state = job.pop()
            except IndexError:  # a newer update is queued behind this one: it shows the newer map
                self.skipped += 1
                return
            self._emit(*state)

        self.submit(emit)

    def _emit(self, event, intr, model, beta, T, kf, poses, measured, render=True, voxels=True) -> None:
        if render:
            small = intr.scaled(RENDER_SCALE)
            view = render_image(model, beta, T, small, self.slam.cfg.render)
            self.sink.log_map_render(event.index, view.rgb, view.depth, view.normal, small, T.double().cpu().numpy())
        if kf:
            self.sink.log_keyframes(np.stack(kf))
        if voxels:
            self._log_voxels(model, beta)
        self.sink.log_scalars(event.index, {"mapping_loss": event.loss,
                                            **{f"mapping_{k}": v for k, v in event.terms.items()}})
        if poses is not None:
            mesh = coarse_mesh(self.slam, poses, intr, model, beta, measured)
            if len(mesh.faces):
                self.sink.log_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces),
                                   np.asarray(mesh.visual.vertex_colors)[:, :3])

    def _log_voxels(self, model, beta) -> None:
        centres, betas = beta.voxel_betas()
        if len(betas) > LIVE_VOXELS:
            keep = torch.topk(betas, LIVE_VOXELS, largest=False).indices
            centres, betas = centres[keep], betas[keep]
        if len(centres):
            world = model.bound.denormalise(centres.to(torch.float32)).cpu().numpy()
            self.sink.log_beta_voxels(world, betas.cpu().numpy(),
                                      2 * model.bound.half_extent / self.slam.cfg.render.beta_voxels)
