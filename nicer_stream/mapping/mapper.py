"""Mapping optimiser: the three-stage schedule of Sec. 3.3 with Adam groups.

Stage 1 (< fine_start): coarse SDF only. Stage 2: coarse + fine. Stage 3
(>= ba_start): colour grids and the near half of the window's poses join
(local BA). The optimiser persists across calls so Adam's moments carry over.
"""
from __future__ import annotations

import math
import random
import time
from dataclasses import dataclass

import torch

from nicer_stream.config import SlamConfig
from nicer_stream.denormals import flush_denormals
from nicer_stream.geometry.se3 import se3_exp
from nicer_stream.losses import LossTerms, total_loss
from nicer_stream.mapping.batched_objective import FrameStack, mapping_terms_batched
from nicer_stream.mapping.exposure import FrameExposures
from nicer_stream.mapping.map_frame import MapFrame
from nicer_stream.mapping.objective import mapping_terms
from nicer_stream.mapping.ray_sampling import batch_rays
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.render.renderer import render_rays


@dataclass
class MappingStats:
    """Result of one mapping call: iterations, final total loss and terms (floats), seconds."""

    iters: int
    loss: float
    terms: dict[str, float]
    seconds: float


class Mapper:
    """Owns the scene optimiser. `poses` maps frame index -> T_world_cam (4, 4) tensors."""

    def __init__(self, model: SceneModel, beta: BetaField, cfg: SlamConfig, seed: int = 0) -> None:
        self.model, self.beta, self.cfg = model, beta, cfg
        groups = model.param_groups(cfg.mapping)
        if beta.cfg.beta_mode == "global":
            groups["beta"] = {"params": [beta.log_beta], "lr": cfg.mapping.lr}
        self.group_names = list(groups)
        self.base_lrs = [g["lr"] for g in groups.values()]
        # fused Adam: one kernel over the ~20M grid parameters, ~5x faster than the default on CPU.
        self.opt = torch.optim.Adam(list(groups.values()), betas=(0.9, 0.99), eps=1e-15, fused=True)
        # Persistent gradient buffers for the grid tables, zeroed in place each iteration:
        # the row gathers add into them (model/gather.py) instead of allocating.
        for t in model.grid_tables():
            t.grad = torch.zeros_like(t)
        self.gen = torch.Generator().manual_seed(seed)
        self.rng = random.Random(seed)
        self.exposures = FrameExposures(cfg.mapping.lr_brightness, model.geometry.coarse_grid.table.device) \
            if cfg.loss.affine_brightness else None

    def _frozen(self, frac: float, color_start: float) -> set[str]:
        frozen = set()
        if frac < self.cfg.mapping.fine_start:
            frozen |= {"fine", "fine_mlp"}
        if frac < color_start:
            frozen.add("color_grid")
        return frozen

    def _step(self, frozen: set[str]) -> None:
        """Adam step on the groups not in `frozen` (Adam skips parameters without a
        gradient; the buffers are handed back afterwards)."""
        kept = []
        for name, group in zip(self.group_names, self.opt.param_groups):
            if name in frozen:
                for p in group["params"]:
                    kept.append((p, p.grad))
                    p.grad = None
        self.opt.step()
        for p, g in kept:
            p.grad = g

    def _set_lr(self, frac: float, end: float) -> None:
        """Each group's learning rate at fraction `frac` of a call: a cosine from its base rate
        to `end` times it."""
        f = end + (1 - end) * 0.5 * (1 + math.cos(math.pi * frac))
        for group, base in zip(self.opt.param_groups, self.base_lrs):
            group["lr"] = base * f

    def _eikonal_points(self, n: int, use_fine: bool) -> torch.Tensor | None:
        if n <= 0:
            return None
        dev = self.model.geometry.coarse_grid.table.device
        x = torch.rand(n, 3, generator=self.gen).to(dev) * 2 - 1
        return self.model.geometry(x, use_fine=use_fine, with_grad=True).grad

    @flush_denormals()
    def optimise(self, frames: list[MapFrame], poses: dict[int, torch.Tensor], iters: int,
                 ba_indices: set[int] = frozenset(), fixed_scale_shift: tuple[float, float] | None = None,
                 progress=None, time_budget_s: float | None = None,
                 color_start: float | None = None, stop=None, lr_end: float = 1.0) -> MappingStats:
        """Run `iters` iterations over `frames`; poses of `ba_indices` are refined in the
        last stage and written back into `poses`. With `time_budget_s`, the iteration
        count is cut after 3 timed iterations so the schedule fits the budget. The colour
        grids join at fraction `color_start` (default: with the poses, `ba_start`).
        `stop()`, polled before each iteration, ends the call early (stats count the
        iterations done). `lr_end`: the scene's learning rates fall from their base to this
        fraction of it over the call (a cosine); 1: constant."""
        t0 = time.perf_counter()
        m = self.cfg.mapping
        color_start = m.ba_start if color_start is None else color_start
        dev = frames[0].rgb.device
        xi = {i: torch.zeros(6, device=dev, requires_grad=True) for i in ba_indices}
        pose_opt = torch.optim.Adam(list(xi.values()), lr=m.lr_pose) if xi else None
        terms = LossTerms()
        loss = torch.zeros(())
        stack = FrameStack.build(frames) if m.batched_terms else None
        it = 0
        while it < iters:
            if stop is not None and stop():
                break
            if time_budget_s is not None and it == 3:
                per_iter = (time.perf_counter() - t0) / 3
                iters = max(4, min(iters, int(time_budget_s / per_iter)))
            frac = it / max(iters, 1)
            self._set_lr(frac, lr_end)
            use_fine = frac >= m.fine_start
            ba = pose_opt is not None and frac >= m.ba_start
            T = [poses[f.index] @ se3_exp(xi[f.index]) if (ba and f.index in xi) else poses[f.index] for f in frames]
            rays, layout = batch_rays(frames, T, m.rays, self.gen)
            out = render_rays(self.model, self.beta, rays, self.cfg.render, use_fine=use_fine)
            extra = self._eikonal_points(m.eikonal_points, use_fine)
            ab = None if self.exposures is None else self.exposures.rows([f.index for f in frames])
            if stack is not None and stack.fits(layout):
                terms = mapping_terms_batched(out, layout, stack, self.cfg.loss, fixed_scale_shift, extra, self.rng, ab)
            else:
                terms = mapping_terms(out, layout, self.cfg.loss, fixed_scale_shift, extra, self.rng, ab)
            loss = total_loss(terms, self.cfg.loss.weights)
            self.opt.zero_grad(set_to_none=False)
            if pose_opt is not None:
                pose_opt.zero_grad(set_to_none=True)
            loss.backward()
            self._step(self._frozen(frac, color_start))
            self.model.parameters_changed()
            if ba:
                pose_opt.step()
            if self.exposures is not None:
                self.exposures.step()
            self.beta.count(out.points.detach())
            if progress is not None:
                progress(it, iters, float(loss.detach()))
            it += 1
        with torch.no_grad():
            for i, x in xi.items():
                poses[i] = poses[i] @ se3_exp(x.detach())
        vals = {k: float(v.detach()) for k, v in vars(terms).items() if v is not None}
        return MappingStats(it, float(loss.detach()), vals, time.perf_counter() - t0)
