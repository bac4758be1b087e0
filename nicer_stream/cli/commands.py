"""Registers every sub-command on the typer app (modules import heavy deps lazily)."""
from __future__ import annotations

import typer

from nicer_stream.cli.common import not_built


def register(app: typer.Typer) -> None:
    @app.command("run")
    def run() -> None:
        """Full SLAM on a source: trajectory, mesh, recording (issue #4)."""
        not_built("run", 4)

    @app.command("map")
    def map_() -> None:
        """Mapping with known poses (issue #3)."""
        not_built("map", 3)

    @app.command("eval")
    def eval_() -> None:
        """Recompute eval.json for an output directory (issue #2)."""
        not_built("eval", 2)

    @app.command("priors")
    def priors() -> None:
        """Precompute a prior cache (issue #5)."""
        not_built("priors", 5)

    @app.command("convert")
    def convert() -> None:
        """Convert outputs to MCAP (sinks issue)."""
        not_built("convert", 6)

    @app.command("inspect")
    def inspect() -> None:
        """Describe a source or recording (sinks issue)."""
        not_built("inspect", 6)
