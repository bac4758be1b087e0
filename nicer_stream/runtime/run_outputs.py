"""Writing the output-directory contract (docs: nicer_stream/io/output_dir.py)."""
from __future__ import annotations

import logging
from importlib import metadata
from pathlib import Path

import numpy as np
import trimesh

from nicer_stream.io import output_dir as od
from nicer_stream.io.trajectory import write_tum
from nicer_stream.mesh import write_ply
from nicer_stream.model.bound import SceneBound
from nicer_stream.runtime.stage_timer import StageTimer, peak_rss_mb

log = logging.getLogger(__name__)


def package_versions() -> dict[str, str]:
    out = {}
    for name in ("nicer-stream", "torch", "numpy", "rerun-sdk", "mcap", "opencv-python-headless", "trimesh", "scikit-image"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = "missing"
    return out


def write_trajectory(out_dir: Path, timestamps: list[float], poses: list[np.ndarray]) -> None:
    """trajectory.tum, one line per frame with a pose (only its header when none has one yet);
    NaN poses are refused by write_tum."""
    write_tum(Path(out_dir) / od.TRAJECTORY_FILE, np.asarray(timestamps, dtype=np.float64),
              np.stack(poses) if poses else np.zeros((0, 4, 4)))


def write_mesh(out_dir: Path, mesh: trimesh.Trimesh | None) -> None:
    if mesh is not None and len(mesh.faces):
        write_ply(mesh, Path(out_dir) / od.MESH_FILE)
    else:
        log.warning("no surface was reconstructed: mesh.ply not written")


def write_summary(out_dir: Path, *, frames: int, preset: str, device: str, priors: list[str], timer: StageTimer,
                  interrupted: bool, error: str | None = None, bound: SceneBound | None, source: str, notes: list[str], intrinsics: dict | None,
                  config: dict | None, stats: dict) -> od.Summary:
    wall = timer.total()
    s = od.Summary(
        frames=frames, preset=preset, device=device, priors=priors, wall_s=wall, stages_s=timer.seconds,
        seconds_per_frame=wall / max(frames, 1), peak_rss_mb=peak_rss_mb(), versions=package_versions(),
        interrupted=interrupted, error=error, bound=od.Bound(**bound.to_dict()) if bound else None, notes=notes, source=source,
        intrinsics=intrinsics, config=config, stats=stats,
    )
    od.write_summary(out_dir, s)
    return s
