"""JAX's persistent compilation cache for the command line.

Every fit compiles its model once per shape of campaign (run kinds, run lengths, effects):
tens of seconds on a small CPU. A line or a lab analyses many campaigns of the same shape, so
the commands keep the compiled programs on disk and a later process of the same shape skips
compilation. The library itself does not switch this on (no global state on import); the CLI
does, and scripts may call :func:`enable_compilation_cache`.

``TORSIONFIT_CACHE_DIR`` chooses the folder (default ``~/.cache/torsionfit/jax``, or
``$XDG_CACHE_HOME/torsionfit/jax``); ``TORSIONFIT_CACHE_DIR=off`` switches the cache off.
"""

import os
from pathlib import Path

import jax

#: compilations faster than this are not worth a disk entry (s)
MIN_COMPILE_TIME_S = 0.2


def default_cache_dir() -> Path | None:
    """The cache folder the environment asks for; None when it says ``off``."""
    chosen = os.environ.get("TORSIONFIT_CACHE_DIR")
    if chosen is not None:
        return None if chosen.strip().lower() in ("", "off", "0", "none") else Path(chosen).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "torsionfit" / "jax"


def enable_compilation_cache(path: Path | str | None = None) -> Path | None:
    """Keep JAX's compiled programs in ``path`` (default :func:`default_cache_dir`); returns the
    folder used, or None when the cache is off or the folder cannot be created."""
    folder = Path(path) if path is not None else default_cache_dir()
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None  # a read-only home must not stop an analysis: it only costs compile time
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", MIN_COMPILE_TIME_S)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    return folder
