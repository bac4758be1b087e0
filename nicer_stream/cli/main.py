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


@app.callback()
def _configure(log_level: str = typer.Option("info", "--log-level", help="debug, info, warning or error: what the log shows on stderr.")) -> None:
    """Streaming RGB-only neural-implicit SLAM (NICER-SLAM) for recorded logs."""
    import logging

    level = getattr(logging, log_level.upper(), None)
    if not isinstance(level, int):
        typer.echo(f"error: --log-level '{log_level}' is not one of debug, info, warning, error", err=True)
        raise typer.Exit(2)
    # Other libraries stay at WARNING: --log-level is about this project's messages.
    logging.basicConfig(level=max(level, logging.WARNING), format="%(levelname)s %(name)s: %(message)s")
    for name in ("nicer_stream", "sources", "sinks"):
        logging.getLogger(name).setLevel(level)


commands.register(app)

if __name__ == "__main__":  # pragma: no cover
    app()
