"""User-facing errors: the CLI prints their message on one line and exits non-zero."""


class UserError(Exception):
    """Bad input a person can fix; the message says what to do."""


class SourceError(UserError):
    """A frame source cannot be opened or read."""


def one_line(e: BaseException) -> str:
    """`Type: first line of the message`: how a run, a batch row or summary.json reports an error."""
    return f"{type(e).__name__}: {e}".strip().splitlines()[0]
