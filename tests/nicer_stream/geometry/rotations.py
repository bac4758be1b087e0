"""Rotations for the tests (geometry/se3.py's own so3_exp moved here: only the tests used it)."""
import torch

from nicer_stream.geometry.se3 import se3_exp


def so3_exp(phi: torch.Tensor) -> torch.Tensor:
    """(..., 3) axis-angle -> (..., 3, 3) rotation matrix (Rodrigues): se3_exp's rotation block."""
    return se3_exp(torch.cat([torch.zeros_like(phi), phi], -1))[..., :3, :3]
