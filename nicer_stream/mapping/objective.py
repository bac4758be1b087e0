"""The mapping objective (Eq. 12) for one rendered ray batch."""
from __future__ import annotations

import random

import torch

from nicer_stream.config import LossConfig
from nicer_stream.losses import (
    LossTerms, eikonal_loss, flow_loss, mono_depth_loss, normal_loss, rgb_l1, warp_pixels, warping_loss,
)
from nicer_stream.losses.brightness import apply_brightness
from nicer_stream.mapping.ray_sampling import FrameRays
from nicer_stream.render.renderer import RenderOutput


def _mean(xs: list[torch.Tensor]) -> torch.Tensor | None:
    return torch.stack(xs).mean() if xs else None


def warp_partners(fr: FrameRays, layout: list[FrameRays], k: int, rng: random.Random) -> list[FrameRays]:
    """k other window frames drawn at random each iteration, those with a flow prior first:
    varied baselines constrain depth far better than the nearest (near-zero parallax) frames."""
    others = [o for o in layout if o.frame.index != fr.frame.index]
    rng.shuffle(others)
    others.sort(key=lambda o: o.frame.index not in fr.frame.flows)
    return others[:k]


def brightness_prior(brightness: torch.Tensor | None) -> torch.Tensor | None:
    """The pull of (F, 2) frames' affine brightness toward (0, 0): mean of a^2 + b^2 (None: off)."""
    return None if brightness is None else (brightness * brightness).sum(-1).mean()


def mapping_terms(out: RenderOutput, layout: list[FrameRays], cfg: LossConfig,
                  fixed_scale_shift: tuple[float, float] | None = None,
                  extra_sdf_grad: torch.Tensor | None = None, rng: random.Random | None = None,
                  brightness: torch.Tensor | None = None) -> LossTerms:
    """Unweighted loss terms. Per-frame terms (depth alignment, warping, flow) are
    computed frame by frame and averaged. `brightness`: (F, 2) affine brightness (a, b) of the
    layout's frames in its order (`mapping/exposure.py`), applied to the RGB and warping terms
    (None: the paper's, none)."""
    rgb, warp, flow, depth, n_l1, n_ang = [], [], [], [], [], []
    pos = {fr.frame.index: i for i, fr in enumerate(layout)}
    for i, fr in enumerate(layout):
        sl = slice(fr.start, fr.stop)
        f = fr.frame
        target = f.rgb.reshape(-1, 3)[fr.pix]
        pred = out.rgb[sl] if brightness is None else apply_brightness(out.rgb[sl], brightness[i])
        rgb.append(rgb_l1(pred, target, None, cfg.huber_delta))
        d = out.depth[sl]
        if f.depth_prior is not None:
            prior = f.depth_prior.reshape(-1)[fr.pix]
            fixed = f.depth_scale_shift or fixed_scale_shift
            depth.append(mono_depth_loss(d, prior, (prior > 0) & torch.isfinite(prior), fixed))
        if f.normal_prior is not None:
            n_cam = out.normal[sl] @ fr.T_world_cam[:3, :3]  # R^T n in row form
            n_prior = f.normal_prior.reshape(-1, 3)[fr.pix]
            # Zero normals are unknown (stereo priors leave them where the depth is not confident).
            l1, ang = normal_loss(n_cam, n_prior, n_prior.abs().sum(-1) > 0)
            n_l1.append(l1)
            n_ang.append(ang)
        partners = warp_partners(fr, layout, cfg.warp_frames, rng or random.Random(0)) if (cfg.weights.warp > 0 or cfg.weights.flow > 0) else []
        if partners:
            uvs, valids, imgs = [], [], []
            for p in partners:
                uv_dst, _, valid = warp_pixels(fr.uv, d, f.intr, fr.T_world_cam, p.frame.intr, p.T_world_cam)
                uvs.append(uv_dst)
                valids.append(valid)
                imgs.append(p.frame.rgb)
                if p.frame.index in f.flows and cfg.weights.flow > 0:
                    fl, fv = f.flows[p.frame.index]
                    flow.append(flow_loss(fr.uv, uv_dst, fl.reshape(-1, 2)[fr.pix], valid & fv.reshape(-1)[fr.pix]))
            if cfg.weights.warp > 0:
                ab_dst = None if brightness is None else [brightness[pos[p.frame.index]] for p in partners]
                warp.append(warping_loss(target, imgs, uvs, valids, cfg.huber_delta,
                                         None if brightness is None else brightness[i], ab_dst))
    grads = out.sdf_grad if extra_sdf_grad is None else torch.cat([out.sdf_grad, extra_sdf_grad])
    return LossTerms(
        rgb=_mean(rgb), warp=_mean(warp), flow=_mean(flow), depth=_mean(depth),
        normal_l1=_mean(n_l1), normal_angular=_mean(n_ang), eikonal=eikonal_loss(grads),
        brightness=brightness_prior(brightness),
    )
