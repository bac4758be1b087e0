"""`nicer-stream run`: full SLAM on a source."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli.common import DROP_HELP, parse_drop, parse_intrinsics, user_errors
from nicer_stream.errors import UserError


def run_command(
    source: str = typer.Option("synthetic:room?frames=60", "--source", help="Source URI: replica:PATH, tum:PATH, 7scenes:PATH, folder:PATH, video:FILE, mcap:FILE[?topic=T], synthetic:NAME."),
    out: Path = typer.Option(Path("runs/latest"), "--out", help="Output directory."),
    preset: str = typer.Option("fast", "--preset", help="fast (2-core CPU) or paper."),
    config: str = typer.Option(None, "--config", help="A .toml/.json file overriding preset fields."),
    priors: str = typer.Option("auto", "--priors", help="Depth/normal priors: auto (learned weights if present, else stereo), stereo, none, oracle (GT with a monocular network's errors, evaluation only), oracle:clean (near GT, debugging), cache:DIR, omnidata, depth-anything."),
    flow: str = typer.Option(None, "--flow", help="Flow prior: dis, oracle, none, cache:DIR (default: oracle with oracle:clean priors, else dis)."),
    sink: list[str] = typer.Option([], "--sink", help="rerun (viewer), rerun:FILE.rrd, mcap:FILE.mcap; repeatable. A bare 'rerun' with no viewer writes OUT/recording.rrd."),
    max_frames: int = typer.Option(None, "--max-frames"),
    stride: int = typer.Option(1, "--stride"),
    start: int = typer.Option(0, "--start"),
    drop: str = typer.Option(None, "--drop", help=DROP_HELP),
    max_side: int = typer.Option(None, "--max-side", help="Resize so the longer side is at most N pixels (default: preset)."),
    intrinsics: str = typer.Option(None, "--intrinsics", help="fx,fy,cx,cy at the original image size."),
    realtime: bool = typer.Option(False, "--realtime", help="Play the log at its recorded rate, dropping frames SLAM cannot keep up with."),
    device: str = typer.Option("cpu", "--device", help="torch device, e.g. cpu or cuda."),
    render_every: int = typer.Option(10, "--render-every", help="Render (and evaluate) every N-th frame at the end; their images are kept until then."),
    max_renders: int = typer.Option(20, "--max-renders", help="At most N of those, spread evenly (a longer log doubles the stride; 0: no cap)."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No per-frame lines or mapping progress: errors and the final summary only."),
    live_mesh_every: int = typer.Option(5, "--live-mesh-every", help="With --sink: a coarse mesh every N map updates while the run goes on (0: only the final mesh)."),
    log_images_every: int = typer.Option(10, "--log-images-every", help="With --sink: the input image of every N-th frame only (every pose is logged); 1: all."),
    log_image_side: int = typer.Option(320, "--log-image-side", help="With --sink: input images downsized to at most PX on the longer side (0: as read)."),
    sync: bool = typer.Option(False, "--sync", help="Everything in one thread, in order (deterministic under a seed)."),
    mapping_worker: str = typer.Option("auto", "--mapping-worker", help="on: mapping on its own thread while tracking goes on; off: inline; auto: on with a GPU or >= 4 cores (on 2 cores it measured 11% slower)."),
) -> None:
    """Track every frame and map keyframes; writes trajectory.tum, mesh.ply, summary.json (+ eval.json with GT)."""
    user_errors(_run)(source, out, preset, config, priors, flow, sink, max_frames, stride, start, drop, max_side, intrinsics,
                      realtime, device, render_every, max_renders, live_mesh_every, quiet, sync, mapping_worker,
                      log_images_every, log_image_side)


def _resolve_sinks(sinks: list[str], out: Path, images_every: int = 1, image_side: int = 0) -> tuple[str, ...]:
    """A bare 'rerun' becomes a file in OUT when no viewer can be spawned (headless); each spec
    without a query of its own gets the image stride and size (sinks/options.py)."""
    import os
    import shutil

    from sinks.options import SinkOptions

    query = SinkOptions(images_every, image_side or None).query()
    res = []
    for s in sinks:
        if s == "rerun" and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) and not shutil.which("rerun-viewer"):
            s = f"rerun:{out / 'recording.rrd'}"
            typer.echo(f"no display for a Rerun viewer: recording to {s[6:]}", err=True)
        res.append(s if "?" in s else ",".join(p + query for p in s.split(",") if p.strip()))
    return tuple(res)


def _run(source, out, preset, config, priors, flow, sinks, max_frames, stride, start, drop, max_side, intrinsics, realtime,
         device, render_every, max_renders, live_mesh_every, quiet, sync, mapping_worker, log_images_every,
         log_image_side) -> None:
    from nicer_stream.cli.run_report import evaluate_and_print
    from nicer_stream.runtime.slam_run import RunRequest, run_slam
    from sources.base import SourceOptions

    if render_every < 1 or max_renders < 0:
        raise UserError(f"--render-every must be at least 1 and --max-renders at least 0 (0: no cap), "
                        f"got {render_every} and {max_renders}")
    opts = SourceOptions(start=start, stride=stride, drop=parse_drop(drop), max_frames=max_frames, max_side=max_side,
                         intrinsics=parse_intrinsics(intrinsics))
    res = run_slam(RunRequest(source=source, out_dir=out, priors=priors, flow=flow, preset=preset, config_file=config,
                              sinks=_resolve_sinks(sinks, out, log_images_every, log_image_side), device=device, realtime=realtime,
                              render_every=render_every, max_renders=max_renders, live_mesh_every=live_mesh_every, quiet=quiet, sync=sync, mapping_worker=mapping_worker,
                              source_opts=opts))
    if res.exit_code:  # stopped or failed: the partial outputs are written; no evaluation
        if res.error:
            typer.echo(f"error: {res.error}", err=True)
        raise typer.Exit(res.exit_code)
    evaluate_and_print(res.out_dir, source, opts)
