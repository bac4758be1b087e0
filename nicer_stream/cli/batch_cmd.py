"""`nicer-stream batch SOURCES... --out ROOT`: many logs, one Ray task each (runtime/batch_run.py)."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli import options as o
from nicer_stream.cli.common import user_errors
from nicer_stream.errors import UserError


@user_errors
def batch_command(
    sources: list[str] = typer.Argument(..., help="Source URIs, globs in a URI's path (mcap:logs/*.mcap) or text files of URIs (.txt)."),
    out: Path = typer.Option(..., "--out", help="Root directory: ROOT/<name>/ per source, ROOT/batch.json."),
    preset: str = o.PRESET,
    config: str = typer.Option(None, "--config", help="A .toml/.json file overriding preset fields, for every run."),
    priors: str = o.PRIORS,
    flow: str = o.FLOW,
    sink: list[str] = typer.Option([], "--sink", help="rerun:FILE.rrd, mcap:FILE.mcap; repeatable. Each source writes FILE in its own ROOT/<name>/."),
    max_frames: int = o.MAX_FRAMES,
    max_side: int = o.MAX_SIDE,
    stride: int = o.STRIDE,
    start: int = o.START,
    drop: str = o.DROP,
    intrinsics: str = o.INTRINSICS,
    render_every: int = o.RENDER_EVERY,
    local: bool = typer.Option(False, "--local", help="Run the sources one after another in this process (no Ray)."),
    address: str = typer.Option(None, "--address", help="Join a Ray cluster: auto or ray://HOST:PORT (default: a local instance)."),
    cpus_per_run: float = typer.Option(1.0, "--cpus-per-run", help="CPUs each run asks Ray for (its torch threads), > 0."),
    gpus_per_run: float = typer.Option(0.0, "--gpus-per-run", help="GPUs each run asks for, >= 0 (> 0: the run uses cuda)."),
    retries: int = typer.Option(1, "--retries", help="Retries of a source whose worker process died, >= 0."),
    force: bool = typer.Option(False, "--force", help="Redo sources whose outputs are complete."),
    no_eval: bool = typer.Option(False, "--no-eval", help="Skip evaluation against ground truth."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="No line per finished source: the final table only."),
) -> None:
    """Run SLAM on many sources (Ray: local by default, a cluster with --address); a table and ROOT/batch.json summarise them."""
    import importlib.util

    from nicer_stream.runtime.batch_plan import RunOptions, expand_sources, plan, table
    from nicer_stream.runtime.batch_run import RAY_HINT, BatchRequest, run_batch

    if not cpus_per_run > 0:
        raise UserError(f"--cpus-per-run must be > 0, got {cpus_per_run}")
    o.at_least("--gpus-per-run", gpus_per_run, 0)
    o.at_least("--retries", retries, 0)
    opts = o.source_options(start=start, stride=stride, drop=drop, max_frames=max_frames, max_side=max_side,
                            intrinsics=intrinsics)
    request = o.run_request("", Path(), opts, preset=preset, config_file=config, priors=priors, flow=flow,
                            sinks=tuple(sink), render_every=render_every)
    items = plan(expand_sources(list(sources)))
    if not local and importlib.util.find_spec("ray") is None:
        typer.echo(f"{RAY_HINT}; running sequentially (--local)", err=True)
        local = True
    rep = run_batch(BatchRequest(tuple(items), out, RunOptions(request, evaluate=not no_eval), local=local,
                                 address=address, cpus_per_run=cpus_per_run, gpus_per_run=gpus_per_run,
                                 retries=retries, force=force, quiet=quiet))
    typer.echo(table(rep.sources))
    failed = sum(r.status == "failed" for r in rep.sources)
    typer.echo(f"{len(rep.sources)} sources in {rep.wall_s:.0f} s ({failed} failed){'; interrupted' if rep.interrupted else ''}; "
               f"{Path(rep.root) / 'batch.json'}")
    if rep.interrupted:
        raise typer.Exit(130)
    if failed:
        raise typer.Exit(1)
