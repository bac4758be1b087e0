"""`nicer-stream render OUT_DIR`: novel views of a finished run (runtime/render_views.py)."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli.common import user_errors
from nicer_stream.errors import UserError


@user_errors
def render_command(
    outdir: Path = typer.Argument(..., help="Output directory of a run (scene.pt, summary.json, trajectory.tum)."),
    poses: Path = typer.Option(None, "--poses", help="TUM file of camera poses (T_world_cam) in the run's world frame."),
    frames: bool = typer.Option(False, "--frames", help="The run's tracked poses (the default path)."),
    orbit: int = typer.Option(None, "--orbit", help="N views on a circle around the centre of the mapped space, at the cameras' height."),
    interpolate_n: int = typer.Option(None, "--interpolate", help="N poses between consecutive keyframes (SE(3) geodesic)."),
    arc: float = typer.Option(360.0, "--arc", help="With --orbit: sweep only this many degrees, from the first camera towards the last (a partial scan seen from where it was filmed)."),
    scale: float = typer.Option(1.0, "--scale", help="Image size relative to the run's."),
    out: Path = typer.Option(None, "--out", help="Directory for the views (default OUT_DIR/views)."),
    fps: float = typer.Option(10.0, "--fps", help="Frame rate of the .mp4."),
    sink: list[str] = typer.Option([], "--sink", help="Also log the views: rerun:FILE.rrd, mcap:FILE.mcap, rerun; repeatable."),
    device: str = typer.Option("cpu", "--device", help="torch device, e.g. cpu or cuda."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No per-view lines."),
) -> None:
    """Render RGB, depth and normals of a finished run along a camera path: PNGs, an .mp4, the path as TUM."""
    from nicer_stream.runtime.render_views import VIDEO_FILE, ViewRequest, render_views

    chosen = [name for name, on in (("poses", poses is not None), ("frames", frames), ("orbit", orbit is not None),
                                    ("interpolate", interpolate_n is not None)) if on]
    if len(chosen) > 1:
        raise UserError(f"choose one camera path, got {', '.join('--' + c for c in chosen)}")
    if scale <= 0 or fps <= 0 or arc <= 0:
        raise UserError("--scale, --fps and --arc must be positive")
    path = chosen[0] if chosen else "frames"
    n = orbit if path == "orbit" else (interpolate_n if path == "interpolate" else 0)
    dest, written = render_views(ViewRequest(out_dir=outdir, path=path, poses_file=poses, n=n or 0, arc_deg=arc, scale=scale,
                                             dest=out, fps=fps, sinks=tuple(sink), device=device, quiet=quiet))
    typer.echo(f"{written} views in {dest} ({VIDEO_FILE}, view_NNNNN.png: render | depth | normals, view_NNNNN.npz, poses.tum)")
