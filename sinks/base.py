"""The `Sink` interface (where a run's results are written) and the array
conversions every sink shares. Conventions: docs/conventions.md.

Poses are `T_world_cam` (4, 4) camera-to-world, metres; images are
(H, W, 3) float32 RGB in [0, 1]; depth is z-depth in metres (0 = invalid);
normals are unit vectors in the camera frame (OpenCV axes).
A sink is safe to close twice and after an exception; it flushes regularly
so that what was already logged survives a crash.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Mapping

import cv2
import numpy as np
import torch

from nicer_stream.geometry.se3 import matrix_to_quat, pose_to_tum
from nicer_stream.types import Intrinsics
from sinks.options import SinkOptions


class Sink(ABC):
    """Receives per-frame results, trajectories, meshes and metrics."""

    options: SinkOptions = SinkOptions()
    """How much of each input frame it keeps (`wants_image`); the default keeps every image."""

    @abstractmethod
    def log_pose(self, index: int, timestamp: float, T_world_cam: np.ndarray,
                 gt_T_world_cam: np.ndarray | None = None, timestamp_ns: int | None = None) -> None:
        """Camera pose (4, 4) of frame `index` at `timestamp` seconds, without images.
        `timestamp_ns`, when the source has it, is the exact sensor time and wins over `timestamp`."""

    @abstractmethod
    def log_frame(self, index: int, timestamp: float, rgb: np.ndarray, intrinsics: Intrinsics,
                  T_world_cam: np.ndarray, depth: np.ndarray | None = None,
                  normal: np.ndarray | None = None, gt_T_world_cam: np.ndarray | None = None,
                  timestamp_ns: int | None = None) -> None:
        """One frame: pose plus rgb (H, W, 3) float32 [0, 1], optional z-depth (H, W) metres
        and camera-frame normals (H, W, 3). `timestamp_ns` as in `log_pose`."""

    @abstractmethod
    def log_trajectory(self, positions: np.ndarray, name: str = "estimate",
                       rotations: np.ndarray | None = None) -> None:
        """Camera centres (N, 3) world metres as one polyline called `name` ("estimate", "gt").
        `rotations` (N, 3, 3) R_world_cam, if known, lets pose-aware formats keep orientations."""

    @abstractmethod
    def log_mesh(self, vertices: np.ndarray, faces: np.ndarray,
                 vertex_colors: np.ndarray | None = None, normals: np.ndarray | None = None) -> None:
        """Mesh: vertices (V, 3) world metres, faces (F, 3) int, colours (V, 3) uint8 or
        float [0, 1], normals (V, 3). Expensive: log rarely."""

    @abstractmethod
    def log_beta_voxels(self, centres: np.ndarray, beta: np.ndarray, voxel_size: float) -> None:
        """Voxel centres (N, 3) world metres with their density sharpness `beta` (N,)."""

    @abstractmethod
    def log_map_render(self, index: int, rgb: np.ndarray, depth: np.ndarray, normal: np.ndarray,
                       intrinsics: Intrinsics, T_world_cam: np.ndarray) -> None:
        """What the map renders at keyframe `index`'s pose after a map update: rgb (H, W, 3),
        z-depth (H, W) metres, camera-frame normals (H, W, 3); logged at the current frame's time."""

    @abstractmethod
    def log_keyframes(self, poses: np.ndarray) -> None:
        """Every keyframe's pose (K, 4, 4) after a map update (local BA moves them), at the
        current frame's time."""

    @abstractmethod
    def log_scalars(self, index: int, values: Mapping[str, float]) -> None:
        """Named metrics (name -> value) at frame `index`."""

    def log_warning(self, index: int, kind: str, message: str) -> None:
        """A tracking warning at frame `index` (`slam.events.TrackingWarning`); sinks without a
        text channel ignore it."""

    @abstractmethod
    def close(self) -> None:
        """Finalise outputs. Idempotent; must work after an exception."""

    def wants_image(self, index: int) -> bool:
        """Whether `log_frame(index, ...)` records the image (else the pose only): a caller can
        then skip holding the image for it (the sink worker's queue)."""
        return self.options.keeps_image(index)

    def __enter__(self) -> "Sink":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _forwarded(name: str):
    """A Sink method that hands the call `name(*args, **kwargs)` to `self._forward`."""

    def method(self, *args, **kwargs) -> None:
        self._forward(name, *args, **kwargs)

    method.__name__ = method.__qualname__ = name
    return method


