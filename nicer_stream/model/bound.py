"""The cube that maps world coordinates into the model's [-1, 1]^3."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch


@dataclass(frozen=True)
class SceneBound:
    """Axis-aligned cube: x_norm = (x_world - centre) / half_extent.

    source: 'config' or 'depth_prior' (how it was chosen; never ground truth).
    """

    centre: tuple[float, float, float]
    half_extent: float
    source: str

    def normalise(self, x: torch.Tensor) -> torch.Tensor:
        """(N, 3) world metres -> (N, 3) normalised."""
        return (x - x.new_tensor(self.centre)) / self.half_extent

    def denormalise(self, x: torch.Tensor) -> torch.Tensor:
        """(N, 3) normalised -> (N, 3) world metres."""
        return x * self.half_extent + x.new_tensor(self.centre)

    def world_min_max(self) -> tuple[np.ndarray, np.ndarray]:
        c = np.asarray(self.centre)
        return c - self.half_extent, c + self.half_extent

    def to_dict(self) -> dict:
        return {"centre": list(self.centre), "half_extent": self.half_extent, "source": self.source}


def bound_from_points(points: np.ndarray, margin: float, source: str, cameras: np.ndarray | None = None,
                      camera_margin: float = 0.0, edge: float = 0.0) -> SceneBound:
    """Cube around (N, 3) world points (e.g. unprojected scaled depth prior) grown by `margin`.

    The cube's side is `margin` times the longest side of the points' 1-99 percentile box, centred
    on that box. With `cameras` (M, 3) world centres, the cube slides, on each axis where their mean
    is nearer a face than `camera_margin` times the half side, until it is not, as far as keeps the
    box, grown by `edge` times its longest side, inside: a first frame's points lie in front of its
    camera, and centred on them the cube starts at the camera, leaving out what a moving camera
    turns round to see next (the demo room's back wall, docs/priors.md)."""
    lo, hi = np.percentile(points, 1, axis=0), np.percentile(points, 99, axis=0)
    centre = (lo + hi) / 2
    longest = float((hi - lo).max())
    half = max(longest / 2 * margin, 0.5)
    if cameras is not None and len(cameras) and camera_margin > 0:
        c = np.asarray(cameras, np.float64).mean(0)
        room = camera_margin * half
        shift = np.minimum(0.0, c - room - (centre - half)) + np.maximum(0.0, c + room - (centre + half))
        e = edge * longest
        first, last = hi + e - half, lo - e + half  # the centres that keep [lo - e, hi + e] inside
        centre = np.where(first <= last, np.clip(centre + shift, first, last), centre)
    return SceneBound(tuple(float(v) for v in centre), half, source)
