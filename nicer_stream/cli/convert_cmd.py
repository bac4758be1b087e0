"""`nicer-stream convert OUTDIR|FILE.rrd --to mcap|rrd [--out FILE]`: replay an output directory
(or a Rerun recording, into MCAP) into a sink.

Reads OUTDIR/trajectory.tum (required), mesh.ply, renders/frame_NNNNNN.npz (rgb, depth,
normal) and summary.json's `intrinsics` {fx, fy, cx, cy, width, height} when present.
A render belongs to the trajectory line with its `timestamp` (so `--stride`, `--drop` and
`--realtime` drops do not shift it); renders written before they carried one fall back to
line = frame index. A pose with a render (and known intrinsics) is logged with its images,
the others as poses only.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import typer

from nicer_stream.errors import UserError
from nicer_stream.io.output_dir import MESH_FILE, RENDERS_DIR, SUMMARY_FILE, TRAJECTORY_FILE
from nicer_stream.io.trajectory import read_tum
from nicer_stream.types import Intrinsics
from sinks import make_sink
from sinks.base import Sink

FORMATS = {"mcap": ".mcap", "rrd": ".rrd"}


@dataclass(frozen=True)
class ConvertResult:
    """What was written: the file, poses, frames with images, mesh size (None: no mesh.ply),
    and renders left out because summary.json gives no intrinsics."""

    out: Path
    poses: int
    images: int
    mesh_vertices: int | None
    mesh_faces: int | None
    renders_without_intrinsics: int = 0


def read_intrinsics(outdir: Path) -> Intrinsics | None:
    """summary.json's `intrinsics` entry, or None when the file or the key is absent."""
    path = outdir / SUMMARY_FILE
    if not path.is_file():
        return None
    try:
        entry = json.loads(path.read_text()).get("intrinsics")
        if entry is None:
            return None
        return Intrinsics(float(entry["fx"]), float(entry["fy"]), float(entry["cx"]), float(entry["cy"]),
                          int(entry["width"]), int(entry["height"]))
    except (json.JSONDecodeError, AttributeError, KeyError, TypeError, ValueError) as e:
        raise UserError(f"{path}: unreadable 'intrinsics' entry ({e}): it needs fx, fy, cx, cy, width, height") from None


def _resolve_out(outdir: Path, to: str, out: Path | None, force: bool) -> Path:
    if to not in FORMATS:
        raise UserError(f"--to must be one of {', '.join(FORMATS)}, got '{to}'")
    out = out if out is not None else outdir / f"recording{FORMATS[to]}"
    if out.suffix != FORMATS[to]:
        raise UserError(f"--out {out} must end in {FORMATS[to]} for --to {to}")
    if out.exists() and not force:
        raise UserError(f"{out} already exists: pass --force to overwrite it or choose another --out")
    return out


def _load_render(path: Path) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """renders/frame_NNNNNN.npz -> rgb (H, W, 3), depth (H, W) or None, normal (H, W, 3) or None."""
    try:
        with np.load(path) as z:
            rgb = z["rgb"]
            return rgb, z["depth"] if "depth" in z else None, z["normal"] if "normal" in z else None
    except (OSError, ValueError, KeyError) as e:
        raise UserError(f"{path}: unreadable render ({e}): it needs an 'rgb' array; delete or rewrite it") from None


def renders_by_line(outdir: Path, times: np.ndarray) -> dict[int, tuple[int, Path]]:
    """{trajectory line: (frame index, render path)}, matched by timestamp (to 1 us, the
    precision trajectory.tum is written with); older renders without one by line = frame index."""
    found: dict[int, tuple[int, Path]] = {}
    d = outdir / RENDERS_DIR
    for path in sorted(d.glob("frame_*.npz")) if d.is_dir() else []:
        try:
            with np.load(path) as z:
                index = int(z["frame_index"]) if "frame_index" in z else int(path.stem.split("_")[1])
                t = float(z["timestamp"]) if "timestamp" in z else None
        except (OSError, ValueError, KeyError) as e:
            raise UserError(f"{path}: unreadable render ({e}): delete or rewrite it") from None
        if t is None:
            line = index if index < len(times) else None
        else:
            j = int(np.argmin(np.abs(times - t))) if len(times) else 0
            line = j if len(times) and abs(times[j] - t) < 1e-6 else None
        if line is not None:
            found[line] = (index, path)
    return found


def _log_frames(sink: Sink, outdir: Path, times: np.ndarray, poses: np.ndarray, intr: Intrinsics | None) -> int:
    """Log every pose, with its render when there is one; returns the number of frames with images."""
    images = 0
    renders = renders_by_line(outdir, times) if intr is not None else {}
    for i, (t, T) in enumerate(zip(times, poses)):
        if i not in renders:
            sink.log_pose(i, float(t), T)
            continue
        index, render = renders[i]
        rgb, depth, normal = _load_render(render)
        h, w = rgb.shape[:2]
        frame_intr = intr if (intr.width, intr.height) == (w, h) else intr.resized(w, h)
        sink.log_frame(i, float(t), rgb, frame_intr, T, depth=depth, normal=normal)
        images += 1
    return images


def _load_mesh(path: Path):
    """mesh.ply -> (vertices (V, 3), faces (F, 3), vertex colours (V, 3|4) uint8 or None)."""
    import trimesh

    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as e:  # trimesh raises many types on corrupt files
        raise UserError(f"{path}: unreadable mesh ({e}): delete or rewrite it") from None
    colors = None
    if getattr(mesh.visual, "kind", None) == "vertex":
        colors = np.asarray(mesh.visual.vertex_colors)[:, :3]
    return np.asarray(mesh.vertices), np.asarray(mesh.faces), colors


