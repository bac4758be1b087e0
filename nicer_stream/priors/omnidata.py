"""Omnidata DPT-Hybrid monocular depth and normals through torch.hub.

`torch.hub.load(repo_or_dir, 'dpt_hybrid_384', pretrained=True, task='depth'|'normal')`
with the default GitHub repo `alexsax/omnidata_tools` (needs internet: GitHub for
the code, HuggingFace for the weights), or `source='local'` when `repo_or_dir`
is a directory holding a hubconf.py (e.g. a clone with its weights cached).

Preprocessing as Omnidata's demo: RGB resized to 384x384; depth input normalised
with mean = std = 0.5 (i.e. to [-1, 1]); normal input left in [0, 1].
Outputs are resized back to the frame size (bilinear).

Normal convention (assumption, stated by Omnidata's authors and by DN-Splatter,
not verifiable offline here): the normal output in [0, 1] maps by 2x-1 to a unit
vector in OpenGL-style camera axes (x right, y up, z towards the viewer), so a
surface facing the camera reads (0, 0, 1). We convert to OpenCV axes (x right,
y down, z forward) by negating y and z (`OMNIDATA_TO_OPENCV`), then flip any
normal still pointing away from the camera.
"""
from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np
import torch
import torch.nn.functional as F

from nicer_stream.errors import UserError
from nicer_stream.priors.base import DepthNormal, DepthNormalProvider
from nicer_stream.geometry.depth_normals import orient_towards_camera
from nicer_stream.types import Frame

DEFAULT_REPO = "alexsax/omnidata_tools"
ENTRYPOINT = "dpt_hybrid_384"
INPUT_SIZE = 384
OMNIDATA_TO_OPENCV = np.array([1.0, -1.0, -1.0], dtype=np.float32)


def omnidata_normals_to_opencv(n01: np.ndarray) -> np.ndarray:
    """(..., 3) Omnidata normal output in [0, 1] -> (..., 3) float32 OpenCV-axes vectors (not re-normalised)."""
    return ((np.clip(n01, 0.0, 1.0) * 2.0 - 1.0) * OMNIDATA_TO_OPENCV).astype(np.float32)


def load_hub_model(repo_or_dir: str, task: str, load: Callable = torch.hub.load) -> torch.nn.Module:
    """Omnidata model for `task` ('depth' or 'normal'); local directory -> source='local'."""
    local = Path(repo_or_dir).is_dir()
    kwargs = dict(source="local") if local else dict(source="github", trust_repo=True)
    try:
        return load(repo_or_dir, ENTRYPOINT, pretrained=True, task=task, **kwargs)
    except Exception as e:  # hub errors are varied (network, missing hubconf, bad weights)
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise UserError(
            f"cannot load Omnidata '{task}' model from '{repo_or_dir}' ({first}): it needs internet access "
            f"(GitHub + HuggingFace) or a local directory with hubconf.py: --provider omnidata:/path/to/omnidata_tools"
        ) from None


def _to_batch(rgb: np.ndarray, device) -> torch.Tensor:
    """(H, W, 3) float32 [0, 1] -> (1, 3, 384, 384) on device."""
    x = torch.from_numpy(np.ascontiguousarray(rgb)).permute(2, 0, 1)[None].float().to(device)
    return F.interpolate(x, size=(INPUT_SIZE, INPUT_SIZE), mode="bilinear", align_corners=False, antialias=True)


def _back_to_size(y: torch.Tensor, h: int, w: int) -> torch.Tensor:
    """Model output (1, H', W') or (1, C, H', W') -> (C, h, w) float32 on CPU."""
    if y.ndim == 3:
        y = y[:, None]
    return F.interpolate(y.float(), size=(h, w), mode="bilinear", align_corners=False)[0].cpu()


class OmnidataProvider(DepthNormalProvider):
    """`omnidata[:PATH_OR_HUB]`: Omnidata DPT-Hybrid depth (relative, larger = farther) and normals."""

    name = "omnidata"

    def __init__(self, repo_or_dir: str = DEFAULT_REPO, device: str | torch.device = "cpu", load: Callable = torch.hub.load) -> None:
        self.device = torch.device(device)
        self.depth_model = load_hub_model(repo_or_dir, "depth", load).to(self.device).eval()
        self.normal_model = load_hub_model(repo_or_dir, "normal", load).to(self.device).eval()

    @torch.no_grad()
    def predict(self, frame: Frame) -> DepthNormal:
        h, w = frame.height, frame.width
        x = _to_batch(frame.rgb, self.device)
        depth = _back_to_size(self.depth_model((x - 0.5) / 0.5), h, w)[0].clamp(0, 1).numpy()
        n01 = _back_to_size(self.normal_model(x), h, w).permute(1, 2, 0).numpy()
        normal = orient_towards_camera(omnidata_normals_to_opencv(n01), frame.intrinsics)
        return DepthNormal(depth=depth.astype(np.float32), normal=normal)
