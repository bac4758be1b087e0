"""Registers every sub-command on the typer app (modules import heavy deps lazily)."""
from __future__ import annotations

import importlib

import typer


def register(app: typer.Typer) -> None:
    def add(name: str, module: str, fn: str) -> None:  # the command function `fn` of nicer_stream.cli.`module`
        app.command(name)(getattr(importlib.import_module(f"nicer_stream.cli.{module}"), fn))

    add("run", "run_cmd", "run_command")
    add("map", "map_cmd", "map_command")
    add("eval", "eval_cmd", "eval_cli")
    add("batch", "batch_cmd", "batch_command")
    add("render", "render_cmd", "render_command")
    add("priors", "priors_cmd", "priors")

    @app.command("convert")
    def convert(
        outdir: str = typer.Argument(..., help="Output directory of a run (trajectory.tum, mesh.ply, renders/, summary.json), or a run's .rrd recording (to MCAP)."),
        to: str = typer.Option("mcap", "--to", help="Output format: mcap or rrd."),
        out: str = typer.Option(None, "--out", help="Output file (default OUTDIR/recording.mcap or .rrd)."),
        force: bool = typer.Option(False, "--force", help="Overwrite an existing output file."),
    ) -> None:
        """Convert an output directory to an MCAP (Foxglove) or Rerun recording, or a run's .rrd to MCAP."""
        from pathlib import Path

        from nicer_stream.cli.common import user_errors
        from nicer_stream.cli.convert_cmd import convert_command

        user_errors(convert_command)(Path(outdir), to, Path(out) if out else None, force)

    add("inspect", "inspect_cmd", "inspect_command")
