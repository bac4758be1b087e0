"""Exact ray casting of analytic surfaces with view-independent shading (numpy).

Colour of a surface point = solid texture(point) * (ambient + (1 - ambient) * max(0, n . light)),
with a fixed light direction in the world: it depends on the point and its
normal only, never on the viewer, so all views agree on every point's colour.
Rays that hit nothing get depth 0 (invalid) and the scene's sky colour (black without one).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nicer_stream.types import Intrinsics
from sources.synthetic.primitives import Primitive, linear
from sources.synthetic.texture import RoomTexture, SkyGradient, SolidTexture

AMBIENT = 0.6
"""Fraction of the texture colour that unlit (back-facing) surfaces keep."""


def random_light(rng: np.random.Generator) -> np.ndarray:
    """(3,) unit direction towards a light 37 degrees off the zenith, at a random azimuth."""
    az = rng.uniform(0, 2 * np.pi)
    v = np.array([0.6 * np.cos(az), 0.6 * np.sin(az), 0.8])
    return v / np.linalg.norm(v)


@dataclass(frozen=True, eq=False)
class Surface:
    """One textured object of a scene; the texture maps (N, 3) world points to (N, 3) RGB."""

    shape: Primitive
    texture: SolidTexture | RoomTexture
    name: str = ""


@dataclass(frozen=True)
class RenderedView:
    """rgb: (H, W, 3) float32 in [0, 1]; depth: (H, W) float32 z-depth in metres (0 = no hit);
    normal: (H, W, 3) float32 unit normals in the camera frame (OpenCV axes), facing the camera (0 where no hit)."""

    rgb: np.ndarray
    depth: np.ndarray
    normal: np.ndarray


def camera_rays(T_world_cam: np.ndarray, intr: Intrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays of every pixel centre, in row-major pixel order.

    Returns the origin (3,) world (shared by all rays), unit directions (3, H*W)
    world, and unit directions (3, H*W) in the camera frame; float32 directions.
    """
    u = ((np.arange(intr.width) - intr.cx) / intr.fx).astype(np.float32)
    v = ((np.arange(intr.height) - intr.cy) / intr.fy).astype(np.float32)
    d = np.empty((3, intr.height, intr.width), dtype=np.float32)
    d[0], d[1], d[2] = u[None, :], v[:, None], 1.0
    d = d.reshape(3, -1)
    d /= np.sqrt((d * d).sum(0))
    return T_world_cam[:3, 3].copy(), linear(T_world_cam[:3, :3], d), d


def cast(surfaces: list[Surface], o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nearest hit over all surfaces of rays from one origin `o` (3,) along `d` (3, N).

    Returns t (N,) ray distance (inf = miss), index (N,) of the surface hit (-1 = miss),
    and world normals (3, N) (zero on a miss).
    """
    n_rays = d.shape[1]
    t = np.full(n_rays, np.inf, dtype=d.dtype)
    idx = np.full(n_rays, -1)
    normal = np.zeros_like(d)
    for k, s in enumerate(surfaces):
        # Cull with the bounding sphere first: objects cover a small part of the image.
        radius = s.shape.bounding_radius
        if np.isfinite(radius):
            oc = (s.shape.centre - o).astype(d.dtype)
            b = linear(oc, d)
            sel = np.flatnonzero((b * b >= oc @ oc - radius**2) & (b > -radius))
        else:
            sel = np.arange(n_rays)
        if len(sel) == 0:
            continue
        hit = s.shape.intersect(o, d[:, sel])
        closer = hit.t < t[sel]
        rows = sel[closer]
        t[rows] = hit.t[closer]
        idx[rows] = k
        normal[:, rows] = hit.normal[:, closer]
    return t, idx, normal


def shade(surfaces: list[Surface], idx: np.ndarray, p: np.ndarray, n: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(3, N) float32 colour of world points `p` (3, N) with world normals `n` (3, N) on surface `idx` (N,)."""
    rgb = np.zeros(p.shape, dtype=np.float32)
    for k in np.unique(idx[idx >= 0]):
        m = idx == k
        rgb[:, m] = surfaces[k].texture(p[:, m])
    lambert = AMBIENT + (1.0 - AMBIENT) * np.clip(linear(light, n.astype(np.float32)), 0.0, 1.0)
    return rgb * lambert


def render_view(
    surfaces: list[Surface], light: np.ndarray, T_world_cam: np.ndarray, intr: Intrinsics, sky: SkyGradient | None = None
) -> RenderedView:
    """Ray-cast `surfaces` seen by a camera at `T_world_cam` (4, 4) with intrinsics `intr`.

    `light`: (3,) unit world direction towards the light; `sky`: colour of rays that hit nothing.
    """
    T = np.asarray(T_world_cam, dtype=np.float64)
    o, d, d_cam = camera_rays(T, intr)
    t, idx, n = cast(surfaces, o, d)
    hit = idx >= 0
    t_safe = np.where(hit, t, 0.0).astype(np.float32)
    p = o[:, None].astype(np.float32) + d * t_safe
    # Shade with the surface's own normal (view-independent), then make output normals
    # face the viewer (n . d < 0), which only flips rare grazing-angle sign slips.
    rgb = shade(surfaces, idx, p, n, light)
    if sky is not None and not hit.all():
        rgb[:, ~hit] = sky(d[:, ~hit])
    n = np.where((n * d).sum(0) > 0, -n, n)
    n_cam = linear(T[:3, :3].T, n)
    H, W = intr.height, intr.width
    return RenderedView(
        rgb=np.ascontiguousarray(rgb.T.reshape(H, W, 3)),
        depth=(t_safe * d_cam[2]).reshape(H, W),
        normal=np.ascontiguousarray(n_cam.T.reshape(H, W, 3)),
    )
