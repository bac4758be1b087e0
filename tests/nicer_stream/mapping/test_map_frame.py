"""MapFrame.halved: the half-resolution copy old keyframes keep (bounded memory)."""
import math

import torch

from nicer_stream.geometry.camera import project
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.types import Intrinsics


def test_halved_keeps_the_camera_the_colours_and_only_fully_valid_depth():
    intr = Intrinsics(40.0, 42.0, 15.5, 11.5, 32, 24)
    v, u = torch.meshgrid(torch.arange(24.0), torch.arange(32.0), indexing="ij")
    rgb = torch.stack([u / 31, v / 23, torch.full_like(u, 0.5)], -1)
    depth = 2.0 + 0.01 * u
    depth[5, 7] = float("nan")
    normal = torch.nn.functional.normalize(torch.stack([u - 16, v - 12, -torch.full_like(u, 20.0)], -1), dim=-1)
    mf = MapFrame(3, 0.1, intr, rgb, depth, normal, {9: (torch.zeros(24, 32, 2), torch.ones(24, 32, dtype=torch.bool))},
                  (1.5, 0.2))
    half = mf.halved()
    assert half.rgb.shape == (12, 16, 3) and half.flows == {} and half.depth_scale_shift == (1.5, 0.2)
    # The same 3D point lands on the same spot of the image in both (pixel units scale by 2).
    p = torch.tensor([[0.3, -0.2, 2.0]])
    uv_full, _ = project(p, intr)
    uv_half, _ = project(p, half.intr)
    assert torch.allclose((uv_full + 0.5) / 2 - 0.5, uv_half, atol=1e-5)
    # Colours: 2x2 means of a linear ramp are the ramp at the block centre.
    assert torch.allclose(half.rgb[3, 4, 0], torch.tensor(8.5 / 31), atol=1e-6)
    assert math.isnan(half.depth_prior[2, 3]) and torch.isfinite(half.depth_prior).sum() == 12 * 16 - 1
    assert torch.allclose(half.normal_prior.norm(dim=-1), torch.ones(12, 16), atol=1e-5)
