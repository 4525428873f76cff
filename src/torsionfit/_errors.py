"""The one exception type for bad input: its message is a single line for the user."""


class InputError(ValueError):
    """Bad user input (file, column, key or value). ``str(err)`` is one line naming what
    was wrong and what was expected; the CLI prints it and exits non-zero."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))
