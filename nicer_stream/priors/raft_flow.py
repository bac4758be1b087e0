"""torchvision RAFT optical flow (optional; UNTESTED on the project machines).

torchvision cannot be installed next to this project's torch build on the
development machines, so it is imported lazily and a missing torchvision is a
one-line UserError. The weights (`Raft_Large_Weights.DEFAULT`) download on first
use, so this needs internet once. Same mask as DIS: forward/backward consistency.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from nicer_stream.errors import UserError
from nicer_stream.priors.base import FlowProvider
from nicer_stream.priors.flow_consistency import consistency_mask
from nicer_stream.types import FlowPrior, Frame


def _pad8(x: torch.Tensor) -> tuple[torch.Tensor, int, int]:
    """Pad (B, 3, H, W) on the right/bottom to multiples of 8 (RAFT's requirement)."""
    h, w = x.shape[-2:]
    ph, pw = (-h) % 8, (-w) % 8
    return F.pad(x, (0, pw, 0, ph), mode="replicate"), h, w


class RaftFlowProvider(FlowProvider):
    """`raft`: torchvision RAFT-large, both directions in one batch."""

    name = "raft"

    def __init__(self, device: str | torch.device = "cpu", iters: int = 12, alpha: float = 0.005, beta: float = 0.1) -> None:
        try:
            from torchvision.models.optical_flow import Raft_Large_Weights, raft_large
        except ImportError:
            raise UserError(
                "raft needs torchvision built for your torch (pip install torchvision matching torch); "
                "without it use --flow dis"
            ) from None
        weights = Raft_Large_Weights.DEFAULT
        self.device = torch.device(device)
        self.model = raft_large(weights=weights).to(self.device).eval()
        self.transforms = weights.transforms()
        self.iters, self.alpha, self.beta = iters, alpha, beta

    @torch.no_grad()
    def flow_both(self, a: Frame, b: Frame) -> tuple[FlowPrior, FlowPrior]:
        ta = torch.from_numpy(np.ascontiguousarray(a.rgb)).permute(2, 0, 1)[None]
        tb = torch.from_numpy(np.ascontiguousarray(b.rgb)).permute(2, 0, 1)[None]
        x1, x2 = self.transforms(torch.cat([ta, tb]), torch.cat([tb, ta]))  # [0,1] -> [-1,1]
        x1, h, w = _pad8(x1.to(self.device))
        x2, _, _ = _pad8(x2.to(self.device))
        flows = self.model(x1, x2, num_flow_updates=self.iters)[-1][:, :, :h, :w]
        fw, bw = (f.permute(1, 2, 0).cpu().numpy().astype(np.float32) for f in flows)
        return (
            FlowPrior(a.index, b.index, fw, consistency_mask(fw, bw, self.alpha, self.beta)),
            FlowPrior(b.index, a.index, bw, consistency_mask(bw, fw, self.alpha, self.beta)),
        )