def convert_outputs(outdir: Path, to: str = "mcap", out: Path | None = None, force: bool = False) -> ConvertResult:
    """Replay OUTDIR into a new .mcap or .rrd file; see the module docstring."""
    outdir = Path(outdir)
    if not outdir.is_dir():
        raise UserError(f"{outdir} is not a directory: point at an output directory written by 'nicer-stream run'")
    traj = outdir / TRAJECTORY_FILE
    if not traj.is_file():
        raise UserError(f"no {TRAJECTORY_FILE} in {outdir}: point at an output directory written by 'nicer-stream run'")
    times, poses = read_tum(traj, "fix or rewrite the trajectory file")
    out = _resolve_out(outdir, to, out, force)
    intr = read_intrinsics(outdir)
    mesh_path = outdir / MESH_FILE
    mesh = _load_mesh(mesh_path) if mesh_path.is_file() else None
    with make_sink(f"{'rerun' if to == 'rrd' else 'mcap'}:{out}") as sink:
        images = _log_frames(sink, outdir, times, poses, intr)
        sink.log_trajectory(poses[:, :3, 3], "estimate", rotations=poses[:, :3, :3])
        if mesh is not None:
            sink.log_mesh(*mesh)
    n_renders = len(list((outdir / RENDERS_DIR).glob("frame_*.npz"))) if (outdir / RENDERS_DIR).is_dir() else 0
    return ConvertResult(out, len(poses), images, None if mesh is None else len(mesh[0]),
                         None if mesh is None else len(mesh[1]), n_renders if intr is None else 0)


def _rrd_poses(cols: dict, entity: str = "/world/camera") -> tuple[list[int], list[int | None], np.ndarray]:
    """An entity's Transform3D rows -> frame indices, sensor times (ns, or None), poses (N, 4, 4)."""
    import torch

    from nicer_stream.geometry.se3 import quat_to_matrix

    cam = cols.get(entity, {})
    trans, quats = cam.get("Transform3D:translation", []), cam.get("Transform3D:quaternion", [])
    frames = cam.get("frame", [None] * len(trans))
    times = cam.get("sensor_time", [None] * len(trans))
    poses = np.tile(np.eye(4), (len(trans), 1, 1))
    for k, (t, q) in enumerate(zip(trans, quats)):
        poses[k, :3, 3] = t[0]
        poses[k, :3, :3] = quat_to_matrix(torch.tensor(q[0], dtype=torch.float64)).numpy()
    return [int(f) if f is not None else k for k, f in enumerate(frames)], times, poses


def convert_rrd(path: Path, out: Path | None = None, force: bool = False) -> ConvertResult:
    """A Rerun recording written by the run's sink -> MCAP: every camera pose (with the ground
    truth pose where it was logged), the estimated trajectory and the last mesh."""
    from sinks.readback import read_rrd_columns

    out = _resolve_out(path.parent, "mcap", out if out is not None else path.with_suffix(".mcap"), force)
    try:
        cols = read_rrd_columns(path)
    except (RuntimeError, ValueError, OSError) as e:
        raise UserError(f"cannot read {path} as a Rerun recording ({str(e).splitlines()[0]}): "
                        "is it a .rrd written by nicer-stream?") from None
    frames, times, poses = _rrd_poses(cols)
    if not len(poses):
        raise UserError(f"{path} has no /world/camera poses: is it a recording of a nicer-stream run?")
    gt_frames, _, gt_poses = _rrd_poses(cols, "/world/camera_gt")
    gt = dict(zip(gt_frames, gt_poses))
    mesh_rows = cols.get("/world/mesh", {})
    with make_sink(f"mcap:{out}") as sink:
        for f, ns, T in zip(frames, times, poses):
            sink.log_pose(f, 0.0 if ns is None else ns / 1e9, T, gt_T_world_cam=gt.get(f), timestamp_ns=ns)
        sink.log_trajectory(poses[:, :3, 3], "estimate", rotations=poses[:, :3, :3])
        verts = mesh_rows.get("Mesh3D:vertex_positions", [])
        if verts:
            faces = np.asarray(mesh_rows["Mesh3D:triangle_indices"][-1], dtype=np.int64).reshape(-1, 3)
            sink.log_mesh(np.asarray(verts[-1], dtype=np.float64), faces)
    return ConvertResult(out, len(poses), 0, len(verts[-1]) if verts else None, len(faces) if verts else None)


def convert_command(outdir: Path, to: str, out: Path | None, force: bool) -> None:
    """CLI entry: convert and print one summary line."""
    if outdir.suffix == ".rrd" and outdir.is_file():
        if to != "mcap":
            raise UserError(f"{outdir} is already a Rerun recording: convert it --to mcap")
        r = convert_rrd(outdir, out, force)
    else:
        r = convert_outputs(outdir, to, out, force)
    mesh = "no mesh" if r.mesh_faces is None else f"mesh {r.mesh_vertices} vertices / {r.mesh_faces} faces"
    typer.echo(f"wrote {r.out}: {r.poses} poses, {r.images} frames with images, {mesh}")
    if r.renders_without_intrinsics:
        typer.echo(f"note: {r.renders_without_intrinsics} renders left out: {SUMMARY_FILE} has no 'intrinsics' entry",
                   err=True)
