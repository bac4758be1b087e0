"""A frame as the mapper holds it: observed image and priors as device tensors."""
from __future__ import annotations

from dataclasses import dataclass, field

import torch
import torch.nn.functional as F

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

    def halved(self) -> "MapFrame":
        """This frame at half resolution (2x2 area means; a depth-prior pixel only where all four
        were valid; normals renormalised) without its flows: what an old keyframe keeps in RAM."""
        h, w = self.rgb.shape[0] // 2, self.rgb.shape[1] // 2

        def pool(a: torch.Tensor) -> torch.Tensor:  # (H, W, C) -> (h, w, C)
            return F.avg_pool2d(a[: 2 * h, : 2 * w].permute(2, 0, 1)[None], 2)[0].permute(1, 2, 0)

        depth = None
        if self.depth_prior is not None:
            d = self.depth_prior[..., None]
            valid = torch.isfinite(d) & (d > 0)
            mean = pool(torch.where(valid, d, torch.zeros_like(d)))[..., 0]
            all_valid = pool(valid.float())[..., 0] > 0.999
            depth = torch.where(all_valid, mean, torch.full_like(mean, float("nan")))
        normal = None
        if self.normal_prior is not None:
            n = pool(self.normal_prior)
            norm = n.norm(dim=-1, keepdim=True)
            normal = torch.where(norm > 1e-6, n / norm.clamp_min(1e-6), torch.zeros_like(n))  # zero: unknown
        return MapFrame(self.index, self.timestamp, self.intr.resized(w, h), pool(self.rgb), depth, normal,
                        {}, self.depth_scale_shift)

    def add_flows(self, priors: Priors) -> None:
        """Keep the flows that start at this frame (not into a `halved` one: other pixels)."""
        for fp in priors.flows:
            if fp.src_index == self.index and tuple(fp.flow.shape[:2]) == tuple(self.rgb.shape[:2]):
                self.flows[fp.dst_index] = (
                    torch.as_tensor(fp.flow, dtype=torch.float32, device=self.rgb.device),
                    torch.as_tensor(fp.valid, dtype=torch.bool, device=self.rgb.device),
                )
