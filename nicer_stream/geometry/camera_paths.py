"""Generated camera paths for novel views: T_world_cam (4, 4) float64, OpenCV camera axes
(x right, y down, z forward), metres (docs/conventions.md)."""
from __future__ import annotations

import numpy as np
import torch

from nicer_stream.geometry.se3 import se3_exp, se3_log


def look_at(eye: np.ndarray, target: np.ndarray, down: np.ndarray) -> np.ndarray:
    """The camera at `eye` (3,) looking at `target` (3,), its image's y axis as close to the world
    direction `down` (3,) as the view allows. Raises ValueError when eye == target or the view
    direction is parallel to `down`."""
    z = np.asarray(target, np.float64) - np.asarray(eye, np.float64)
    if np.linalg.norm(z) < 1e-12:
        raise ValueError("look_at: eye and target coincide")
    z /= np.linalg.norm(z)
    x = np.cross(np.asarray(down, np.float64), z)  # y = z x x points along `down`
    if np.linalg.norm(x) < 1e-9:
        raise ValueError("look_at: the view direction is parallel to `down`")
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    T[:3, 3] = eye
    return T


def orbit(poses: np.ndarray, n: int, centre: np.ndarray | None = None, radius_scale: float = 1.0,
          arc_deg: float = 360.0) -> np.ndarray:
    """(n, 4, 4) cameras on a horizontal circle around `centre` (3,) (default: the point nearest
    all the cameras' optical axes), looking at it. `poses` (N, 4, 4) are the run's cameras: their
    `world_down` is the circle's axis, their mean horizontal distance to the centre
    (x `radius_scale`) the radius, their mean height the circle's height; it starts nearest
    the first camera. `arc_deg` < 360 sweeps only that arc (both ends included), turning the way
    the last camera lies from the first: a partial scan is then seen from where it was filmed."""
    poses = np.asarray(poses, np.float64)
    down = world_down(poses)
    centre = _gaze_centre(poses) if centre is None else np.asarray(centre, np.float64)
    eyes = poses[:, :3, 3]
    height = float(np.mean((eyes - centre) @ down))
    flat = (eyes - centre) - np.outer((eyes - centre) @ down, down)
    radius = radius_scale * max(float(np.linalg.norm(flat, axis=1).mean()), 1e-3)
    start = flat[0] / max(np.linalg.norm(flat[0]), 1e-12) if np.linalg.norm(flat[0]) > 1e-9 else _any_perp(down)
    side = np.cross(down, start)
    if flat[-1] @ side < 0:
        side = -side
    full = arc_deg >= 360.0
    out = []
    for a in np.linspace(0.0, np.radians(min(arc_deg, 360.0)), n, endpoint=not full):
        eye = centre + height * down + radius * (np.cos(a) * start + np.sin(a) * side)
        out.append(look_at(eye, centre, down))
    return np.stack(out)


def interpolate(poses: np.ndarray, n_between: int) -> np.ndarray:
    """The poses (N, 4, 4) with `n_between` poses inserted between each consecutive pair, on the
    SE(3) geodesic (T_a exp(s log(T_a^-1 T_b)), s in (0, 1)): (N + (N - 1) n_between, 4, 4)."""
    T = torch.as_tensor(np.asarray(poses, np.float64))
    out = [T[0]]
    for a, b in zip(T[:-1], T[1:]):
        xi = se3_log(torch.linalg.inv(a) @ b)
        for s in np.arange(1, n_between + 1) / (n_between + 1):
            out.append(a @ se3_exp(xi * float(s)))
        out.append(b)
    return torch.stack(out).numpy()


def world_down(poses: np.ndarray) -> np.ndarray:
    """The world's down direction (3,) as hand-held or robot cameras show it: their image x axes
    stay horizontal (no roll), so down is the direction most orthogonal to all of them (least
    squares), signed like their mean image y axis; with too little yaw between the cameras to
    tell, their mean image y axis."""
    x, y = poses[:, :3, 0], poses[:, :3, 1].mean(0)
    w, v = np.linalg.eigh(x.T @ x)  # ascending eigenvalues
    if w[1] < 1e-3 * max(w[2], 1e-12):
        return y / np.linalg.norm(y)
    d = v[:, 0]
    return d if d @ y > 0 else -d


def _gaze_centre(poses: np.ndarray) -> np.ndarray:
    """The point with the least squared distance to every camera's optical axis (the cameras'
    mean position when the axes are parallel)."""
    A, b = np.zeros((3, 3)), np.zeros(3)
    for T in poses:
        d = T[:3, 2] / np.linalg.norm(T[:3, 2])
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ T[:3, 3]
    if np.linalg.cond(A) > 1e8:
        return poses[:, :3, 3].mean(0) + poses[:, :3, 2].mean(0)
    return np.linalg.solve(A, b)


def _any_perp(v: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0, 0]) if abs(v[0]) < 0.9 else np.array([0, 1.0, 0])
    p = np.cross(v, a)
    return p / np.linalg.norm(p)
