"""Shared pytest fixtures."""

import gzip
import os
from pathlib import Path

import pytest

# The CLI keeps JAX's compiled programs on disk (torsionfit/_cache.py); tests stay hermetic and
# leave the user's cache alone. tests/test_cache.py exercises the cache in a temporary folder.
os.environ["TORSIONFIT_CACHE_DIR"] = "off"
# One XLA thread per test process: the suite runs two pytest-xdist workers on two cores, and
# XLA's own intra-op threads on top of them oversubscribe the cores (test_diagnose.py alone on
# an idle machine: 558 s of CPU, 6.3 min, with one thread; 656 s with XLA's default threads, in
# a run that other jobs joined halfway). Must be set before JAX starts; a user's XLA_FLAGS win.
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
# One BLAS thread, as the commands use (torsionfit/_threads.py): OpenBLAS's spinning threads
# take the cores from XLA. Set before NumPy loads; inherited by the CLI and notebook subprocesses.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

#: the shared data folder next to the repository (real measured data, never copied in)
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture
def shared_data() -> Path:
    """Path of the shared data folder; skips the test when the folder is not there."""
    if not SHARED_DATA.is_dir():
        pytest.skip(f"shared data folder {SHARED_DATA} is absent (clone the repo next to shared/)")
    return SHARED_DATA


@pytest.fixture
def write_files(tmp_path):
    """Write ``{relative name: text}`` under a temporary folder; returns the manifest path
    ``campaign.toml`` in it. Names ending in ``.gz`` are gzip-compressed."""
    def write(files: dict[str, str]) -> Path:
        for name, text in files.items():
            path = tmp_path / name
            path.parent.mkdir(parents=True, exist_ok=True)
            if name.endswith(".gz"):
                with gzip.open(path, "wt", encoding="utf-8") as handle:
                    handle.write(text)
            else:
                path.write_text(text, encoding="utf-8")
        return tmp_path / "campaign.toml"

    return write
