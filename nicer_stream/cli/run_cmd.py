"""`nicer-stream run`: full SLAM on a source."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli import options as o
from nicer_stream.cli.common import user_errors


@user_errors
def run_command(
    source: str = typer.Option(..., "--source", help=o.SOURCE_HELP),
    out: Path = typer.Option(Path("runs/latest"), "--out", help="Output directory."),
    preset: str = o.PRESET,
    config: str = o.CONFIG,
    priors: str = o.PRIORS,
    flow: str = o.FLOW,
    sink: list[str] = o.SINK,
    max_frames: int = o.MAX_FRAMES,
    stride: int = o.STRIDE,
    start: int = o.START,
    drop: str = o.DROP,
    max_side: int = o.MAX_SIDE,
    intrinsics: str = o.INTRINSICS,
    realtime: bool = typer.Option(False, "--realtime", help="Play the log at its recorded rate, dropping frames SLAM cannot keep up with."),
    device: str = o.DEVICE,
    render_every: int = o.RENDER_EVERY,
    max_renders: int = typer.Option(20, "--max-renders", help="At most N of those, spread evenly (a longer log doubles the stride; 0: no cap)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No per-frame lines or mapping progress: errors and the final summary only."),
    live_mesh_every: int = typer.Option(5, "--live-mesh-every", help="With --sink: a coarse mesh every N map updates while the run goes on (0: only the final mesh)."),
    log_images_every: int = typer.Option(10, "--log-images-every", help="With --sink: the input image of every N-th frame only (every pose is logged); 1: all."),
    log_image_side: int = typer.Option(320, "--log-image-side", help="With --sink: input images downsized to at most PX on the longer side (0: as read)."),
    sync: bool = typer.Option(False, "--sync", help="Everything in one thread, in order (deterministic under a seed)."),
    mapping_worker: str = typer.Option("auto", "--mapping-worker", help="on: mapping on its own thread while tracking goes on; off: inline; auto: on with a GPU or >= 4 cores (on 2 cores it measured 11% slower)."),
) -> None:
    """Track every frame and map keyframes; writes trajectory.tum, mesh.ply, summary.json (+ eval.json with GT)."""
    from nicer_stream.cli.run_report import evaluate_and_print
    from nicer_stream.runtime.slam_run import run_slam

    opts = o.source_options(start=start, stride=stride, drop=drop, max_frames=max_frames, max_side=max_side,
                            intrinsics=intrinsics)
    res = run_slam(o.run_request(source, out, opts, preset=preset, config_file=config, priors=priors,
                                 flow=flow, device=device, sinks=tuple(sink), render_every=render_every,
                                 max_renders=max_renders, realtime=realtime, quiet=quiet,
                                 live_mesh_every=live_mesh_every, log_images_every=log_images_every,
                                 log_image_side=log_image_side, sync=sync, mapping_worker=mapping_worker))
    if res.exit_code:  # stopped or failed: the partial outputs are written; no evaluation
        if res.error:
            typer.echo(f"error: {res.error}", err=True)
        raise typer.Exit(res.exit_code)
    evaluate_and_print(res.out_dir, source, opts)
