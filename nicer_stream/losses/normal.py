"""Monocular normal loss (paper Sec. 3.3): L1 and angular terms."""
from __future__ import annotations

import torch
import torch.nn.functional as F

from nicer_stream.losses.photometric import masked_mean


def normal_loss(
    pred: torch.Tensor, prior: torch.Tensor, mask: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """L1 and angular consistency of rendered and prior normals.

    pred: (N, 3) volume-rendered normals in the camera frame (OpenCV axes);
        not unit length (a weighted sum), so they are normalised first.
    prior: (N, 3) unit monocular normals in the camera frame.
    mask: (N,) bool or None (all rays).
    Returns (l1, angular), 0-dim tensors: mean |n - n_prior|_1 and
    mean |1 - n . n_prior|.
    """
    # eps keeps a zero-length rendered normal (empty ray) finite instead of NaN.
    n = F.normalize(pred, dim=-1, eps=1e-8)
    l1 = masked_mean((n - prior).abs().sum(dim=-1), mask)
    angular = masked_mean((1.0 - (n * prior).sum(dim=-1)).abs(), mask)
    return l1, angular
