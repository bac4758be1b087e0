"""The batched mapping objective against the frame-by-frame reference: the same terms and
gradients, the same random partners, and the cases where it must not apply."""
import random
from dataclasses import replace

import pytest
import torch

from nicer_stream.config import LossConfig
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.losses import LossWeights
from nicer_stream.mapping.batched_objective import FrameStack, mapping_terms_batched
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.objective import mapping_terms
from nicer_stream.mapping.ray_sampling import batch_rays
from nicer_stream.render.renderer import RenderOutput
from nicer_stream.types import Intrinsics

INTR = Intrinsics(fx=40.0, fy=42.0, cx=15.5, cy=11.5, width=32, height=24)


def _frames(gen: torch.Generator) -> list[MapFrame]:
    """Six frames with every mix of priors: full, none, depth only, NaN / zero pixels,
    unknown normals, a fixed (w, q), flows to some others."""
    h, w = INTR.height, INTR.width
    frames = []
    for i in range(6):
        f = MapFrame(i, float(i), INTR, torch.rand(h, w, 3, generator=gen))
        if i != 1:
            f.depth_prior = 1.0 + torch.rand(h, w, generator=gen)
            f.depth_prior[0, :5] = float("nan")
            f.depth_prior[1, :5] = 0.0
        if i not in (1, 2):
            n = torch.randn(h, w, 3, generator=gen)
            f.normal_prior = n / n.norm(dim=-1, keepdim=True)
            f.normal_prior[2, :7] = 0.0
        if i == 3:
            f.depth_scale_shift = (1.5, 0.2)
        for j in (i - 1, i + 2):
            if 0 <= j < 6 and i != 4:
                f.flows[j] = (3 * torch.randn(h, w, 2, generator=gen), torch.rand(h, w, generator=gen) > 0.2)
        frames.append(f)
    return frames


def _setup(seed: int = 0):
    gen = torch.Generator().manual_seed(seed)
    frames = _frames(gen)
    xi = torch.randn(len(frames), 6, generator=gen) * torch.tensor([0.05] * 3 + [0.02] * 3)
    xi.requires_grad_(True)
    poses = [se3_exp(x) for x in xi]
    rays, layout = batch_rays(frames, poses, 6 * 40, gen)
    n = rays.origins.shape[0]
    out = RenderOutput(
        rgb=torch.rand(n, 3, generator=gen).requires_grad_(),
        depth=(0.5 + 2 * torch.rand(n, generator=gen)).requires_grad_(),
        ray_dist=torch.zeros(n), normal=torch.randn(n, 3, generator=gen).requires_grad_(),
        opacity=torch.ones(n), points=torch.zeros(n, 3),
        sdf_grad=torch.randn(n * 4, 3, generator=gen).requires_grad_(),
    )
    return frames, layout, out, xi


CFG = LossConfig(weights=LossWeights(rgb=1.0, warp=0.5, flow=0.01, depth=10.0, normal_l1=0.2, normal_angular=0.2))


@pytest.mark.parametrize("fixed,real_camera", [(None, False), ((20.0, 0.0), False), (None, True)])
def test_batched_terms_and_gradients_equal_the_frame_by_frame_reference(fixed, real_camera):
    """Also with a real camera's terms: per-frame affine brightness (gradients to it too) and
    Huber-smoothed RGB and warping residuals (threshold 0.1: about half the random residuals)."""
    frames, layout, out, xi = _setup()
    stack = FrameStack.build(frames)
    assert stack is not None and stack.fits(layout)
    cfg, ab = CFG, None
    if real_camera:
        cfg = replace(CFG, affine_brightness=True, huber_delta=0.1)
        ab = (torch.randn(len(frames), 2, generator=torch.Generator().manual_seed(3)) * 0.2).requires_grad_()
    ref = mapping_terms(out, layout, cfg, fixed, None, random.Random(7), ab)
    new = mapping_terms_batched(out, layout, stack, cfg, fixed, None, random.Random(7), ab)
    inputs = [out.rgb, out.depth, out.normal, out.sdf_grad, xi] + ([ab] if real_camera else [])
    names = ("rgb", "warp", "flow", "depth", "normal_l1", "normal_angular", "eikonal") + (("brightness",) if real_camera else ())
    for name in names:
        a, b = getattr(ref, name), getattr(new, name)
        assert a is not None and b is not None, name
        assert torch.allclose(a, b, rtol=1e-5, atol=1e-7), (name, float(a), float(b))
        ga = torch.autograd.grad(a, inputs, retain_graph=True, allow_unused=True)
        gb = torch.autograd.grad(b, inputs, retain_graph=True, allow_unused=True)
        for x, y in zip(ga, gb):
            assert (x is None or not x.any()) == (y is None or not y.any()), name
            if x is not None and y is not None:
                assert torch.allclose(x, y, rtol=1e-4, atol=1e-6), (name, float((x - y).abs().max()))
    if real_camera:  # every frame's (a, b) takes a gradient from the RGB and warping terms
        for name in ("rgb", "warp"):
            (g,) = torch.autograd.grad(getattr(new, name), [ab], retain_graph=True)
            assert torch.isfinite(g).all() and (g.abs().sum(-1) > 0).all(), name


def test_a_degenerate_depth_fit_counts_as_zero_in_both():
    frames, layout, out, _ = _setup(1)
    with torch.no_grad():
        out.depth[: layout[0].stop] = 1.0  # frame 0's rendered depth is constant: no (w, q) fit
    cfg = replace(CFG, weights=replace(CFG.weights, warp=0.0, flow=0.0))
    ref = mapping_terms(out, layout, cfg, None, None, random.Random(0))
    new = mapping_terms_batched(out, layout, FrameStack.build(frames), cfg, None, None, random.Random(0))
    assert torch.allclose(ref.depth, new.depth, rtol=1e-5)
    assert new.warp is None and new.flow is None


def test_frames_of_other_sizes_or_intrinsics_are_not_stacked():
    frames = _frames(torch.Generator().manual_seed(0))
    assert FrameStack.build(frames[:2] + [frames[2].halved()]) is None
    other = MapFrame(9, 9.0, replace(INTR, fx=41.0), frames[0].rgb)
    assert FrameStack.build(frames[:2] + [other]) is None


def test_a_layout_with_a_frame_outside_the_stack_does_not_fit():
    frames, layout, _, _ = _setup()
    assert not FrameStack.build(frames[:3]).fits(layout)
