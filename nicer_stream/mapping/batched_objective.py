"""The mapping objective (Eq. 12) over all window frames at once.

The same terms as `objective.mapping_terms` (the reference, frame by frame), for a window
whose frames share their size and intrinsics and whose rays are split evenly
(`ray_sampling.batch_rays`): ~100 tensor ops per iteration instead of ~40 per frame and ~70
per warped partner. At the demo's 9-frame windows the reference's ~18k small ops per
iteration (forward and backward, each a few microseconds of dispatch on one thread) were
a fifth of a `fast` mapping iteration (docs/performance.md).
"""
from __future__ import annotations

import random
from dataclasses import dataclass

import torch
import torch.nn.functional as F

from nicer_stream.config import LossConfig
from nicer_stream.geometry.camera import in_image, project, unproject
from nicer_stream.geometry.se3 import invert
from nicer_stream.losses import LossTerms, eikonal_loss, masked_mean
from nicer_stream.losses.brightness import apply_brightness, brightness_into
from nicer_stream.losses.mono_depth import degenerate_fit, masked_moments
from nicer_stream.losses.robust import robust_l1
from nicer_stream.losses.warping import bilinear_sample_rows
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.objective import brightness_prior, warp_partners
from nicer_stream.mapping.ray_sampling import FrameRays
from nicer_stream.render.renderer import RenderOutput


@dataclass
class FrameStack:
    """A mapping call's frames as rows of one tensor per kind (built once per call).

    rgb (K*H*W, 3); depth (K*H*W,) relative prior, NaN where a frame has none; normal
    (K*H*W, 3) camera frame, zero where unknown; `has_depth`, `has_normal` per frame; `row`:
    frame index -> its position k (its pixels start at row k*H*W)."""

    rgb: torch.Tensor
    depth: torch.Tensor
    normal: torch.Tensor
    has_depth: list[bool]
    has_normal: list[bool]
    row: dict[int, int]
    height: int
    width: int

    @staticmethod
    def build(frames: list[MapFrame]) -> "FrameStack | None":
        """None when the frames differ in size or intrinsics (then the reference applies)."""
        f0 = frames[0]
        if any(f.intr != f0.intr or f.rgb.shape != f0.rgb.shape for f in frames):
            return None
        h, w = f0.rgb.shape[:2]
        nan = torch.full((h, w), float("nan"), device=f0.rgb.device)
        zero = torch.zeros(h, w, 3, device=f0.rgb.device)
        return FrameStack(
            rgb=torch.cat([f.rgb.reshape(-1, 3) for f in frames]),
            depth=torch.cat([(nan if f.depth_prior is None else f.depth_prior).reshape(-1) for f in frames]),
            normal=torch.cat([(zero if f.normal_prior is None else f.normal_prior).reshape(-1, 3) for f in frames]),
            has_depth=[f.depth_prior is not None for f in frames],
            has_normal=[f.normal_prior is not None for f in frames],
            row={f.index: k for k, f in enumerate(frames)},
            height=h, width=w,
        )

    def fits(self, layout: list[FrameRays]) -> bool:
        """The layout's frames are stacked here and their rays split evenly, in order."""
        per = layout[0].stop - layout[0].start
        return all(fr.frame.index in self.row and fr.start == i * per and fr.stop - fr.start == per
                   for i, fr in enumerate(layout))


def _depth_rows(d: torch.Tensor, prior: torch.Tensor, fixed: list[tuple[float, float] | None]) -> torch.Tensor:
    """Eq. 10 per row: (R, n) rendered z-depth and relative prior -> (R,) `mono_depth_loss`,
    with (w, q) fitted per row where `fixed[r]` is None (0 for a degenerate fit)."""
    valid = (prior > 0) & torch.isfinite(prior)
    with torch.no_grad():
        n, mp, mt, var, cov = masked_moments(d, prior, valid)
        degenerate = degenerate_fit(n, mp, var)
        w = torch.where(degenerate, 1.0, cov / var.clamp_min(1e-300))
        q = torch.where(degenerate, 0.0, mt - w * mp)
        for r, wq in enumerate(fixed):
            if wq is not None:
                w[r], q[r] = wq
        skip = (degenerate & torch.tensor([wq is None for wq in fixed], device=d.device)).tolist()
    keep = [r for r, s in enumerate(skip) if not s]
    out = d.new_zeros(len(fixed))
    if keep:
        k = torch.tensor(keep, device=d.device)
        res = w[k].to(d.dtype)[:, None] * d[k] + q[k].to(d.dtype)[:, None] - torch.where(valid[k], prior[k], 0.0)
        out = out.index_put((k,), masked_mean(res * res, valid[k]))
    return out


