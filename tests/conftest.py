"""Shared pytest fixtures."""

import gc
import gzip
import os
import shutil
import tempfile
import uuid
from pathlib import Path

import pytest

# One XLA thread per test process: the suite runs two pytest-xdist workers on two cores, and
# XLA's own intra-op threads on top of them oversubscribe the cores (test_diagnose.py alone on
# an idle machine: 558 s of CPU, 6.3 min, with one thread; 656 s with XLA's default threads, in
# a run that other jobs joined halfway). Must be set before JAX starts; a user's XLA_FLAGS win.
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")
# XLA's optimisation work off for the suite's programs (JAX's jax_disable_most_optimizations:
# backend optimisation level 0, LLVM's expensive passes off). Most of a cold test is XLA compiling
# distinct programs that then run for a second or two: a diagnose case 64 → 51 s, the MAP,
# Laplace and gradient programs of a four-run campaign 8.4 → 6.0 s to compile. Tests that spend
# their time running programs rather than compiling them (long chains, hundreds of fits) are
# marked ``runtime_bound`` and compile with the optimisations (the 200-unit acceptance: 75 s with
# them, 111 s without; the NUTS file 263 s against 334 s). A program a worker has already
# compiled is reused as it is. Inherited by the command-line and notebook subprocesses; a
# user's setting wins.
os.environ.setdefault("JAX_DISABLE_MOST_OPTIMIZATIONS", "1")
# One BLAS thread, as the commands use (torsionfit/_threads.py): OpenBLAS's spinning threads
# take the cores from XLA. Set before NumPy loads; inherited by the CLI and notebook subprocesses.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# The CLI keeps JAX's compiled programs on disk (torsionfit/_cache.py). The tests leave the
# user's cache alone but share one fresh cache per test run: both pytest-xdist workers, the
# command-line calls, the batch's worker processes and the notebook kernels compile the same
# model shapes again and again, and most of the suite's time is XLA compiling. The folder starts
# empty (nothing from an earlier run) and is removed when the run ends. tests/test_cache.py
# exercises the cache in folders of its own. TORSIONFIT_TEST_CACHE=off: no cache at all.
# The first process of the run (pytest-xdist's controller, or the only one) names the folder;
# the workers and every subprocess inherit the name from the environment.
from torsionfit._cache import MIN_COMPILE_TIME_S, enable_compilation_cache  # noqa: E402 (after the flags)
import jax  # noqa: E402

# torsionfit leaves JAX's precision alone (its entry points compute in float64 under a scoped,
# thread-local switch). Many tests call building blocks directly (model components, FitProblem
# methods) and compare with float64 tolerances, so this test process computes in float64
# throughout; tests/test_library_hygiene.py checks the library in fresh interpreters without it,
# and the command-line subprocesses of the tests run without it as well.
jax.config.update("jax_enable_x64", True)

_RUN_CACHE = "TORSIONFIT_TEST_RUN_CACHE"
_NAMED_HERE = _RUN_CACHE not in os.environ
if _NAMED_HERE:
    os.environ[_RUN_CACHE] = str(Path(tempfile.gettempdir()) / f"torsionfit-test-cache-{uuid.uuid4().hex}")
TEST_CACHE_DIR = Path(os.environ[_RUN_CACHE])
if os.environ.get("TORSIONFIT_TEST_CACHE", "").lower() == "off":
    os.environ["TORSIONFIT_CACHE_DIR"] = "off"
else:
    # the commands' switch, and JAX's own for library calls in this process, the workers and
    # the notebook kernels (JAX reads its options from the environment when it starts)
    os.environ["TORSIONFIT_CACHE_DIR"] = str(TEST_CACHE_DIR)
    os.environ["JAX_COMPILATION_CACHE_DIR"] = str(TEST_CACHE_DIR)
    os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = str(MIN_COMPILE_TIME_S)
    os.environ["JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES"] = "-1"
    enable_compilation_cache(TEST_CACHE_DIR)  # JAX may have been imported before this file


