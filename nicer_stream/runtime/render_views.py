"""`nicer-stream render OUT_DIR`: novel views of a finished run. Loads the saved scene
(scene.pt), renders RGB, z-depth and normals along a camera path in the run's world frame
(the tracked poses, a TUM file, an orbit around the map's centre, or an interpolation between
keyframes), and writes per view a PNG (render | depth | normals) and an .npz (rgb, z-depth,
camera-frame normals, pose), an .mp4 and the path as TUM (+ sinks). A stop (Ctrl-C,
SIGTERM) keeps the views rendered so far, the video included."""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import torch

from nicer_stream.errors import UserError
from nicer_stream.geometry.camera_paths import interpolate, orbit
from nicer_stream.io import output_dir as od
from nicer_stream.io.scene_file import SCENE_FILE, load_scene
from nicer_stream.io.trajectory import read_tum, write_tum
from nicer_stream.render.renderer import render_image
from nicer_stream.runtime.scene_export import render_tile
from nicer_stream.runtime.stop import StopSignals
from nicer_stream.types import Intrinsics
from sinks import make_sink

PATHS = ("frames", "poses", "orbit", "interpolate")
VIDEO_FILE = "views.mp4"


@dataclass(frozen=True)
class ViewRequest:
    """What `nicer-stream render` was asked to do."""

    out_dir: Path
    """The run's output directory (scene.pt, summary.json, trajectory.tum)."""
    path: str = "frames"
    """One of PATHS: the tracked poses, `poses_file`, an orbit around the centre of the observed
    space (`observed_centre`), or poses between keyframes."""
    poses_file: Path | None = None
    """TUM file of T_world_cam in the run's world frame (path 'poses')."""
    n: int = 60
    """Views on the orbit; poses inserted between consecutive keyframes ('interpolate')."""
    arc_deg: float = 360.0
    """The orbit's sweep (< 360: from the first camera towards the last; partial scans)."""
    scale: float = 1.0
    """Image size relative to the run's."""
    dest: Path | None = None
    """Where the views go (default OUT_DIR/views)."""
    fps: float = 10.0
    sinks: tuple[str, ...] = ()
    device: str = "cpu"
    quiet: bool = False


