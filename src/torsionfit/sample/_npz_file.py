"""A sampler's state on disk: one ``.npz`` file, replaced at once.

The NUTS backend and the SMC checkpoint write their state after every block or stage; a process
that stops while writing must leave the last complete file in place, never half of a new one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np


def save_npz_atomically(path: Path | str, **arrays) -> None:
    """Write ``arrays`` to the ``.npz`` file ``path`` through a temporary file beside it, then
    replace ``path`` with it in one step (the temporary file is removed if writing fails)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=path.name, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            np.savez(fh, **arrays)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
