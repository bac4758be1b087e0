"""A frame as the mapper holds it: observed image and priors as device tensors."""
from __future__ import annotations

from dataclasses import dataclass, field

import torch

from nicer_stream.types import Frame, Intrinsics, Priors


@dataclass
class MapFrame:
    """Observed data of one frame (no ground truth).

    rgb (H, W, 3) [0, 1]; depth_prior (H, W) relative (NaN/0 invalid) or None;
    normal_prior (H, W, 3) camera frame or None; flows: dst index -> (flow (H, W, 2)
    pixels, valid (H, W) bool).
    """

    index: int
    timestamp: float
    intr: Intrinsics
    rgb: torch.Tensor
    depth_prior: torch.Tensor | None = None
    normal_prior: torch.Tensor | None = None
    flows: dict[int, tuple[torch.Tensor, torch.Tensor]] = field(default_factory=dict)
    depth_scale_shift: tuple[float, float] | None = None
    """(w, q) with depth_prior = w * metric_depth + q when known (then used instead of the
    per-iteration least-squares fit)."""

    @staticmethod
    def from_frame(frame: Frame, priors: Priors | None, device: torch.device) -> "MapFrame":
        def t(a):
            return None if a is None else torch.as_tensor(a, dtype=torch.float32, device=device)

        mf = MapFrame(frame.index, frame.timestamp, frame.intrinsics, t(frame.rgb))
        if priors is not None:
            mf.depth_prior = t(priors.depth)
            mf.normal_prior = t(priors.normal)
            mf.add_flows(priors)
        return mf

    def add_flows(self, priors: Priors) -> None:
        """Keep the flows that start at this frame."""
        for fp in priors.flows:
            if fp.src_index == self.index:
                self.flows[fp.dst_index] = (
                    torch.as_tensor(fp.flow, dtype=torch.float32, device=self.rgb.device),
                    torch.as_tensor(fp.valid, dtype=torch.bool, device=self.rgb.device),
                )
