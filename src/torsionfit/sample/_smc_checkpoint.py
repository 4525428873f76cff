"""Tempered SMC's state on disk after every stage, so a run stopped part-way resumes there.

On measured loops one SMC run takes up to two hours, most of it in its last stages; a process
that ends (a machine restarted, a job's time limit) otherwise loses all of it. After each stage
:func:`~torsionfit.sample.tempered_smc` writes the particles (positions, log densities,
gradients), the tempering so far, the kernel's tuned step and the random generator's state to
one ``.npz`` file, replacing the last one at once (a file half written is never left in its
place). Started with the same file, it goes on from there and ends where the run without the
stop would have ended, draw for draw.

A checkpoint belongs to one problem: its settings (particles, coordinates, moves, kernel) are
compared with the run's, and the posterior and the approximation are evaluated again at the
saved particles and compared with the saved values; any difference stops with one line naming
the file, rather than carrying particles of one posterior into another.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ._npz_file import save_npz_atomically

#: written into every checkpoint; a file of another layout is refused
CHECKPOINT_VERSION = 1

#: the saved log densities and the ones evaluated again at the saved particles agree to this
#: (relative, and absolute in log density): the same program on the same machine repeats to the
#: digit, another program or data differ by far more
CHECK_RTOL = 1e-7
CHECK_ATOL = 1e-6


def save_checkpoint(path: Path | str, arrays: dict, record: dict) -> None:
    """Write ``arrays`` (NumPy arrays) and ``record`` (JSON) to ``path``, replacing it atomically."""
    save_npz_atomically(path, **{f"a_{k}": np.asarray(v) for k, v in arrays.items()},
                        record=np.array(json.dumps({"version": CHECKPOINT_VERSION, **record})))


def load_checkpoint(path: Path | str) -> tuple[dict, dict]:
    """(arrays, record) of a checkpoint written by :func:`save_checkpoint`."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            record = json.loads(str(data["record"]))
            arrays = {k[2:]: data[k] for k in data.files if k.startswith("a_")}
    except (OSError, ValueError, KeyError) as err:
        raise ValueError(f"{path}: not an SMC checkpoint ({err}); remove it to start afresh") from None
    if record.get("version") != CHECKPOINT_VERSION:
        raise ValueError(f"{path}: an SMC checkpoint of layout {record.get('version')!r}, this version writes "
                         f"{CHECKPOINT_VERSION}; remove it to start afresh")
    return arrays, record


def check_settings(path: Path | str, saved: dict, asked: dict) -> None:
    """Stop with one line where a setting of the run differs from the checkpoint's."""
    for key, value in asked.items():
        if saved.get(key) != value:
            raise ValueError(f"{path}: an SMC checkpoint made with {key} = {saved.get(key)!r}, this run asks "
                             f"{value!r}; remove it to start afresh or run with its settings")


def check_densities(path: Path | str, what: str, saved: np.ndarray, again: np.ndarray) -> None:
    """Stop with one line where the log density evaluated again at the saved particles is not the
    saved one (another posterior, other data, another approximation)."""
    saved, again = np.asarray(saved, float), np.asarray(again, float)
    finite = np.isfinite(saved)
    same = np.array_equal(finite, np.isfinite(again)) and np.allclose(
        saved[finite], again[finite], rtol=CHECK_RTOL, atol=CHECK_ATOL)
    if not same:
        worst = float(np.nanmax(np.abs(np.where(finite, saved - again, np.nan)))) if finite.any() else float("nan")
        raise ValueError(f"{path}: the {what} at the checkpoint's particles is not the one it was saved with "
                         f"(largest difference {worst:.3g} in log density): it belongs to another problem; "
                         "remove it to start afresh")