#: Every XLA CPU executable holds a few memory mappings until its jit cache entry goes; a
#: long-lived xdist worker compiling for dozens of files reached ~30 000 of Linux's default 65 530
#: (vm.max_map_count), and workers that passed it aborted inside XLA (serialising or compiling a
#: program, late in clean-clone runs, never when a file ran alone). So the count is checked after
#: every test and the compiled programs dropped above this many mappings (the disk cache makes
#: the recompiles cheap). Dropping them after every file as well cost 5 % of the suite's time:
#: the next file traced again and reloaded the very programs it shares with the one before.
MAX_MAPPINGS = 20_000


@pytest.fixture(autouse=True)
def _release_compiled_programs_when_many():
    yield
    try:
        with open("/proc/self/maps") as fh:
            mappings = sum(1 for _ in fh)
    except OSError:  # not Linux: no such limit to watch
        return
    if mappings > MAX_MAPPINGS:
        jax.clear_caches()
        gc.collect()


@pytest.fixture(autouse=True)
def _optimised_programs_for_runtime_bound_tests(request, monkeypatch):
    """A ``runtime_bound`` test compiles its programs with XLA's optimisations (see the top),
    in this process and in the processes it starts."""
    if request.node.get_closest_marker("runtime_bound") is None:
        yield
        return
    monkeypatch.setenv("JAX_DISABLE_MOST_OPTIMIZATIONS", "0")
    before = jax.config.values["jax_disable_most_optimizations"]
    if before:
        # the setting is not part of JAX's in-memory program cache: without this, the programs
        # an earlier test of the worker compiled without optimisations run here as they are
        # (the 200-unit acceptance took 190 s in the suite after its file's small tests, 57 s alone)
        jax.clear_caches()
    jax.config.update("jax_disable_most_optimizations", False)
    try:
        yield
    finally:
        jax.config.update("jax_disable_most_optimizations", before)


#: The files that take longest in the two-worker pool (seconds of test time, summed from
#: ``--durations=0`` of a whole pool run on the idle 2-core machine, the NUTS file beside them;
#: less the trails since moved to ``extended``), longest first. ``make test`` runs the
#: pool with ``--dist loadfile --no-loadscope-reorder``, so the workers take the files in the
#: collection's order: these first, then the rest as collected. pytest-xdist's default order (most
#: tests first) left the few-test, minute-long files (the 200-unit acceptance, the TE-export
#: diagnose) for the end, where one worker ran them while the other had nothing left (the last
#: 3 min at 75–86 % of the two cores). Only the order changes; a stale list costs time, not tests.
LONGEST_FILES = (
    "test_independent_bench.py",  # 203
    "test_accept.py",  # 186
    "test_batch.py",  # 149
    "test_fit_statistics.py",  # 142
    "test_report.py",  # 108
    "test_model.py",  # 87
    "test_fit_noise_classes.py",  # 78
    "test_library_hygiene.py",  # 78
    "test_diagnose_friction.py",  # 68 (run alone, after its two longest trails moved to extended)
    "test_fit_map.py",  # 67
    "test_notebooks.py",  # 56
    "test_diagnose.py",  # 55
    "test_te_exports_e2e.py",  # 46
    "test_sample.py",  # 39
    "test_diagnose_temperature.py",  # 37
    "test_measured_validation.py",  # 29
    "test_model_held_gap.py",  # 29
    "test_model_preload.py",  # 26
)


#: ``extended`` tests run only when asked (``make test-extended``): the suite's 15-minute budget
#: on the 2-core machine. Each is a long trail or end-to-end run whose capability a shorter test
#: of ``make test`` also covers (docs/statistics.md lists them and says which).
RUN_EXTENDED = os.environ.get("TORSIONFIT_EXTENDED_TESTS") == "1"
_EXTENDED_SKIP = pytest.mark.skip(reason="extended test, left out of `make test` for the suite's time: `make test-extended` "
                                        "(TORSIONFIT_EXTENDED_TESTS=1) runs it")


def pytest_collection_modifyitems(session, config, items):
    rank = {name: i for i, name in enumerate(LONGEST_FILES)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest as collected
    if not RUN_EXTENDED:
        for item in items:
            if item.get_closest_marker("extended"):
                item.add_marker(_EXTENDED_SKIP)


def pytest_unconfigure(config):
    # the process that named the folder ends last (xdist's controller after its workers)
    if _NAMED_HERE:
        shutil.rmtree(TEST_CACHE_DIR, ignore_errors=True)


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
