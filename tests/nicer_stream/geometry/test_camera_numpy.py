"""The numpy camera pair: `unproject_world` is the inverse of `project_world`."""
import numpy as np

from nicer_stream.geometry.camera import project_world, unproject_world
from nicer_stream.types import Intrinsics


def test_unproject_world_inverts_project_world():
    rng = np.random.default_rng(0)
    intr = Intrinsics(fx=300.0, fy=280.0, cx=160.0, cy=118.0, width=320, height=240)
    a = 0.4
    T = np.eye(4)
    T[:3, :3] = [[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]]
    T[:3, 3] = [0.5, -0.2, 1.0]
    uv = rng.uniform([0, 0], [320, 240], (50, 2))
    z = rng.uniform(0.3, 5.0, 50)
    X = unproject_world(T, uv, z, intr)
    uv2, z2 = project_world(T, X, intr)
    assert np.allclose(uv2, uv, atol=1e-9) and np.allclose(z2, z, atol=1e-12)
    # z-depth, not ray distance: the point's distance from the camera exceeds z off the axis
    assert (np.linalg.norm(X - T[:3, 3], axis=1) > z - 1e-12).all()
