"""Smooth camera trajectories: an elliptical arc around the scene, looking at a moving target.

World frame of the synthetic scenes: z up, metres. Poses are `T_world_cam`
(camera-to-world) with OpenCV camera axes (x right, y down, z forward).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from nicer_stream.geometry.camera_paths import look_at

DOWN = -np.array([0.0, 0.0, 1.0])
"""World down direction of the synthetic scenes (z up; negated up: -0.0 entries, so the poses
keep the signed zeros they had): cameras keep their image's y axis near it."""


@dataclass(frozen=True)
class OrbitParams:
    """An elliptical arc of the camera centre plus a wandering look-at target.

    centre: (2,) ellipse centre (x, y); radii: (2,) semi-axes (metres).
    phase0, sweep: start angle and swept angle along the ellipse (radians).
    height, height_amp: camera height and its oscillation amplitude (metres).
    target: (3,) mean look-at point; target_amp: (3,) its oscillation amplitude (metres).
    wobble: number of target/height oscillation cycles over the path.
    """

    centre: np.ndarray
    radii: np.ndarray
    phase0: float
    sweep: float
    height: float
    height_amp: float
    target: np.ndarray
    target_amp: np.ndarray
    wobble: float = 1.5


def orbit_positions(p: OrbitParams, n_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) camera centres and (N, 3) look-at targets, sampling the same path for any N."""
    s = np.linspace(0.0, 1.0, n_frames)
    ang = p.phase0 + p.sweep * s
    w = 2 * np.pi * p.wobble * s
    eye = np.stack(
        [
            p.centre[0] + p.radii[0] * np.cos(ang),
            p.centre[1] + p.radii[1] * np.sin(ang),
            p.height + p.height_amp * np.sin(w),
        ],
        axis=-1,
    )
    # Incommensurate phases so the target wanders rather than oscillating on a line.
    osc = np.stack([np.sin(w + 0.3), np.sin(0.7 * w + 1.1), np.sin(1.3 * w + 2.0)], axis=-1)
    target = p.target + p.target_amp * osc
    return eye, target


def orbit_trajectory(p: OrbitParams, n_frames: int) -> np.ndarray:
    """(N, 4, 4) float64 T_world_cam poses along the orbit."""
    if n_frames < 1:
        raise ValueError("n_frames must be >= 1")
    eye, target = orbit_positions(p, n_frames)
    return np.stack([look_at(e, t, DOWN) for e, t in zip(eye, target)])
