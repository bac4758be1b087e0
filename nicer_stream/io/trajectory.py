"""TUM trajectory files: one line per frame, `t tx ty tz qx qy qz qw`, T_world_cam."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from nicer_stream.errors import UserError
from nicer_stream.geometry.se3 import pose_from_tum, pose_to_tum


def write_tum(path: str | Path, timestamps: np.ndarray, poses: np.ndarray) -> None:
    """Write (N,) timestamps [s] and (N, 4, 4) T_world_cam poses. Refuses NaN."""
    poses = np.asarray(poses, dtype=np.float64)
    if not np.isfinite(poses).all():
        raise ValueError("refusing to write a trajectory containing NaN/inf poses")
    rows = pose_to_tum(torch.from_numpy(poses)).numpy() if len(poses) else np.zeros((0, 7))
    with open(path, "w") as f:
        f.write("# timestamp tx ty tz qx qy qz qw (T_world_cam, OpenCV camera axes, metres)\n")
        for t, r in zip(np.asarray(timestamps, dtype=np.float64), rows):
            f.write(f"{t:.6f} " + " ".join(f"{x:.9f}" for x in r) + "\n")


def read_tum(path: str | Path, fix: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM file -> ((N,) timestamps, (N, 4, 4) T_world_cam). A malformed file raises
    ValueError, or with `fix` (what to do about it) a one-line UserError ending in it."""
    rows = []
    try:
        for line in Path(path).read_text().splitlines():
            line = line.strip()
            if not line or line.startswith("#"):
                continue
            vals = line.replace(",", " ").split()
            if len(vals) != 8:
                raise ValueError(f"{path}: expected 8 values per line (t tx ty tz qx qy qz qw), "
                                 f"got {len(vals)}")
            rows.append([float(v) for v in vals])
        if not rows:
            raise ValueError(f"{path}: no poses found")
    except ValueError as e:
        if fix is None:
            raise
        raise UserError(f"{e}: {fix}") from None
    arr = np.asarray(rows, dtype=np.float64)
    return arr[:, 0], pose_from_tum(torch.from_numpy(arr[:, 1:])).numpy()
