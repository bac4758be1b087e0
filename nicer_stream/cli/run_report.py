"""After a run: evaluate against ground truth when the source has it, print the table."""
from __future__ import annotations

from pathlib import Path

import typer

from sources.base import SourceOptions


def evaluate_and_print(out_dir: Path, source: str, opts: SourceOptions) -> None:
    """Write eval.json and print the metrics table if `source` carries GT poses."""
    from nicer_stream.cli.eval_cmd import eval_command
    from sources import open_source

    if not open_source(source, opts).has_gt_pose:
        typer.echo(f"outputs in {out_dir} (the source has no ground truth: no eval.json)")
        return
    eval_command(Path(out_dir), source, stride=opts.stride, start=opts.start, max_frames=opts.max_frames,
                 drop=opts.drop)
