"""Shared CLI plumbing: one-line errors, source options from flags."""
from __future__ import annotations

import functools

import typer

from nicer_stream.errors import UserError


def user_errors(fn):
    """Turn UserError and any OSError a user can cause (a missing file, a file where a folder should
    be, no permission, a full disk) into a one-line message and exit code 2."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except (UserError, OSError) as e:
            typer.echo(f"error: {_message(e)}", err=True)
            raise typer.Exit(2)

    return wrapper


def _message(e: Exception) -> str:
    if isinstance(e, UserError):
        return str(e)
    if isinstance(e, FileNotFoundError):
        return f"file not found: {e.filename or e}"
    return os_error(e)


def os_error(e: OSError) -> str:
    """'File exists: runs/x' (the system's reason and the path), whatever the OSError."""
    where = " -> ".join(str(f) for f in (e.filename, e.filename2) if f is not None)
    return f"{e.strerror or type(e).__name__}: {where}" if where else str(e) or type(e).__name__


def parse_intrinsics(text: str | None) -> tuple[float, float, float, float] | None:
    """'fx,fy,cx,cy' -> tuple, or None."""
    if not text:
        return None
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 4:
        raise UserError(f"--intrinsics must be 'fx,fy,cx,cy' (four numbers), got '{text}'")
    return vals  # type: ignore[return-value]


DROP_HELP = "A:B drops input frames A..B-1 (raw numbers, as --start counts), to simulate a jump."


def parse_drop(text: str | None) -> tuple[int, int] | None:
    """'A:B' -> (A, B), or None; the range itself is checked by SourceOptions."""
    if not text:
        return None
    a, _, b = text.partition(":")
    try:
        return int(a), int(b)
    except ValueError:
        raise UserError(f"--drop must be 'A:B' (two integers, drops input frames A..B-1), got '{text}'") from None
