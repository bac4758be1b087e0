"""Rerun sink: a `.rrd` file, a spawned viewer or a gRPC viewer (rerun-sdk 0.41).

Entities (world frame = the SLAM world, metres):
  world/camera               Transform3D, camera-to-world (T_world_cam)
  world/camera/image         Pinhole (RDF = OpenCV axes) with rgb (JPEG), depth (m), normal ((n+1)/2),
                             of every `images_every`-th frame at up to `image_side` px (SinkOptions)
  world/camera_gt            Transform3D of the ground-truth camera, when given
  world/map_camera/image/{rgb,depth,normal}  the map's render of the newest keyframe after each
                             map update (world/map_camera: its pose; image: its Pinhole)
  world/keyframes            Points3D of every keyframe's centre and Arrows3D of its optical axis
  world/trajectory/estimate  LineStrips3D of the final estimated trajectory (at the end of a run)
  world/trajectory/tracked/NNNNN  LineStrips3D of the camera centres as their poses were logged
                             (a run's poses as tracked), one piece per `strip_every` frames (each
                             starts where the previous ended: logging stays linear in frames)
  world/trajectory/gt/NNNNN  LineStrips3D of the ground truth, in pieces likewise
  world/mesh                 Mesh3D (logged rarely: every write is stored)
  world/beta                 Points3D at voxel centres, radius voxel/2, coloured by beta
  metrics/{name}             Scalars
  tracking/warnings          TextLog (WARN): tracking warnings (frontend health, disagreements)
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
from sinks.base import (Sink, beta_colors, colors_to_u8, downsized, normal_to_u8, pose_tq, remember, rgb_to_u8,
                        seconds_to_ns)
from sinks.options import SinkOptions
from sinks.strip_pieces import StripPieces

APP_ID = "nicer-stream"
# Line colours by trajectory name; other names (GT pieces) are blue.
STRIP_COLOURS = {"estimate": [255, 140, 0], "tracked": [255, 215, 120]}


def default_blueprint() -> rrb.Blueprint:
    """3D world view, the camera's 2D images (tabs) and the metrics time series."""
    def images(origin: str, names: tuple[str, str, str]) -> rrb.Tabs:  # rgb, depth and normal tabs
        return rrb.Tabs(*(rrb.Spatial2DView(origin=origin, contents=["$origin", f"$origin/{part}"], name=name)
                          for part, name in zip(("rgb", "depth", "normal"), names)))

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="world", name="3D"),
            rrb.Vertical(
                images("world/camera/image", ("input", "depth", "normal")),
                images("world/map_camera/image", ("map rgb", "map depth", "map normal")),
                rrb.Tabs(
                    rrb.TimeSeriesView(origin="metrics", name="metrics"),
                    rrb.TextLogView(origin="tracking", name="tracking warnings"),
                ),
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
    `flush_every` frames the stream is flushed so a crash loses little; `strip_every` frames
    the tracked and GT trajectories get their next piece; `options` thin out the input images.
    """

    def __init__(self, path: str | Path | None = None, *, spawn: bool = False, grpc_url: str | None = None,
                 recording_id: str | None = None, log_time: bool = True, jpeg_quality: int = 85,
                 flush_every: int = 10, strip_every: int = 10, options: SinkOptions = SinkOptions()) -> None:
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
        self.options = options
        self._time_ns: dict[int, int] = {}  # recent frames only (`remember`)
        self._strips = {"tracked": StripPieces(strip_every), "gt": StripPieces(strip_every)}
        self._frames = 0
        self._closed = False

    # -- time ---------------------------------------------------------------
    def _set_time(self, index: int, timestamp: float | None = None, timestamp_ns: int | None = None) -> None:
        self.rec.set_time("frame", sequence=int(index))
        if timestamp is not None:
            remember(self._time_ns, index, seconds_to_ns(timestamp, timestamp_ns))
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
        self._grow("tracked", t)
        if gt_T_world_cam is not None:
            tg, qg = pose_tq(gt_T_world_cam)
            self.rec.log("world/camera_gt", rr.Transform3D(translation=tg, quaternion=rr.Quaternion(xyzw=qg)),
                         rr.TransformAxes3D(0.1))
            self._grow("gt", tg)
        self._frames += 1
        if self._frames % self.flush_every == 0:
            self.rec.flush()

    def log_frame(self, index, timestamp, rgb, intrinsics: Intrinsics, T_world_cam, depth=None,
                  normal=None, gt_T_world_cam=None, timestamp_ns=None) -> None:
        self.log_pose(index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns)
        if self.wants_image(index):
            self._log_images("world/camera/image", *downsized(self.options.image_side, intrinsics, rgb, depth, normal))

    def log_trajectory(self, positions, name="estimate", rotations=None) -> None:
        self._check_open()
        pts = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
        colour = STRIP_COLOURS.get(name.split("/")[0], [0, 180, 255])
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
        # The beta values themselves ride along (an `AnyValues` column) for tools and tests.
        self.rec.log("world/beta", rr.Points3D(np.asarray(centres, dtype=np.float32),
                                               colors=beta_colors(beta), radii=0.5 * float(voxel_size)),
                     rr.AnyValues(beta=np.asarray(beta, dtype=np.float32)))

    def _log_images(self, entity: str, intrinsics: Intrinsics, rgb, depth, normal) -> None:
        self.rec.log(entity, rr.Pinhole(
            image_from_camera=intrinsics.matrix(), width=intrinsics.width, height=intrinsics.height,
            camera_xyz=rr.ViewCoordinates.RDF))
        self.rec.log(f"{entity}/rgb", rr.Image(rgb_to_u8(rgb)).compress(jpeg_quality=self.jpeg_quality))
        if depth is not None:
            self.rec.log(f"{entity}/depth", rr.DepthImage(np.asarray(depth, dtype=np.float32), meter=1.0))
        if normal is not None:
            self.rec.log(f"{entity}/normal", rr.Image(normal_to_u8(normal)).compress(jpeg_quality=self.jpeg_quality))

    def log_map_render(self, index, rgb, depth, normal, intrinsics: Intrinsics, T_world_cam) -> None:
        self._check_open()
        t, q = pose_tq(T_world_cam)
        self.rec.log("world/map_camera", rr.Transform3D(translation=t, quaternion=rr.Quaternion(xyzw=q)))
        self._log_images("world/map_camera/image", intrinsics, rgb, depth, normal)
        self.rec.flush()

    def log_keyframes(self, poses) -> None:
        self._check_open()
        poses = np.asarray(poses, dtype=np.float32).reshape(-1, 4, 4)
        self.rec.log("world/keyframes", rr.Points3D(poses[:, :3, 3], colors=[[255, 200, 0]], radii=0.02),
                     rr.Arrows3D(origins=poses[:, :3, 3], vectors=0.1 * poses[:, :3, 2]))

    def log_scalars(self, index: int, values: Mapping[str, float]) -> None:
        self._check_open()
        self._set_time(index)
        for name, value in values.items():
            self.rec.log(f"metrics/{name}", rr.Scalars(float(value)))

    def log_warning(self, index: int, kind: str, message: str) -> None:
        self._check_open()
        self._set_time(index)
        self.rec.log("tracking/warnings", rr.TextLog(f"frame {index}: {kind}: {message}", level=rr.TextLogLevel.WARN))

    def _grow(self, name: str, position: np.ndarray) -> None:
        """Add a camera centre to trajectory `name`; log its next piece when one is full."""
        self._log_piece(name, self._strips[name].add(position))

    def _log_piece(self, name: str, piece: np.ndarray | None) -> None:
        if piece is not None:
            self.log_trajectory(piece, name=f"{name}/{self._strips[name].count - 1:05d}")

    def close(self) -> None:
        if self._closed:
            return
        try:
            for name, strip in self._strips.items():
                self._log_piece(name, strip.take())
            self.rec.flush()
        finally:
            self._closed = True
            self.rec.disconnect()
