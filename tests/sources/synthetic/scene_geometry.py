"""What the tests measure of a synthetic scene (moved from SyntheticScene: only the tests used it)."""
from __future__ import annotations

import numpy as np


def bounds(scene) -> tuple[np.ndarray, np.ndarray]:
    """(3,) min and (3,) max world corner of a box holding every surface of `scene`."""
    centre = np.stack([s.shape.centre for s in scene.surfaces])
    extent = np.stack([s.shape.extent for s in scene.surfaces])
    return (centre - extent).min(0), (centre + extent).max(0)


def clearance(scene, points: np.ndarray) -> np.ndarray:
    """(N,) distance in metres from world points (N, 3) to the nearest surface of `scene`."""
    p = np.asarray(points, dtype=np.float64).T
    return np.min([s.shape.sdf(p) for s in scene.surfaces], axis=0)
