"""Small MLPs. `GeometryMLP` also returns the spatial gradient of its first output (the SDF)
as an ordinary differentiable tensor, so SDF normals and the Eikonal term need only a
first-order backward (its analytic second derivative is in `sdf_grad_mlp.py`).
"""
from __future__ import annotations

import torch
from torch import nn

from nicer_stream.model.linear import Linear
from nicer_stream.model.softplus import softplus_beta
from nicer_stream.model.sdf_grad_mlp import FusedSdfGradMLP


class GeometryMLP(nn.Module):
    """Linear layers with Softplus(beta=100) between them; output 0 is the SDF."""

    def __init__(self, in_dim: int, hidden: int, n_hidden: int, out_dim: int, last_std: float = 1e-4) -> None:
        super().__init__()
        dims = [in_dim] + [hidden] * n_hidden + [out_dim]
        self.layers = nn.ModuleList(Linear(a, b) for a, b in zip(dims[:-1], dims[1:]))
        nn.init.normal_(self.layers[-1].weight, std=last_std)
        nn.init.zeros_(self.layers[-1].bias)

    def forward(self, h: torch.Tensor, n_out: int | None = None) -> torch.Tensor:
        """h (N, in) -> (N, out), or its first `n_out` columns only (the SDF alone: probes and
        meshing skip the features' rows of the last layer); no spatial gradient."""
        for layer in self.layers[:-1]:
            h = softplus_beta(layer(h))
        return self.layers[-1](h, n_out)

    def value_and_input_grad(self, h: torch.Tensor):
        """h (N, in) -> out (N, out) and u = d out[:, 0] / d h (N, in), both differentiable.

        Reverse mode in one fused node (`sdf_grad_mlp.py`): half the FLOPs of the three tangent
        rows of the tests' forward-mode reference; the caller contracts u with its inputs' Jacobians."""
        params = [p for layer in self.layers for p in (layer.weight, layer.bias)]
        return FusedSdfGradMLP.apply(h, len(self.layers), *params)


def plain_mlp(in_dim: int, hidden: int, n_hidden: int, out_dim: int) -> nn.Sequential:
    """ReLU MLP (colour decoder)."""
    dims = [in_dim] + [hidden] * n_hidden
    mods: list[nn.Module] = []
    for a, b in zip(dims[:-1], dims[1:]):
        mods += [Linear(a, b), nn.ReLU(inplace=True)]
    mods.append(Linear(dims[-1], out_dim))
    return nn.Sequential(*mods)
