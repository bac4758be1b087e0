"""SDF -> density (Eq. 4, VolSDF Laplace CDF)."""
from __future__ import annotations

import torch

from nicer_stream.numerics import expm1_neg


def laplace_density(sdf: torch.Tensor, beta: torch.Tensor | float) -> torch.Tensor:
    """sigma = (1/beta) * Psi_beta(-s), Psi_beta the zero-mean Laplace CDF of scale beta.

    Our SDF is positive in free space (VolSDF's sign), so density is low there:
    s > 0: (1/2beta) exp(-s/beta);  s <= 0: (1/beta)(1 - exp(s/beta)/2).
    Paper Eq. 4 is the same curve written for the opposite sign of s. The expm1
    of -|s| form never overflows; `expm1_neg` keeps it off the CPU's denormal path.
    """
    inv = 1.0 / beta
    return inv * (0.5 + 0.5 * torch.sign(sdf) * expm1_neg(sdf.abs() * inv))