class ForwardingSink(Sink):
    """A sink that hands every log call, by method name, to `_forward` (MultiSink: to several
    sinks; the runtime's SinkWorker: to a thread)."""

    @abstractmethod
    def _forward(self, name: str, *args, **kwargs) -> None:
        """Make (or arrange) the call `name(*args, **kwargs)` on the wrapped sink(s)."""

    log_pose = _forwarded("log_pose")
    log_frame = _forwarded("log_frame")
    log_trajectory = _forwarded("log_trajectory")
    log_mesh = _forwarded("log_mesh")
    log_beta_voxels = _forwarded("log_beta_voxels")
    log_map_render = _forwarded("log_map_render")
    log_keyframes = _forwarded("log_keyframes")
    log_scalars = _forwarded("log_scalars")
    log_warning = _forwarded("log_warning")


def pose_tq(T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(4, 4) pose -> translation (3,) and unit quaternion (qx, qy, qz, qw), qw >= 0, float64."""
    row = pose_to_tum(torch.as_tensor(np.asarray(T_world_cam, dtype=np.float64))).numpy()
    return row[:3], row[3:]


def rotations_to_quats(rotations: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations -> (N, 4) quaternions (qx, qy, qz, qw), qw >= 0."""
    return matrix_to_quat(torch.as_tensor(np.asarray(rotations, dtype=np.float64))).numpy()


def rgb_to_u8(rgb: np.ndarray) -> np.ndarray:
    """(H, W, 3) float [0, 1] (or already uint8) -> (H, W, 3) uint8, clipped."""
    if rgb.dtype == np.uint8:
        return rgb
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def normal_to_u8(normal: np.ndarray) -> np.ndarray:
    """(H, W, 3) unit normals in [-1, 1] -> (H, W, 3) uint8 image of (n + 1) / 2."""
    return rgb_to_u8((np.asarray(normal, dtype=np.float32) + 1.0) * 0.5)


def colors_to_u8(colors: np.ndarray | None) -> np.ndarray | None:
    """(V, 3|4) colours, uint8 or float [0, 1] -> (V, 3|4) uint8 (None passes through)."""
    if colors is None:
        return None
    colors = np.asarray(colors)
    return colors.astype(np.uint8) if np.issubdtype(colors.dtype, np.integer) else rgb_to_u8(colors)


def beta_colors(beta: np.ndarray) -> np.ndarray:
    """(N,) beta -> (N, 3) uint8 RGB, viridis over the min..max range (constant beta: mid colour)."""
    beta = np.asarray(beta, dtype=np.float64).reshape(-1)
    lo, hi = (beta.min(), beta.max()) if beta.size else (0.0, 1.0)
    t = (beta - lo) / (hi - lo) if hi > lo else np.full_like(beta, 0.5)
    lut = cv2.applyColorMap(np.arange(256, dtype=np.uint8)[:, None], cv2.COLORMAP_VIRIDIS)[:, 0, ::-1]
    return lut[np.round(t * 255).astype(np.int64)]


def encode_jpeg(rgb: np.ndarray, quality: int = 90) -> bytes:
    """(H, W, 3) float [0, 1] or uint8 RGB -> JPEG bytes."""
    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb_to_u8(rgb), cv2.COLOR_RGB2BGR),
                           [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:  # pragma: no cover - cv2 only fails on empty images
        raise ValueError(f"cannot JPEG-encode an image of shape {rgb.shape}")
    return buf.tobytes()


def downsized(side: int | None, intrinsics: Intrinsics, rgb: np.ndarray, depth: np.ndarray | None = None,
              normal: np.ndarray | None = None) -> tuple[Intrinsics, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """The images (H, W, ...) and their intrinsics with the longer side at most `side` pixels
    (None, or already small enough: as given). RGB by area averaging; depth and normals by the
    nearest pixel, so no depth mixes a foreground and a background."""
    h, w = rgb.shape[:2]
    if side is None or max(h, w) <= side:
        return intrinsics, rgb, depth, normal
    f = side / max(h, w)
    size = (max(1, round(w * f)), max(1, round(h * f)))
    near = (lambda a: None if a is None else cv2.resize(np.asarray(a), size, interpolation=cv2.INTER_NEAREST))
    return (intrinsics.resized(*size), cv2.resize(np.asarray(rgb), size, interpolation=cv2.INTER_AREA),
            near(depth), near(normal))


def remember(times: dict[int, int], index: int, ns: int, limit: int = 4096) -> None:
    """times[index] = ns, forgetting the oldest entry beyond `limit`: a sink looks up only recent
    frames' times (metrics of the frame just tracked or mapped), and a long log must not grow it."""
    times[int(index)] = ns
    if len(times) > limit:
        del times[next(iter(times))]  # dicts keep insertion order: the oldest frame


def seconds_to_ns(timestamp: float, timestamp_ns: int | None = None) -> int:
    """Seconds -> integer nanoseconds, or `timestamp_ns` when given (exact); clamped at 0
    because MCAP times are unsigned."""
    ns = int(timestamp_ns) if timestamp_ns is not None else int(round(float(timestamp) * 1e9))
    return max(0, ns)
