"""Rerun sink: a `.rrd` file, a spawned viewer or a gRPC viewer (rerun-sdk 0.41).

Entities (world frame = the SLAM world, metres):
  world/camera               Transform3D, camera-to-world (T_world_cam)
  world/camera/image         Pinhole (RDF = OpenCV axes) with rgb (JPEG), depth (m), normal ((n+1)/2)
  world/camera_gt            Transform3D of the ground-truth camera, when given
  world/trajectory/{name}    LineStrips3D (estimate, gt)
  world/mesh                 Mesh3D (logged rarely: every write is stored)
  world/beta                 Points3D at voxel centres, radius voxel/2, coloured by beta
  metrics/{name}             Scalars
Timelines: `frame` (sequence) and `sensor_time` (timestamp, ns exact).
"""
from __future__ import annotations

import os
import sys
import uuid
from pathlib import Path
from typing import Mapping

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from nicer_stream.errors import UserError
from nicer_stream.types import Intrinsics
from sinks.base import Sink, beta_colors, colors_to_u8, normal_to_u8, pose_tq, rgb_to_u8, seconds_to_ns

APP_ID = "nicer-stream"


def default_blueprint() -> rrb.Blueprint:
    """3D world view, the camera's 2D images (tabs) and the metrics time series."""
    image = "world/camera/image"
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="3D"),
            rrb.Vertical(
                rrb.Tabs(
                    rrb.Spatial2DView(origin=image, contents=["$origin", "$origin/rgb"], name="rgb"),
                    rrb.Spatial2DView(origin=image, contents=["$origin", "$origin/depth"], name="depth"),
                    rrb.Spatial2DView(origin=image, contents=["$origin", "$origin/normal"], name="normal"),
                ),
                rrb.TimeSeriesView(origin="metrics", name="metrics"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


def _can_spawn_viewer() -> bool:
    """A viewer window needs a display on Linux; macOS and Windows always have one."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class RerunSink(Sink):
    """Writes to exactly one of: `path` (.rrd), a spawned viewer (`spawn=True`), `grpc_url`.

    `log_time=False` drops the wall-clock timeline (deterministic files for tests);
    `flush_every` frames the stream is flushed so a crash loses little.
    """

    def __init__(self, path: str | Path | None = None, *, spawn: bool = False, grpc_url: str | None = None,
                 recording_id: str | None = None, log_time: bool = True, jpeg_quality: int = 85,
                 flush_every: int = 10, gt_strip_every: int = 10) -> None:
        if sum([path is not None, spawn, grpc_url is not None]) != 1:
            raise ValueError("RerunSink needs exactly one of path, spawn=True, grpc_url")
        self.rec = rr.RecordingStream(APP_ID, recording_id=recording_id or str(uuid.uuid4()))
        self.rec.set_log_time_enabled(log_time)
        bp = default_blueprint()
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            self.rec.save(str(path), default_blueprint=bp)
        elif spawn:
            if not _can_spawn_viewer():
                raise UserError("cannot spawn the Rerun viewer (no display): use --sink rerun:FILE.rrd "
                                "or rerun+grpc:URL instead")
            try:
                self.rec.spawn(default_blueprint=bp)
            except Exception as e:  # the viewer binary is missing or fails to start
                raise UserError(f"cannot spawn the Rerun viewer ({e}): use rerun:FILE.rrd instead") from e
        else:
            self.rec.connect_grpc(grpc_url or None, default_blueprint=bp)
        self.jpeg_quality = jpeg_quality
        self.flush_every = max(1, flush_every)
        self.gt_strip_every = max(1, gt_strip_every)
        self._time_ns: dict[int, int] = {}
        self._gt_positions: list[np.ndarray] = []
        self._gt_logged = 0
        self._frames = 0
        self._closed = False

    # -- time ---------------------------------------------------------------
    def _set_time(self, index: int, timestamp: float | None = None, timestamp_ns: int | None = None) -> None:
        self.rec.set_time("frame", sequence=int(index))
        if timestamp is not None:
            self._time_ns[int(index)] = seconds_to_ns(timestamp, timestamp_ns)
        ns = self._time_ns.get(int(index))
        if ns is not None:
            self.rec.set_time("sensor_time", timestamp=np.datetime64(ns, "ns"))

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("RerunSink is closed")

    # -- Sink API -----------------------------------------------------------
    def log_pose(self, index, timestamp, T_world_cam, gt_T_world_cam=None, timestamp_ns=None) -> None:
        self._check_open()
        self._set_time(index, timestamp, timestamp_ns)
        t, q = pose_tq(T_world_cam)
        self.rec.log("world/camera", rr.Transform3D(translation=t, quaternion=rr.Quaternion(xyzw=q)))
        if gt_T_world_cam is not None:
            tg, qg = pose_tq(gt_T_world_cam)
            self.rec.log("world/camera_gt", rr.Transform3D(translation=tg, quaternion=rr.Quaternion(xyzw=qg)),
                         rr.TransformAxes3D(0.1))
            self._gt_positions.append(tg)
            if len(self._gt_positions) % self.gt_strip_every == 0:
                self._log_gt_strip()
        self._frames += 1
        if self._frames % self.flush_every == 0:
            self.rec.flush()

    def log_frame(self, index, timestamp, rgb, intrinsics: Intrinsics, T_world_cam, depth=None,
                  normal=None, gt_T_world_cam=None, timestamp_ns=None) -> None:
        self.log_pose(index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns)
        self.rec.log("world/camera/image", rr.Pinhole(
            image_from_camera=intrinsics.matrix(), width=intrinsics.width, height=intrinsics.height,
            camera_xyz=rr.ViewCoordinates.RDF))
        self.rec.log("world/camera/image/rgb", rr.Image(rgb_to_u8(rgb)).compress(jpeg_quality=self.jpeg_quality))
        if depth is not None:
            self.rec.log("world/camera/image/depth", rr.DepthImage(np.asarray(depth, dtype=np.float32), meter=1.0))
        if normal is not None:
            self.rec.log("world/camera/image/normal",
                         rr.Image(normal_to_u8(normal)).compress(jpeg_quality=self.jpeg_quality))

    def log_trajectory(self, positions, name="estimate", rotations=None) -> None:
        self._check_open()
        pts = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
        colour = [255, 140, 0] if name == "estimate" else [0, 180, 255]
        self.rec.log(f"world/trajectory/{name}", rr.LineStrips3D([pts], colors=[colour], radii=[0.005]))

    def log_mesh(self, vertices, faces, vertex_colors=None, normals=None) -> None:
        self._check_open()
        self.rec.log("world/mesh", rr.Mesh3D(
            vertex_positions=np.asarray(vertices, dtype=np.float32),
            triangle_indices=np.asarray(faces, dtype=np.uint32),
            vertex_colors=colors_to_u8(vertex_colors),
            vertex_normals=None if normals is None else np.asarray(normals, dtype=np.float32)))
        self.rec.flush()  # meshes are rare and big: make sure they reach the file

    def log_beta_voxels(self, centres, beta, voxel_size) -> None:
        self._check_open()
        self.rec.log("world/beta", rr.Points3D(np.asarray(centres, dtype=np.float32),
                                               colors=beta_colors(beta), radii=0.5 * float(voxel_size)))

    def log_scalars(self, index: int, values: Mapping[str, float]) -> None:
        self._check_open()
        self._set_time(index)
        for name, value in values.items():
            self.rec.log(f"metrics/{name}", rr.Scalars(float(value)))

    def _log_gt_strip(self) -> None:
        if len(self._gt_positions) > self._gt_logged:
            self.log_trajectory(np.stack(self._gt_positions), name="gt")
            self._gt_logged = len(self._gt_positions)

    def close(self) -> None:
        if self._closed:
            return
        try:
            self._log_gt_strip()
            self.rec.flush()
        finally:
            self._closed = True
            self.rec.disconnect()
