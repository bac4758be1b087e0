"""The `nicer-stream` command line. Each command lives in its own module."""
from __future__ import annotations

import typer

from nicer_stream.cli import commands

app = typer.Typer(
    help="Streaming RGB-only neural-implicit SLAM (NICER-SLAM) for recorded logs.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
commands.register(app)

if __name__ == "__main__":  # pragma: no cover
    app()