def mapping_terms_batched(out: RenderOutput, layout: list[FrameRays], stack: FrameStack, cfg: LossConfig,
                          fixed_scale_shift: tuple[float, float] | None = None,
                          extra_sdf_grad: torch.Tensor | None = None, rng: random.Random | None = None,
                          brightness: torch.Tensor | None = None) -> LossTerms:
    """`objective.mapping_terms` for a layout that `stack.fits`: the same terms (to float
    rounding) and the same random partners drawn from `rng`."""
    nfr, per = len(layout), layout[0].stop - layout[0].start
    h, w, hw = stack.height, stack.width, stack.height * stack.width
    dev = out.rgb.device
    k_of = torch.tensor([stack.row[fr.frame.index] for fr in layout], device=dev)  # (F,) stack position
    pix = torch.cat([fr.pix for fr in layout]).view(nfr, per)
    grow = k_of[:, None] * hw + pix  # (F, per) rows of the stack
    target = stack.rgb[grow.reshape(-1)]
    pred = out.rgb.view(nfr, per, 3)
    if brightness is not None:
        pred = apply_brightness(pred, brightness[:, None])
    rgb = robust_l1(pred - target.view(nfr, per, 3), cfg.huber_delta).mean(-1).mean()
    d = out.depth.view(nfr, per)
    intr = layout[0].frame.intr

    depth = None
    rows = [i for i, fr in enumerate(layout) if stack.has_depth[stack.row[fr.frame.index]]]
    if rows:
        ri = torch.tensor(rows, device=dev)
        fixed = [layout[i].frame.depth_scale_shift or fixed_scale_shift for i in rows]
        depth = _depth_rows(d[ri], stack.depth[grow[ri]], fixed).mean()

    n_l1 = n_ang = None
    rows = [i for i, fr in enumerate(layout) if stack.has_normal[stack.row[fr.frame.index]]]
    if rows:
        ri = torch.tensor(rows, device=dev)
        R = torch.stack([layout[i].T_world_cam[:3, :3] for i in rows])
        n_cam = F.normalize(torch.bmm(out.normal.view(nfr, per, 3)[ri], R), dim=-1, eps=1e-8)  # R^T n, rows
        n_prior = stack.normal[grow[ri]]
        known = n_prior.abs().sum(-1) > 0  # zero normals are unknown (stereo priors)
        n_l1 = masked_mean((n_cam - n_prior).abs().sum(-1), known).mean()
        n_ang = masked_mean((1.0 - (n_cam * n_prior).sum(-1)).abs(), known).mean()

    warp = flow = None
    if cfg.weights.warp > 0 or cfg.weights.flow > 0:
        pos = {fr.frame.index: i for i, fr in enumerate(layout)}
        pairs = [(i, pos[p.frame.index]) for i, fr in enumerate(layout)
                 for p in warp_partners(fr, layout, cfg.warp_frames, rng or random.Random(0))]
        if pairs:
            si = torch.tensor([a for a, _ in pairs], device=dev)
            di = torch.tensor([b for _, b in pairs], device=dev)
            Ts = torch.stack([fr.T_world_cam for fr in layout]).to(d.dtype)
            T_ds = invert(Ts[di]) @ Ts[si]  # (P, 4, 4) T_dst_src
            uv = torch.cat([fr.uv for fr in layout]).view(nfr, per, 2)[si]  # (P, per, 2)
            p_src = unproject(uv.reshape(-1, 2), d[si].reshape(-1), intr).view(len(pairs), per, 3)
            p_dst = p_src @ T_ds[:, :3, :3].transpose(1, 2) + T_ds[:, None, :3, 3]
            uv_dst, z_dst = project(p_dst.reshape(-1, 3), intr)
            valid = ((d[si].reshape(-1) > 0) & (z_dst > 0) & in_image(uv_dst, intr)).view(len(pairs), per)
            uv_dst = uv_dst.view(len(pairs), per, 2)
            if cfg.weights.flow > 0:
                with_flow = [j for j, (a, b) in enumerate(pairs) if layout[b].frame.index in layout[a].frame.flows]
                if with_flow:
                    fl, fv = zip(*(layout[pairs[j][0]].frame.flows[layout[pairs[j][1]].frame.index] for j in with_flow))
                    src_pix = [layout[pairs[j][0]].pix for j in with_flow]
                    prior = torch.stack([f.reshape(-1, 2)[p] for f, p in zip(fl, src_pix)])
                    ok = torch.stack([v.reshape(-1)[p] for v, p in zip(fv, src_pix)])
                    jf = torch.tensor(with_flow, device=dev)
                    residual = (uv_dst[jf] - uv[jf]) - prior
                    flow = masked_mean(residual.abs().sum(-1), valid[jf] & ok).mean()
            if cfg.weights.warp > 0:
                first = (k_of[di] * hw)[:, None].expand(len(pairs), per).reshape(-1)
                seen = bilinear_sample_rows(stack.rgb, h, w, uv_dst.reshape(-1, 2), first).view(len(pairs), per, 3)
                if brightness is not None:  # the partner's colours in the source's exposure
                    seen = brightness_into(seen, brightness[di, None], brightness[si, None])
                err = torch.where(valid, robust_l1(seen - target.view(nfr, per, 3)[si], cfg.huber_delta), 0.0)
                num = d.new_zeros(nfr).index_add(0, si, err.sum(-1))
                cnt = d.new_zeros(nfr).index_add(0, si, valid.sum(-1).to(d.dtype))
                src = torch.unique(si)  # frames with partners, in layout order
                warp = (num[src] / cnt[src].clamp_min(1)).mean()
    grads = out.sdf_grad if extra_sdf_grad is None else torch.cat([out.sdf_grad, extra_sdf_grad])
    return LossTerms(rgb=rgb, warp=warp, flow=flow, depth=depth, normal_l1=n_l1, normal_angular=n_ang,
                     eikonal=eikonal_loss(grads), brightness=brightness_prior(brightness))
