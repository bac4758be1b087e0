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


def bound_from_points(points: np.ndarray, margin: float, source: str) -> SceneBound:
    """Cube around (N, 3) world points (e.g. unprojected scaled depth prior) grown by `margin`."""
    lo, hi = np.percentile(points, 1, axis=0), np.percentile(points, 99, axis=0)
    centre = (lo + hi) / 2
    half = float((hi - lo).max() / 2 * margin)
    return SceneBound(tuple(float(c) for c in centre), max(half, 0.5), source)
