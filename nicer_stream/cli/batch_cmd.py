"""`nicer-stream batch SOURCES... --out ROOT`: many logs, one Ray task each (runtime/batch_run.py)."""
from __future__ import annotations

from pathlib import Path

import typer

from nicer_stream.cli.common import user_errors


def batch_command(
    sources: list[str] = typer.Argument(..., help="Source URIs, globs in a URI's path (mcap:logs/*.mcap) or text files of URIs (.txt)."),
    out: Path = typer.Option(..., "--out", help="Root directory: ROOT/<name>/ per source, ROOT/batch.json."),
    preset: str = typer.Option("fast", "--preset"),
    config: str = typer.Option(None, "--config", help="TOML overrides for every run."),
    priors: str = typer.Option("auto", "--priors"),
    flow: str = typer.Option(None, "--flow"),
    max_frames: int = typer.Option(None, "--max-frames"),
    max_side: int = typer.Option(None, "--max-side"),
    stride: int = typer.Option(1, "--stride"),
    local: bool = typer.Option(False, "--local", help="Run the sources one after another in this process (no Ray)."),
    address: str = typer.Option(None, "--address", help="Join a Ray cluster: auto or ray://HOST:PORT (default: a local instance)."),
    cpus_per_run: float = typer.Option(1.0, "--cpus-per-run", help="CPUs each run asks Ray for (its torch threads)."),
    gpus_per_run: float = typer.Option(0.0, "--gpus-per-run", help="GPUs each run asks for (> 0: the run uses cuda)."),
    retries: int = typer.Option(1, "--retries", help="Retries of a source whose worker process died."),
    force: bool = typer.Option(False, "--force", help="Redo sources whose outputs are complete."),
    no_eval: bool = typer.Option(False, "--no-eval", help="Skip evaluation against ground truth."),
    quiet: bool = typer.Option(False, "--quiet", "-q"),
) -> None:
    """Run SLAM on many sources (Ray: local by default, a cluster with --address); a table and ROOT/batch.json summarise them."""
    user_errors(_batch)(sources, out, preset, config, priors, flow, max_frames, max_side, stride, local, address,
                        cpus_per_run, gpus_per_run, retries, force, no_eval, quiet)


def _batch(sources, out, preset, config, priors, flow, max_frames, max_side, stride, local, address, cpus_per_run,
           gpus_per_run, retries, force, no_eval, quiet) -> None:
    import importlib.util

    from nicer_stream.runtime.batch_plan import RunOptions, expand_sources, plan, table
    from nicer_stream.runtime.batch_run import RAY_HINT, BatchRequest, run_batch

    items = plan(expand_sources(list(sources)))
    if not local and importlib.util.find_spec("ray") is None:
        typer.echo(f"{RAY_HINT}; running sequentially (--local)", err=True)
        local = True
    opts = RunOptions(preset=preset, priors=priors, flow=flow, config_file=config, max_frames=max_frames,
                      max_side=max_side, stride=stride, evaluate=not no_eval)
    rep = run_batch(BatchRequest(tuple(items), out, opts, local=local, address=address, cpus_per_run=cpus_per_run,
                                 gpus_per_run=gpus_per_run, retries=retries, force=force, quiet=quiet))
    typer.echo(table(rep.sources))
    failed = sum(r.status == "failed" for r in rep.sources)
    typer.echo(f"{len(rep.sources)} sources in {rep.wall_s:.0f} s ({failed} failed){'; interrupted' if rep.interrupted else ''}; "
               f"{Path(rep.root) / 'batch.json'}")
    if rep.interrupted:
        raise typer.Exit(130)
    if failed:
        raise typer.Exit(1)
