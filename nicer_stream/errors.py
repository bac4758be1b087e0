"""User-facing errors: the CLI prints their message on one line and exits non-zero."""


class UserError(Exception):
    """Bad input a person can fix; the message says what to do."""


class SourceError(UserError):
    """A frame source cannot be opened or read."""
