"""A Sim(3) applied to whole poses: how the tests build estimates off by a known alignment."""
from __future__ import annotations

import numpy as np

from nicer_stream.eval.trajectory import Sim3


def apply_poses(sim: Sim3, T: np.ndarray) -> np.ndarray:
    """(N, 4, 4) T_world_cam of the estimate -> aligned poses (rotation R @ R_i, centre scaled)."""
    out = np.array(T, dtype=np.float64, copy=True)
    out[:, :3, :3] = sim.R @ out[:, :3, :3]
    out[:, :3, 3] = sim.apply_points(out[:, :3, 3])
    return out