def camera_path(req: ViewRequest, summary: od.Summary, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(timestamps (N,), T_world_cam (N, 4, 4)) of the requested path."""
    if req.path not in PATHS:
        raise UserError(f"unknown camera path {req.path!r}: use one of {', '.join(PATHS)}")
    if req.path == "poses":
        if req.poses_file is None or not Path(req.poses_file).is_file():
            raise UserError(f"poses file {req.poses_file} not found: give a TUM trajectory in the run's world frame")
        return read_tum(req.poses_file, "fix the TUM file")
    traj = Path(req.out_dir) / od.TRAJECTORY_FILE
    if not traj.is_file():
        raise UserError(f"{traj} not found: the run wrote no trajectory; use --poses FILE.tum")
    t, T = read_tum(traj, "fix the TUM file")
    if len(T) == 0:
        raise UserError(f"{traj} is empty: the run stopped before its first pose; use --poses FILE.tum")
    if req.path == "frames":
        return t, T
    if req.n < 1:
        raise UserError(f"--orbit / --interpolate need a count >= 1, got {req.n}")
    if req.path == "orbit":
        return np.arange(req.n) / req.fps, orbit(T, req.n, centre=centre, arc_deg=req.arc_deg)
    keys = _keyframe_rows(summary, len(T))
    path = interpolate(T[keys], req.n)
    return np.arange(len(path)) / req.fps, path


def observed_centre(model, beta) -> np.ndarray:
    """(3,) world: the centroid of the space the mapping samples visited, weighted by their counts
    (the beta field's counter); the scene bound's centre before any mapping. The middle of what
    was seen, not of the bounding box, which a partial scan fills only in part."""
    counts = beta.counts.double()
    if not bool((counts > 0).any()):
        return np.asarray(model.bound.centre, np.float64)
    centres, _ = beta.voxel_betas()
    w = counts[counts > 0]
    mean = (centres.double() * w[:, None]).sum(0) / w.sum()
    return model.bound.denormalise(mean[None].float()).double().numpy()[0]


def _keyframe_rows(summary: od.Summary, n_rows: int) -> list[int]:
    """Rows of trajectory.tum that are keyframes (summary's frame and keyframe indices; every
    `mapping.keyframe_every`-th row for runs that did not record them)."""
    order, kfs = summary.stats.get("frame_indices"), summary.stats.get("keyframe_indices")
    if order and kfs and len(order) == n_rows:
        pos = {f: r for r, f in enumerate(order)}
        rows = sorted(pos[k] for k in kfs if k in pos)
    else:
        every = int((summary.config or {}).get("mapping", {}).get("keyframe_every", 5))
        rows = list(range(0, n_rows, max(every, 1)))
    if rows[-1] != n_rows - 1:
        rows.append(n_rows - 1)
    return rows


def render_views(req: ViewRequest) -> tuple[Path, int]:
    """Render the path; returns (the views' directory, views written)."""
    out = Path(req.out_dir)
    if not (out / SCENE_FILE).is_file():
        raise UserError(f"{out / SCENE_FILE} not found: render needs the output directory of a 'nicer-stream run' or 'map'")
    summary = od.read_summary(out)
    if not summary.intrinsics:
        raise UserError(f"{out / od.SUMMARY_FILE} has no intrinsics: rerun to record them")
    cfg, model, beta = load_scene(out / SCENE_FILE, req.device)
    intr = Intrinsics(**summary.intrinsics).scaled(req.scale) if req.scale != 1.0 else Intrinsics(**summary.intrinsics)
    times, poses = camera_path(req, summary, observed_centre(model, beta))
    dest = Path(req.dest) if req.dest else out / "views"
    dest.mkdir(parents=True, exist_ok=True)
    write_tum(dest / "poses.tum", times, poses)
    sink = make_sink(list(req.sinks)) if req.sinks else None
    video, written, t0 = None, 0, time.perf_counter()
    say = (lambda s: None) if req.quiet else (lambda s: print(s, flush=True))
    say(f"rendering {len(poses)} views ({req.path}) at {intr.width}x{intr.height} from {out / SCENE_FILE} into {dest}")
    try:
        with StopSignals() as stop:
            for i, (t, T) in enumerate(zip(times, poses)):
                if stop.requested:
                    say(f"stopped by {stop.reason}: {written} views kept")
                    break
                view = render_image(model, beta, torch.as_tensor(T, dtype=torch.float32, device=req.device), intr, cfg.render)
                tile = render_tile(view)
                cv2.imwrite(str(dest / f"view_{i:05d}.png"), tile)
                np.savez_compressed(dest / f"view_{i:05d}.npz", rgb=view.rgb, depth=view.depth, normal=view.normal,
                                    T_world_cam=np.asarray(T, np.float64), timestamp=np.float64(t))
                if video is None:
                    video = _open_video(dest / VIDEO_FILE, req.fps, tile.shape[1], tile.shape[0])
                video.write(tile)
                if sink is not None:
                    sink.log_frame(i, float(t), view.rgb, intr, T, depth=view.depth, normal=view.normal)
                written += 1
                el = time.perf_counter() - t0
                say(f"view {i + 1}/{len(poses)}  {el / written:.1f} s/view  eta {el / written * (len(poses) - written):.0f} s")
    finally:
        if video is not None:
            video.release()
        if sink is not None:
            sink.close()
    return dest, written


def _open_video(path: Path, fps: float, width: int, height: int) -> cv2.VideoWriter:
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height))
    if not w.isOpened():
        raise UserError(f"OpenCV cannot write {path} (no mp4v encoder): the PNGs are written")
    return w
