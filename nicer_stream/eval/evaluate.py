"""Evaluate an output directory (trajectory.tum, mesh.ply, renders/, summary.json) against a source's GT.

The estimate lives in the SLAM world. The trajectory is compared after the Umeyama
Sim(3) alignment of camera centres (trajectory.py). The scene (depth, mesh) is compared
under the trajectory's Sim(3) refined by ICP of the mesh onto the GT surface, as the
paper aligns monocular meshes (registration.py); the metrics under the trajectory's
Sim(3) alone are reported next to them. Missing inputs give None (null) metrics;
malformed files raise one-line UserErrors.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np
import trimesh

from nicer_stream.errors import UserError
from nicer_stream.eval import image, mesh as mesh_m, reference, registration, trajectory
from nicer_stream.eval.heldout import HeldOutPicker, render_heldout
from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import read_tum
from nicer_stream.types import Frame, Intrinsics
from nicer_stream.io.scene_file import SCENE_FILE
from sources.base import FrameSource, SourceOptions, resize_frame

CULL_MAX_SIDE = 320  # GT depth kept for occlusion culling is downsampled to this (memory)
HELDOUT_VIEWS = 8


@dataclass
class _View:
    """One render next to its source frame at the render's size."""

    frame_index: int
    rgb: np.ndarray  # (H, W, 3) float32 rendered
    depth: np.ndarray | None  # (H, W) rendered z-depth, estimate units
    gt_rgb: np.ndarray
    gt_depth: np.ndarray | None


def _read_trajectory(out: Path) -> tuple[np.ndarray, np.ndarray] | None:
    path = out / od.TRAJECTORY_FILE
    return read_tum(path, "rewrite or delete the trajectory") if path.is_file() else None


def _render_paths(out: Path) -> dict[int, Path]:
    """frame index -> render file, from the file names frame_NNNNNN.npz."""
    paths = {}
    for p in sorted((out / od.RENDERS_DIR).glob("frame_*.npz")):
        try:
            paths[int(p.stem.split("_", 1)[1])] = p
        except ValueError:
            continue
    return paths


def _load_view(path: Path, frame: Frame) -> _View | None:
    try:
        with np.load(path) as z:
            rgb = np.asarray(z["rgb"], np.float32)
            depth = np.asarray(z["depth"], np.float32) if "depth" in z.files else None
    except (OSError, ValueError, KeyError) as e:
        raise UserError(f"cannot read render {path} ({e}): delete it or rerun mapping") from None
    H, W = rgb.shape[:2]
    f = resize_frame(frame, SourceOptions(max_side=max(W, H)))
    if (f.width, f.height) != (W, H):
        warnings.warn(f"render {path.name} is {W}x{H} but the source frame is {f.width}x{f.height}: skipped")
        return None
    return _View(frame.index, rgb, depth, f.rgb, f.gt_depth)


def _match(est_t: np.ndarray, frame_t: np.ndarray, tol: float = 5e-4) -> np.ndarray:
    """Positions of source frames matching each trajectory line: by timestamp when
    unambiguous, else by order (first min(N, M) lines)."""
    if len(frame_t) and len(est_t):
        j = np.abs(est_t[:, None] - frame_t[None, :]).argmin(1)
        if (np.abs(frame_t[j] - est_t) < tol).all() and len(np.unique(j)) == len(j):
            return j
    return np.arange(min(len(est_t), len(frame_t)))


def _trajectory_metrics(rep: od.EvalReport, est: np.ndarray, gt: np.ndarray) -> trajectory.Sim3 | None:
    """Fill ATE/RPE fields; returns the Sim(3) that brings the estimated scene (depth,
    mesh) into the GT world (`trajectory.pose_sim3`), None if < 2 poses."""
    if len(est) < 2:
        return None
    sim = trajectory.ate(est, gt, with_scale=True)
    rep.ate_rmse_m, rep.sim3_scale = sim.rmse_m, sim.alignment.scale
    rep.ate_se3_rmse_m = trajectory.ate(est, gt, with_scale=False).rmse_m
    r = trajectory.rpe(est, gt, delta=1, scale=sim.alignment.scale)
    rep.rpe_trans_m, rep.rpe_rot_deg = r.trans_rmse_m, r.rot_rmse_deg
    return trajectory.pose_sim3(est, gt)


