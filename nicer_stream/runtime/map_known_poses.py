"""`nicer-stream map`: fit the scene to frames whose poses are known (GT or a TUM file)."""
from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from nicer_stream import config as config_mod
from nicer_stream.errors import UserError
from nicer_stream.io.trajectory import read_tum
from nicer_stream.mapping.mapper import Mapper
from nicer_stream.mapping.prior_alignment import align_to_widest_partner
from nicer_stream.model.scene import SceneModel
from nicer_stream.render.beta import BetaField
from nicer_stream.runtime.allocator import retain_freed_memory
from nicer_stream.runtime.matmul_backend import enable_onednn_matmul
from nicer_stream.io.scene_file import save_scene
from nicer_stream.model.bound import SceneBound, bound_from_points
from nicer_stream.model.bound_estimate import bound_from_cameras, bound_from_config, metric_points
from nicer_stream.runtime.frame_priors import fuses_stereo, make_engine, map_frame, provider_names
from nicer_stream.runtime.progress import Progress
from nicer_stream.runtime.run_outputs import write_mesh, write_summary, write_trajectory
from nicer_stream.runtime.scene_export import save_render, scene_mesh
from nicer_stream.runtime.stage_timer import StageTimer
from nicer_stream.render.renderer import render_image
from nicer_stream.runtime.source_setup import open_configured
from nicer_stream.priors.keyframe_stereo import StereoPriors, fusion_params
from sources.base import SourceOptions

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class MapRequest:
    """What `nicer-stream map` was asked to do."""

    source: str
    """Source URI (`sources.open_source`)."""
    out_dir: Path
    """Output directory (created)."""
    poses: str
    """A TUM trajectory file, one line per frame, or 'gt': the source's ground truth, by name only."""
    priors: str = "auto"
    """Depth / normal provider by name; `auto` without learned weights is `none` (never `stereo`,
    which needs the SLAM's poses)."""
    flow: str | None = None
    """Flow provider by name (None: the depth provider's default)."""
    preset: str = "fast"
    """Config preset: fast or paper."""
    config_file: str | None = None
    """A .toml / .json file overriding preset fields."""
    iters: int | None = None
    """Mapping iterations (None: the preset's `mapping.batch_iters`)."""
    minutes: float | None = None
    """Stop mapping after about this many minutes (None: no limit)."""
    device: str = "cpu"
    """torch device."""
    render_every: int | None = None
    """Render (and evaluate) every N-th frame; None: at most 20 views spread evenly."""
    source_opts: SourceOptions = SourceOptions()
    """Which frames of the source, at what size, with which intrinsics."""


def _poses(frames, spec: str) -> np.ndarray:
    if spec == "gt":
        missing = [f.index for f in frames if f.gt_pose is None]
        if missing:
            raise UserError(f"--poses gt: the source has no ground-truth pose for frames {missing[:5]}: pass --poses FILE.tum")
        return np.stack([f.gt_pose for f in frames])
    _, poses = read_tum(spec)
    if len(poses) < len(frames):
        raise UserError(f"--poses {spec}: {len(poses)} poses for {len(frames)} frames: one line per frame is needed")
    return poses[: len(frames)]


def _align_priors(mfs, poses) -> dict[int, tuple[float, float]]:
    """Metric (w, q) per frame index from flow triangulation with the known poses, using
    the partner with the widest baseline (frames that could not be aligned are absent)."""
    by_index = {m.index: m for m in mfs}
    return {m.index: wq for m in mfs if (wq := align_to_widest_partner(m, by_index, poses)) is not None}


def _metric_points(cfg, mfs, aligned, poses) -> np.ndarray | None:
    """(P, 3) world points of the metric-aligned priors (every 4th pixel of every aligned frame)."""
    pts = []
    for m in (m for m in mfs if m.index in aligned):
        w, q = aligned[m.index]
        depth = ((m.depth_prior - q) / w)[::4, ::4]
        sub = m.intr.resized(depth.shape[1], depth.shape[0])
        pts.append(metric_points(depth.cpu().numpy(), sub, poses[m.index].double().cpu().numpy(), cfg.bound))
    return np.concatenate(pts) if pts else None


def _bound(cfg, points: np.ndarray | None, poses_np) -> SceneBound:
    """Config bound, else the metric-aligned priors' `points` with the configured margin, else a
    cube in front of the cameras."""
    if cfg.bound.mode == "config":
        return bound_from_config(cfg.bound)
    if points is None:
        return bound_from_cameras(poses_np, cfg.bound)
    return bound_from_points(points, cfg.bound.margin, "depth_prior")


def _fuse_stereo(cfg, frames, mfs, poses, bound: SceneBound, points: np.ndarray | None) -> StereoPriors:
    """`stereo.mono_fusion` as the SLAM does it, with the known poses: every frame swept against
    partners chosen by baseline (the metric-aligned priors' `points` standing in for the
    frontend's landmarks), its monocular depth fitted to that depth and filling its holes."""
    sp = StereoPriors(fusion_params(cfg.stereo))
    for f in frames:
        sp.observe(f.index, f.rgb, f.detail)
    index = [m.index for m in mfs]
    sp.update(index, {m.index: m for m in mfs}, poses, index, bound, points)
    return sp


