"""Depth Anything (V2) monocular depth through Hugging Face `transformers` (optional extra).

Loaded with `AutoImageProcessor` + `AutoModelForDepthEstimation` from a model id
(default `depth-anything/Depth-Anything-V2-Small-hf`, needs internet the first
time; offline, HF_HUB_OFFLINE=1 fails at once instead of after the hub
client's retries) or a local directory saved with `save_pretrained`.

Depth Anything predicts relative *inverse* depth (disparity, affine-invariant:
larger = nearer). We turn it into a depth-like prior: the disparity is
normalised by its 99th percentile, clipped at 0, and inverted as
1 / (disp + eps). That is only an affine-ambiguous stand-in for depth (the
disparity shift is unknown), which is what the scale/shift-invariant depth
loss expects. Normals are derived from that depth with `normals_from_depth`,
so they inherit its distortion; they are a weak prior compared to Omnidata's.
"""
from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F

from nicer_stream.errors import UserError
from nicer_stream.priors.base import DepthNormal, DepthNormalProvider
from nicer_stream.geometry.depth_normals import normals_from_depth
from nicer_stream.types import Frame

DEFAULT_MODEL = "depth-anything/Depth-Anything-V2-Small-hf"


def disparity_to_depth(disp: np.ndarray, eps: float = 0.05) -> np.ndarray:
    """(H, W) relative disparity -> (H, W) float32 depth-like prior 1 / (disp / p99 + eps), in (0, 1/eps]."""
    ref = float(np.percentile(disp, 99))
    d = np.clip(disp / ref, 0.0, None) if ref > 0 else np.zeros_like(disp)
    return (1.0 / (d + eps)).astype(np.float32)


def _load(model_id: str):
    try:
        from transformers import AutoImageProcessor, AutoModelForDepthEstimation
    except ImportError:
        raise UserError(
            "depth-anything needs the `transformers` package: pip install transformers (or use --provider omnidata/cache:DIR)"
        ) from None
    try:
        return AutoImageProcessor.from_pretrained(model_id), AutoModelForDepthEstimation.from_pretrained(model_id)
    except Exception as e:  # network, missing files, wrong architecture
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise UserError(
            f"cannot load Depth Anything '{model_id}' ({first}): give a Hugging Face model id (needs internet) "
            f"or a local save_pretrained directory: --provider depth-anything:/path/to/model"
        ) from None


class DepthAnythingProvider(DepthNormalProvider):
    """`depth-anything[:MODEL_ID_OR_PATH]`: depth-like prior from inverse depth, normals derived from it."""

    name = "depth-anything"

    def __init__(self, model_id: str = DEFAULT_MODEL, device: str | torch.device = "cpu", eps: float = 0.05) -> None:
        self.device = torch.device(device)
        self.eps = eps
        self.processor, model = _load(model_id)
        self.model = model.to(self.device).eval()

    @torch.no_grad()
    def predict(self, frame: Frame) -> DepthNormal:
        h, w = frame.height, frame.width
        u8 = np.clip(frame.rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)
        inputs = self.processor(images=u8, return_tensors="pt")
        out = self.model(pixel_values=inputs["pixel_values"].to(self.device)).predicted_depth  # (1, h', w')
        disp = F.interpolate(out[:, None].float(), size=(h, w), mode="bilinear", align_corners=False)[0, 0]
        depth = disparity_to_depth(disp.cpu().numpy(), self.eps)
        return DepthNormal(depth=depth, normal=normals_from_depth(depth, frame.intrinsics))
