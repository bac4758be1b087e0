"""Normals from depth: planes give their normal, edges do not bleed, orientation."""
from __future__ import annotations

import numpy as np

from nicer_stream.geometry.depth_normals import normals_from_depth, orient_towards_camera, view_rays
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=60.0, fy=55.0, cx=31.5, cy=23.0, width=64, height=48)


def plane_depth(n: np.ndarray, c: float, intr: Intrinsics) -> np.ndarray:
    """z-depth of the plane n . X = -c (c > 0, n facing the camera) seen by `intr`."""
    rays = view_rays(intr)
    rays = rays / rays[..., 2:3]  # z = 1 directions: X = z * ray
    return (-c / (rays @ n)).astype(np.float64)


def test_tilted_plane_normal_is_recovered_everywhere():
    n = np.array([0.3, -0.2, -1.0])
    n /= np.linalg.norm(n)
    depth = plane_depth(n, 2.0, INTR)
    assert (depth > 0).all()
    out = normals_from_depth(depth, INTR)
    assert out.shape == (48, 64, 3) and out.dtype == np.float32
    np.testing.assert_allclose(out, np.broadcast_to(n, out.shape), atol=1e-5)


def test_scale_invariant():
    n = np.array([-0.5, 0.4, -0.7])
    n /= np.linalg.norm(n)
    depth = plane_depth(n, 1.5, INTR)
    np.testing.assert_allclose(normals_from_depth(3.7 * depth, INTR), normals_from_depth(depth, INTR), atol=1e-6)


def test_depth_step_does_not_bleed_across_the_edge():
    """Two fronto-parallel planes (2 m and 3 m): every pixel keeps (0, 0, -1), edge columns included."""
    depth = np.full((48, 64), 2.0)
    depth[:, 30:] = 3.0
    out = normals_from_depth(depth, INTR)
    np.testing.assert_allclose(out, np.broadcast_to([0.0, 0.0, -1.0], out.shape), atol=1e-6)


def test_orientation_faces_the_camera_and_degenerate_gets_reversed_ray():
    rng = np.random.default_rng(0)
    raw = rng.normal(size=(48, 64, 3))
    raw[0, 0] = 0.0
    out = orient_towards_camera(raw, INTR)
    rays = view_rays(INTR)
    np.testing.assert_allclose(np.linalg.norm(out, axis=-1), 1.0, atol=1e-6)
    assert ((out * rays).sum(-1) <= 0).all()
    np.testing.assert_allclose(out[0, 0], -rays[0, 0], atol=1e-6)
    # Flipping only changes sign: |cos| with the input is 1.
    cos = (out[1:, 1:] * raw[1:, 1:]).sum(-1) / np.linalg.norm(raw[1:, 1:], axis=-1)
    np.testing.assert_allclose(np.abs(cos), 1.0, atol=1e-5)
