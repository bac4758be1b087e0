"""Generated camera paths: look-at frames are proper rotations in OpenCV axes, the orbit circles
its centre at constant distance looking at it, interpolation keeps the given poses and moves
along the geodesic."""
import numpy as np
import pytest
import torch

from nicer_stream.geometry.camera_paths import interpolate, look_at, orbit
from nicer_stream.geometry.se3 import se3_exp


def test_look_at_points_z_at_the_target_and_y_down():
    T = look_at(np.array([1.0, -0.5, 2.0]), np.array([0.0, 0.0, 0.0]), down=np.array([0.0, 1.0, 0.0]))
    R = T[:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    assert np.isclose(np.linalg.det(R), 1.0)
    np.testing.assert_allclose(R[:, 2], -np.array([1.0, -0.5, 2.0]) / np.linalg.norm([1.0, -0.5, 2.0]), atol=1e-12)
    assert R[:, 1] @ np.array([0.0, 1.0, 0.0]) > 0.8  # image down is world down as far as possible
    assert abs(R[:, 0] @ np.array([0.0, 1.0, 0.0])) < 1e-12  # no roll: x stays horizontal
    with pytest.raises(ValueError):
        look_at(np.zeros(3), np.array([0.0, 1.0, 0.0]), down=np.array([0.0, 1.0, 0.0]))


def test_orbit_circles_the_centre_looking_at_it():
    cams = np.stack([look_at(np.array([2.0 * np.cos(a), -0.3, 2.0 * np.sin(a)]), np.zeros(3), np.array([0, 1.0, 0]))
                     for a in (0.0, 0.4, 0.8)])
    path = orbit(cams, 12, centre=np.zeros(3))
    assert path.shape == (12, 4, 4)
    eyes = path[:, :3, 3]
    np.testing.assert_allclose(np.linalg.norm(eyes[:, [0, 2]], axis=1), 2.0, atol=1e-9)  # the cameras' radius
    np.testing.assert_allclose(eyes[:, 1], -0.3, atol=1e-9)  # their height
    to_centre = -eyes / np.linalg.norm(eyes, axis=1, keepdims=True)
    np.testing.assert_allclose(path[:, :3, 2], to_centre, atol=1e-9)
    np.testing.assert_allclose(eyes[0], cams[0, :3, 3], atol=1e-9)  # starts at the first camera
    arc = orbit(cams, 5, centre=np.zeros(3), arc_deg=90)  # from the first camera towards the last
    angles = np.degrees(np.arctan2(arc[:, 2, 3], arc[:, 0, 3]))
    np.testing.assert_allclose(angles, [0, 22.5, 45, 67.5, 90], atol=1e-9)
    default = orbit(cams, 4)  # the centre from the optical axes: they meet at the origin
    np.testing.assert_allclose(np.linalg.norm(default[:, :3, 3][:, [0, 2]], axis=1), 2.0, atol=1e-6)


def test_interpolation_keeps_the_poses_and_halves_the_motion():
    a = se3_exp(torch.tensor([0.1, 0.0, 0.2, 0.0, 0.3, 0.0], dtype=torch.float64)).numpy()
    b = se3_exp(torch.tensor([0.5, -0.2, 0.2, 0.2, 0.1, 0.0], dtype=torch.float64)).numpy()
    c = se3_exp(torch.tensor([0.9, -0.2, 0.4, 0.1, 0.1, 0.3], dtype=torch.float64)).numpy()
    path = interpolate(np.stack([a, b, c]), 1)
    assert path.shape == (5, 4, 4)
    np.testing.assert_allclose(path[[0, 2, 4]], np.stack([a, b, c]), atol=1e-12)
    mid = np.linalg.inv(a) @ path[1]  # half of a -> b, applied twice, gives a -> b
    np.testing.assert_allclose(mid @ mid, np.linalg.inv(a) @ b, atol=1e-9)