def _depth_l1(views: list[_View], scale: float) -> float | None:
    """Mean over views of the per-view depth L1 with the estimate scaled by `scale`."""
    l1 = [image.depth_l1(v.depth, v.gt_depth, scale) for v in views if v.depth is not None and v.gt_depth is not None]
    l1 = [x for x in l1 if x is not None]
    return float(np.mean(l1)) if l1 else None


def _psnr_ssim(views: list[_View]) -> tuple[float, float]:
    """PSNR and SSIM averaged over `views` (not empty)."""
    return (float(np.mean([image.psnr(v.rgb, v.gt_rgb) for v in views])),
            float(np.mean([image.ssim(v.rgb, v.gt_rgb) for v in views])))


def _image_metrics(rep: od.EvalReport, views: list[_View], scale: float | None, pose_scale: float | None) -> None:
    """Per-view PSNR/SSIM/depth L1 (under `scale`, and under the trajectory's `pose_scale`), averaged over views."""
    if not views:
        return
    rep.psnr_db, rep.ssim = _psnr_ssim(views)
    if scale is not None:
        rep.depth_l1_m = _depth_l1(views, scale)
        rep.depth_l1_pose_aligned_m = _depth_l1(views, pose_scale)
    rep.evaluated_views = od.EvaluatedViews(
        frame_indices=[v.frame_index for v in views], width=views[0].rgb.shape[1], height=views[0].rgb.shape[0]
    )


def _heldout_metrics(rendered: list, scale: float | None) -> od.HeldOutReport:
    """The mapped views' image metrics on the held-out renders ((frame, render) pairs)."""
    rep = od.HeldOutReport()
    views = [_View(f.index, r.rgb, r.depth, f.rgb, f.gt_depth) for f, r in rendered]
    if views:
        rep.psnr_db, rep.ssim = _psnr_ssim(views)
        rep.depth_l1_m = _depth_l1(views, scale) if scale is not None else None
        rep.frame_indices = [v.frame_index for v in views]
    return rep


def _load_mesh(path: Path) -> trimesh.Trimesh | None:
    if not path.is_file():
        return None
    try:
        m = trimesh.load(path, force="mesh", process=False)
    except Exception as e:  # trimesh raises many types on corrupt files
        raise UserError(f"cannot read mesh {path} ({e}): delete it or rerun") from None
    return m if isinstance(m, trimesh.Trimesh) and len(m.faces) else None


