"""Mapping loss weights (paper Eq. 12) and their weighted sum."""
from __future__ import annotations

from dataclasses import dataclass, fields

import torch


@dataclass(frozen=True)
class LossWeights:
    """Weight of each mapping loss term; defaults are the paper's Eq. 12."""

    rgb: float = 1.0
    """RGB rendering L1 (`rgb_l1`)."""
    warp: float = 0.5
    """RGB warping L1 into nearby keyframes (`warping_loss`)."""
    flow: float = 0.001
    """Optical-flow L1 on rendered correspondences, in pixels (`flow_loss`)."""
    depth: float = 0.1
    """Scale/shift-aligned monocular depth squared error (`mono_depth_loss`)."""
    normal_l1: float = 0.05
    """L1 between rendered and monocular normals (`normal_loss`, first output)."""
    normal_angular: float = 0.05
    """|1 - cos| between rendered and monocular normals (`normal_loss`, second output)."""
    eikonal: float = 0.1
    """Eikonal regulariser on SDF gradients (`eikonal_loss`)."""
    brightness: float = 0.01
    """Pull of the window frames' affine brightness toward (0, 0): mean of a^2 + b^2 (not in
    the paper; only with `loss.affine_brightness`). Weak: the RGB terms decide, it only keeps
    a frame the map barely constrains near the reference exposure."""


@dataclass
class LossTerms:
    """Unweighted loss terms (0-dim tensors) of one iteration; None = not computed.

    Field names match `LossWeights`.
    """

    rgb: torch.Tensor | None = None
    warp: torch.Tensor | None = None
    flow: torch.Tensor | None = None
    depth: torch.Tensor | None = None
    normal_l1: torch.Tensor | None = None
    normal_angular: torch.Tensor | None = None
    eikonal: torch.Tensor | None = None
    brightness: torch.Tensor | None = None


def total_loss(terms: LossTerms, weights: LossWeights = LossWeights()) -> torch.Tensor:
    """Sum of weight * term over the terms that are present (0-dim tensor).

    With no term present, returns a constant 0 (nothing to optimise).
    """
    total: torch.Tensor | None = None
    for f in fields(LossTerms):
        term = getattr(terms, f.name)
        if term is None:
            continue
        weighted = getattr(weights, f.name) * term
        total = weighted if total is None else total + weighted
    return torch.zeros(()) if total is None else total
