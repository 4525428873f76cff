"""The one exception type for bad input: its message is a single line for the user."""


class InputError(ValueError):
    """Bad user input (file, column, key or value). ``str(err)`` is one line naming what
    was wrong and what was expected; the CLI prints it and exits non-zero."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def error_line(err: BaseException) -> str:
    """One line for a unit's row: an InputError's own message, else the exception's type and
    message with whitespace collapsed (a batch must report, not die, on one unit)."""
    if isinstance(err, InputError):
        return str(err)
    return f"{type(err).__name__}: {' '.join(str(err).split())}"