def evaluate_output_dir(out_dir: str | Path, source: FrameSource, mesh_samples: int = 200_000,
                        progress: Callable[[str], None] | None = None) -> od.EvalReport:
    """Compare OUT's trajectory, renders and mesh with the GT of `source` (iterated once), and
    up to HELDOUT_VIEWS frames the map never saw rendered from scene.pt (eval/heldout.py).
    `progress` gets a line as each step starts (the held-out renders take seconds each)."""
    say = progress or (lambda line: None)
    out = Path(out_dir)
    if not out.is_dir():
        raise UserError(f"output directory {out} not found: give the OUTDIR of a 'nicer-stream run' or 'map'")
    rep = od.EvalReport()
    summary = od.read_summary(out) if (out / od.SUMMARY_FILE).is_file() else None
    if summary is not None:
        rep.priors = list(summary.priors)
    traj = _read_trajectory(out)
    picker = None
    if (traj is not None and summary is not None and summary.intrinsics
            and "mapped_frames" in summary.stats and (out / SCENE_FILE).is_file()):
        picker = HeldOutPicker(traj[0], traj[1], set(summary.stats["mapped_frames"]), HELDOUT_VIEWS)
    renders = _render_paths(out)
    est_mesh = _load_mesh(out / od.MESH_FILE) if traj is not None else None
    gt_mesh_fn = getattr(source, "gt_mesh", None)
    gt_mesh = gt_mesh_fn() if est_mesh is not None and callable(gt_mesh_fn) else None
    builder = reference.ReferenceBuilder() if est_mesh is not None and gt_mesh is None else None

    say("reading the source's ground truth")
    stamps, poses, views, cams = [], [], [], []
    for frame in source:
        stamps.append(frame.timestamp)
        poses.append(frame.gt_pose)
        if picker is not None:
            picker.offer(frame)
        if frame.index in renders:
            v = _load_view(renders[frame.index], frame)
            if v is not None:
                views.append(v)
        if frame.gt_pose is None or frame.gt_depth is None:
            continue
        if builder is not None:
            builder.add(frame.gt_depth, frame.intrinsics, frame.gt_pose)
        if gt_mesh is not None:
            small = resize_frame(frame, SourceOptions(max_side=CULL_MAX_SIDE))
            cams.append(mesh_m.CullCamera(frame.gt_pose, small.intrinsics, small.gt_depth))

    align = None
    if traj is not None:
        est_t, est_T = traj
        j = _match(est_t, np.asarray(stamps, np.float64))
        pairs = [(est_T[i], poses[k]) for i, k in enumerate(j) if poses[k] is not None]
        if pairs:
            align = _trajectory_metrics(rep, np.stack([p[0] for p in pairs]), np.stack([p[1] for p in pairs]))
    scene = align
    if est_mesh is not None and align is not None:
        ref, kind = None, None
        if gt_mesh is not None:
            g = mesh_m.sample_mesh(gt_mesh, mesh_samples, seed=1)
            ref, kind = g.subset(mesh_m.cull_observed(g.points, cams)), "gt_mesh"
        elif builder is not None:
            ref, kind = builder.build(), "gt_depth_points"
        if ref is not None and len(ref.points):
            say(f"mesh against the {'GT mesh' if kind == 'gt_mesh' else 'GT depth points'} ({len(ref.points)} points)")
            est = mesh_m.sample_mesh(est_mesh, mesh_samples, seed=0)  # estimate world
            rep.mesh_pose_aligned = _mesh_report(est, align, ref, kind)
            if ref.normals is not None and registration.pins_similarity(ref.points, ref.normals):
                icp = registration.icp_sim3(est.points, ref.points, align)
                if registration.scale_change_trusted(align, icp):
                    scene, rep.scene_alignment = icp, "icp"
            # Without a trusted registration the scene metrics are the trajectory-aligned ones: no second pass.
            rep.mesh = replace(rep.mesh_pose_aligned) if scene is align else _mesh_report(est, scene, ref, kind)
    if scene is not None:
        rep.scene_scale = scene.scale
        rep.scene_alignment = rep.scene_alignment or "poses"
    _image_metrics(rep, views, None if scene is None else scene.scale, None if align is None else align.scale)
    if picker is not None:
        rendered = render_heldout(out / SCENE_FILE, picker.picked, Intrinsics(**summary.intrinsics), say)
        rep.heldout = _heldout_metrics(rendered, None if scene is None else scene.scale)
    return rep


def _mesh_report(est: mesh_m.SurfaceSamples, a: trajectory.Sim3, ref: mesh_m.SurfaceSamples,
                 kind: str) -> od.MeshReport:
    """Mesh metrics of estimate samples (estimate world) moved into the GT world by `a`."""
    normals = None if est.normals is None else est.normals @ a.R.T
    moved = mesh_m.SurfaceSamples(a.apply_points(est.points), normals)
    return replace(mesh_m.mesh_metrics(moved, ref), reference=kind)