def run_map(req: MapRequest) -> Path:
    """Fit the scene to the source's frames with the requested poses and write the output directory."""
    cfg = config_mod.load(req.preset, req.config_file)
    if req.priors == "stereo":
        raise UserError("--priors stereo needs the SLAM's poses: use `nicer-stream run` (map takes per-frame priors)")
    timer = StageTimer()
    torch.manual_seed(cfg.seed)
    retain_freed_memory()
    enable_onednn_matmul()
    engine = make_engine(req.priors, req.flow, req.device, auto_fallback="none", seed=cfg.seed)
    if engine.depth_normal.auto_reason:
        print(engine.depth_normal.auto_reason, flush=True)
    fuse = fuses_stereo(cfg, engine.depth_normal.name)
    # The frontend's larger images are the sweeps' too (`Frame.detail`).
    source, _ = open_configured(req.source, req.source_opts, cfg, tracking=fuse)
    frames = list(source)
    if not frames:
        raise UserError(f"source {req.source} gave no frames")
    poses_np = _poses(frames, req.poses)
    out = Path(req.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with timer.stage("priors"):
        # Flows to frames 2 and 5 steps away (both ways): parallax large enough to constrain depth.
        mfs = [map_frame(f, engine, [frames[j] for j in (i - 5, i - 2, i + 2, i + 5) if 0 <= j < len(frames)], req.device)
               for i, f in enumerate(frames)]
    poses = {f.index: torch.tensor(poses_np[i], dtype=torch.float32, device=req.device) for i, f in enumerate(frames)}
    aligned = _align_priors(mfs, poses)
    points = _metric_points(cfg, mfs, aligned, poses) if cfg.bound.mode != "config" or fuse else None
    bound = _bound(cfg, points, poses_np)
    if cfg.loss.metric_prior_alignment:
        for m in mfs:
            m.depth_scale_shift = aligned.get(m.index)
    stereo = None
    if fuse:
        print(f"fitting the {len(mfs)} frames' depth priors to their plane-sweep stereo (stereo.mono_fusion)", flush=True)
        with timer.stage("priors"):
            stereo = _fuse_stereo(cfg, frames, mfs, poses, bound, points)
    model = SceneModel(cfg.model, bound).to(req.device)
    beta = BetaField(cfg.render).to(req.device)
    stats, interrupted = _optimise(req, cfg, model, beta, mfs, poses, timer)
    save_scene(out, cfg, model, beta)
    with timer.stage("sinks"):
        _write_views(req, cfg, model, beta, frames, poses, poses_np, stereo)
    notes = [f"mapping with known poses ({req.poses}); scene bound from {bound.source}"]
    notes += [engine.depth_normal.auto_reason] if engine.depth_normal.auto_reason else []
    notes += [f"depth prior aligned to metres by flow triangulation on {len(aligned)}/{len(mfs)} frames"
              + ("" if cfg.loss.metric_prior_alignment else " (for the bound only; the depth loss refits scale and shift)")]
    notes += ([f"each frame's depth fitted to its plane-sweep stereo depth, which it fills (stereo.mono_fusion): "
               f"{stereo.fusion_note('frame')}"] if stereo is not None else [])
    write_summary(
        out, frames=len(frames), preset=cfg.preset, device=req.device, priors=provider_names(engine), timer=timer,
        interrupted=interrupted, bound=bound, source=req.source, notes=notes,
        intrinsics=asdict(frames[0].intrinsics), config=asdict(cfg),
        stats={"iterations": stats.iters if stats else 0, "final_loss": stats.loss if stats else None,
               "loss_terms": stats.terms if stats else {}},
    )
    return out


def _optimise(req: MapRequest, cfg, model, beta, mfs, poses, timer: StageTimer):
    """The mapping iterations -> (their stats or None, whether Ctrl-C ended them)."""
    iters = req.iters or cfg.mapping.batch_iters
    try:
        with timer.stage("mapping"):
            return Mapper(model, beta, cfg, cfg.seed).optimise(
                mfs, poses, iters, progress=Progress("mapping"),
                time_budget_s=req.minutes * 60 if req.minutes else None,
                color_start=cfg.mapping.batch_color_start), False
    except KeyboardInterrupt:
        log.warning("interrupted: writing the outputs of the mapping so far")
        return None, True


def _write_views(req: MapRequest, cfg, model, beta, frames, poses, poses_np, stereo) -> None:
    """Renders of every N-th frame and the last one, the trajectory and the mesh."""
    out, intr = Path(req.out_dir), frames[0].intrinsics
    every = req.render_every or -(-len(frames) // 20)
    views = sorted(set(range(0, len(frames), max(1, every))) | {len(frames) - 1})
    for k, i in enumerate(views):
        view = render_image(model, beta, poses[frames[i].index], intr, cfg.render)
        save_render(out, frames[i].index, view, frames[i].rgb, frames[i].timestamp)
        print(f"render {k + 1}/{len(views)} (frame {frames[i].index})", flush=True)
    write_trajectory(out, [f.timestamp for f in frames], list(poses_np))
    measured = stereo.measured_views({f.index: poses_np[i] for i, f in enumerate(frames)}, intr) if stereo else []
    write_mesh(out, scene_mesh(model, beta, poses_np, intr, cfg, measured=measured))
