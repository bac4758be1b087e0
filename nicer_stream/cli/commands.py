"""Registers every sub-command on the typer app (modules import heavy deps lazily)."""
from __future__ import annotations

import importlib

import typer


def register(app: typer.Typer) -> None:
    def add(name: str, module: str, fn: str) -> None:  # the command function `fn` of nicer_stream.cli.`module`
        app.command(name)(getattr(importlib.import_module(f"nicer_stream.cli.{module}"), fn))

    add("run", "run_cmd", "run_command")
    add("map", "map_cmd", "map_command")

    @app.command("eval")
    def eval_(
        outdir: str = typer.Argument(..., help="Output directory of a run (trajectory.tum, mesh.ply, renders/, summary.json)."),
        source: str = typer.Option(None, "--source", help="Source URI with ground truth, e.g. replica:PATH (default: summary.json's)."),
        max_side: int = typer.Option(None, "--max-side", help="Resize frames so the longer side is at most N pixels."),
        stride: int = typer.Option(1, "--stride", help="Keep every N-th frame (as in the run)."),
        start: int = typer.Option(0, "--start", help="Skip this many frames first (as in the run)."),
        max_frames: int = typer.Option(None, "--max-frames", help="Stop after this many frames (as in the run)."),
        drop: str = typer.Option(None, "--drop", help="A:B drops input frames A..B-1 (as in the run)."),
    ) -> None:
        """Recompute eval.json for an output directory against a source's ground truth and print a table."""
        from pathlib import Path

        from nicer_stream.cli.common import parse_drop, user_errors
        from nicer_stream.cli.eval_cmd import eval_command

        drop_range = user_errors(parse_drop)(drop)
        user_errors(eval_command)(Path(outdir), source, max_side=max_side, stride=stride, start=start,
                                  max_frames=max_frames, drop=drop_range)

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
