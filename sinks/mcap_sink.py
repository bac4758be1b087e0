"""MCAP sink: Foxglove protobuf messages, readable by Foxglove and by Rerun's MCAP import.

Topics (frame ids: `world`, `camera` = OpenCV optical frame):
  /camera/image        CompressedImage (jpeg)        /camera/calibration  CameraCalibration
                       (these and depth/normal for every `images_every`-th frame, up to `image_side` px)
  /camera/depth        RawImage 32FC1 (z-depth, m)   /camera/normal       CompressedImage (png, (n+1)/2)
  /tf                  FrameTransform world->camera, i.e. the camera pose T_world_cam
  /camera/pose         PoseInFrame (world)           /camera/gt_pose      PoseInFrame (world), if GT given
  /trajectory[/name]   PosesInFrame (estimate; other names get a sub-topic; identity
                       orientations unless rotations are given)
  /mesh                SceneUpdate with one TriangleListPrimitive
  /beta                PointCloud, fields x y z beta (float32)
  /map/image /map/depth /map/normal /map/calibration   the map's render of the newest keyframe
                       after each map update (frame id `map_camera`, placed by /tf and /map/pose)
  /keyframes           PosesInFrame: every keyframe's pose after each map update
  /metrics/{name}      google.protobuf.DoubleValue
  /tracking/warnings   Log (WARNING): the SLAM's tracking warnings (frontend health, disagreements)
Every message's log_time and publish_time is the sensor time in ns (frame time; the last
frame's time for trajectory, mesh, beta).
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import cv2
import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.TriangleListPrimitive_pb2 import TriangleListPrimitive
from google.protobuf.wrappers_pb2 import DoubleValue
from mcap_protobuf.writer import Writer

from nicer_stream.types import Intrinsics
from sinks.base import (Sink, colors_to_u8, downsized, encode_jpeg, normal_to_u8, pose_tq, remember,
                        rotations_to_quats, seconds_to_ns)
from sinks.options import SinkOptions

WORLD, CAMERA, MAP_CAMERA = "world", "camera", "map_camera"


def stamped(msg, ns: int):
    """`msg` with its `timestamp` set to `ns` nanoseconds."""
    msg.timestamp.FromNanoseconds(ns)
    return msg


def make_pose(t: np.ndarray, q: np.ndarray) -> Pose:
    """Translation (3,) and quaternion (qx, qy, qz, qw) -> foxglove Pose."""
    p = Pose()
    p.position.x, p.position.y, p.position.z = (float(v) for v in t)
    p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w = (float(v) for v in q)
    return p


def calibration(intr: Intrinsics, ns: int, frame_id: str = CAMERA) -> CameraCalibration:
    """Undistorted pinhole: K (3x3) and P = [K | 0] (3x4), row-major."""
    K = intr.matrix()
    msg = CameraCalibration(frame_id=frame_id, width=intr.width, height=intr.height, distortion_model="plumb_bob",
                            K=K.reshape(-1).tolist(), D=[0.0] * 5, R=np.eye(3).reshape(-1).tolist(),
                            P=np.hstack([K, np.zeros((3, 1))]).reshape(-1).tolist())
    return stamped(msg, ns)


def depth_image(depth: np.ndarray, ns: int, frame_id: str = CAMERA) -> RawImage:
    """(H, W) z-depth metres -> RawImage 32FC1, little-endian, unpadded rows."""
    d = np.ascontiguousarray(depth, dtype="<f4")
    return stamped(RawImage(frame_id=frame_id, width=d.shape[1], height=d.shape[0], encoding="32FC1",
                            step=4 * d.shape[1], data=d.tobytes()), ns)


def compressed(data: bytes, fmt: str, ns: int, frame_id: str = CAMERA) -> CompressedImage:
    return stamped(CompressedImage(frame_id=frame_id, data=data, format=fmt), ns)


def normal_png(normal: np.ndarray, ns: int, frame_id: str = CAMERA) -> CompressedImage:
    """(H, W, 3) camera-frame normals -> a PNG CompressedImage of (n + 1) / 2."""
    _, png = cv2.imencode(".png", cv2.cvtColor(normal_to_u8(normal), cv2.COLOR_RGB2BGR))
    return compressed(png.tobytes(), "png", ns, frame_id)


def repeated_doubles_wire(field_number: int, values: np.ndarray) -> bytes:
    """Protobuf wire bytes of a repeated sub-message field whose messages hold only doubles
    numbered 1..K (foxglove Point3: x y z; Color: r g b a). values: (N, K) float64.

    Building 10^5 messages one by one in Python takes seconds; this is one numpy pass.
    """
    n, k = values.shape
    rec = np.dtype([("tag", "u1"), ("len", "u1")] + [(f"t{i}", "u1") if j == 0 else (f"v{i}", "<f8")
                                                     for i in range(k) for j in range(2)])
    out = np.empty(n, rec)
    out["tag"], out["len"] = (field_number << 3) | 2, 9 * k  # length-delimited; 9 bytes per double
    for i in range(k):
        out[f"t{i}"], out[f"v{i}"] = ((i + 1) << 3) | 1, values[:, i]  # 64-bit fixed
    return out.tobytes()


def mesh_update(vertices, faces, colors_u8, ns: int) -> SceneUpdate:
    """A SceneUpdate with entity `mesh`: indexed triangle list in the world frame."""
    tri = TriangleListPrimitive(pose=make_pose(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])))
    tri.MergeFromString(repeated_doubles_wire(2, np.asarray(vertices, dtype=np.float64).reshape(-1, 3)))
    tri.indices.extend(np.asarray(faces, dtype=np.int64).reshape(-1).tolist())
    if colors_u8 is None:
        tri.color.r, tri.color.g, tri.color.b, tri.color.a = 0.7, 0.7, 0.7, 1.0
    else:
        rgba = np.ones((len(colors_u8), 4))
        rgba[:, : colors_u8.shape[1]] = colors_u8[:, :4] / 255.0
        tri.MergeFromString(repeated_doubles_wire(4, rgba))
    return SceneUpdate(entities=[stamped(SceneEntity(frame_id=WORLD, id="mesh", triangles=[tri]), ns)])


def beta_cloud(centres: np.ndarray, beta: np.ndarray, ns: int) -> PointCloud:
    """(N, 3) centres and (N,) beta -> PointCloud with float32 fields x, y, z, beta (stride 16)."""
    data = np.concatenate([np.asarray(centres, "<f4").reshape(-1, 3), np.asarray(beta, "<f4").reshape(-1, 1)], 1)
    f32 = PackedElementField.NumericType.FLOAT32
    fields = [PackedElementField(name=n, offset=4 * i, type=f32) for i, n in enumerate(["x", "y", "z", "beta"])]
    return stamped(PointCloud(frame_id=WORLD, pose=make_pose(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0])),
                              point_stride=16, fields=fields, data=np.ascontiguousarray(data).tobytes()), ns)


class McapSink(Sink):
    """Writes one MCAP file; each frame is flushed as its own chunk so a crash loses at most one
    frame; `options` thin out the input images."""

    def __init__(self, path: str | Path, jpeg_quality: int = 90, options: SinkOptions = SinkOptions()) -> None:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
        self._file = open(path, "wb")
        self._writer = Writer(self._file)
        self.jpeg_quality = jpeg_quality
        self.options = options
        self._time_ns: dict[int, int] = {}  # recent frames only (`remember`)
        self._now_ns = 0
        self._closed = False

    def _write(self, topic: str, msg, ns: int | None = None) -> None:
        if self._closed:
            raise RuntimeError("McapSink is closed")
        ns = self._now_ns if ns is None else ns
        self._writer.write_message(topic, msg, log_time=ns, publish_time=ns)

    def _flush_chunk(self) -> None:
        # mcap's Writer.flush() ends the open chunk and writes it: what was logged survives a crash.
        # mcap_protobuf's Writer does not expose it, hence the inner writer.
        self._writer._writer.flush()

    def _pose_in_frame(self, T: np.ndarray, ns: int) -> PoseInFrame:
        return stamped(PoseInFrame(frame_id=WORLD, pose=make_pose(*pose_tq(T))), ns)

    def log_pose(self, index, timestamp, T_world_cam, gt_T_world_cam=None, timestamp_ns=None) -> None:
        self._write_pose(index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns)
        self._flush_chunk()

    def _write_tf(self, T_world_cam: np.ndarray, child: str, ns: int) -> None:
        t, q = pose_tq(T_world_cam)
        tf = stamped(FrameTransform(parent_frame_id=WORLD, child_frame_id=child), ns)
        tf.translation.x, tf.translation.y, tf.translation.z = (float(v) for v in t)
        tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w = (float(v) for v in q)
        self._write("/tf", tf)

    def _write_pose(self, index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns) -> None:
        ns = self._now_ns = seconds_to_ns(timestamp, timestamp_ns)
        remember(self._time_ns, index, ns)
        self._write_tf(T_world_cam, CAMERA, ns)
        self._write("/camera/pose", self._pose_in_frame(T_world_cam, ns))
        if gt_T_world_cam is not None:
            self._write("/camera/gt_pose", self._pose_in_frame(gt_T_world_cam, ns))

    def log_frame(self, index, timestamp, rgb, intrinsics: Intrinsics, T_world_cam, depth=None,
                  normal=None, gt_T_world_cam=None, timestamp_ns=None) -> None:
        if not self.wants_image(index):
            self.log_pose(index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns)
            return
        self._write_pose(index, timestamp, T_world_cam, gt_T_world_cam, timestamp_ns)
        intrinsics, rgb, depth, normal = downsized(self.options.image_side, intrinsics, rgb, depth, normal)
        ns = self._now_ns
        self._write("/camera/image", compressed(encode_jpeg(rgb, self.jpeg_quality), "jpeg", ns))
        self._write("/camera/calibration", calibration(intrinsics, ns))
        if depth is not None:
            self._write("/camera/depth", depth_image(depth, ns))
        if normal is not None:
            self._write("/camera/normal", normal_png(normal, ns))
        self._flush_chunk()

    def log_trajectory(self, positions, name="estimate", rotations=None) -> None:
        pos = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
        quats = (np.tile([0.0, 0.0, 0.0, 1.0], (len(pos), 1)) if rotations is None
                 else rotations_to_quats(np.asarray(rotations, dtype=np.float64)))
        msg = PosesInFrame(frame_id=WORLD, poses=[make_pose(t, q) for t, q in zip(pos, quats)])
        self._write("/trajectory" if name == "estimate" else f"/trajectory/{name}", stamped(msg, self._now_ns))

    def log_mesh(self, vertices, faces, vertex_colors=None, normals=None) -> None:
        # Foxglove triangle lists carry no normals (they are shaded flat).
        self._write("/mesh", mesh_update(vertices, faces, colors_to_u8(vertex_colors), self._now_ns))
        self._flush_chunk()

    def log_beta_voxels(self, centres, beta, voxel_size) -> None:
        # PointCloud has no point size: viewers pick one (voxel_size is not stored).
        self._write("/beta", beta_cloud(centres, beta, self._now_ns))

    def log_map_render(self, index, rgb, depth, normal, intrinsics: Intrinsics, T_world_cam) -> None:
        ns = self._now_ns
        self._write_tf(T_world_cam, MAP_CAMERA, ns)
        pose = self._pose_in_frame(T_world_cam, ns)
        self._write("/map/pose", pose)
        self._write("/map/calibration", calibration(intrinsics, ns, MAP_CAMERA))
        self._write("/map/image", compressed(encode_jpeg(rgb, self.jpeg_quality), "jpeg", ns, MAP_CAMERA))
        self._write("/map/depth", depth_image(depth, ns, MAP_CAMERA))
        self._write("/map/normal", normal_png(normal, ns, MAP_CAMERA))
        self._flush_chunk()

    def log_keyframes(self, poses) -> None:
        poses = np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4)
        msg = PosesInFrame(frame_id=WORLD, poses=[make_pose(*pose_tq(T)) for T in poses])
        self._write("/keyframes", stamped(msg, self._now_ns))

    def log_scalars(self, index: int, values: Mapping[str, float]) -> None:
        ns = self._time_ns.get(int(index), self._now_ns)
        for name, value in values.items():
            self._write(f"/metrics/{name}", DoubleValue(value=float(value)), ns)

    def log_warning(self, index: int, kind: str, message: str) -> None:
        ns = self._time_ns.get(int(index), self._now_ns)
        msg = Log(level=Log.Level.WARNING, message=f"frame {index}: {kind}: {message}", name="nicer-stream")
        self._write("/tracking/warnings", stamped(msg, ns), ns)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()
