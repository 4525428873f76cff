"""Where the work runs: this process, ``workers`` processes of this machine, or a Dask
distributed cluster (``--scheduler ADDRESS``). An executor maps a picklable function over a
list and yields the results in order, each as soon as it (and those before it) are done."""

import multiprocessing
import os
import queue
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

import jax

from .._errors import InputError

#: one XLA thread per worker process: the processes fill the cores, a second thread in each
#: only contends (the same setting as the test suite's workers)
WORKER_XLA_FLAGS = "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"


def usable_cpus() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def local_map(fn, items: list):
    return (fn(x) for x in items)


def default_workers() -> int:
    """``--workers`` when not given: one process per usable CPU on a CPU; one process (this one)
    when JAX's default device is an accelerator — it drives the device, and each further process
    would claim most of the device's memory (JAX preallocates 75 % per process)."""
    return usable_cpus() if jax.default_backend() == "cpu" else 1


def worker_cpus(workers: int) -> list[int]:
    """The CPU each of ``workers`` processes is pinned to: the usable CPUs, round robin
    (benchmarks/bench_batch.py, 1 000 units, 2 workers: 813 s unpinned → 632 s pinned)."""
    cpus = sorted(os.sched_getaffinity(0))
    return [cpus[i % len(cpus)] for i in range(workers)]


def _start_worker(cache_dir: str | None, xla_flags: str | None, cpu_queue=None) -> None:
    """In a fresh worker process, before any JAX computation: its own CPU (from ``cpu_queue``),
    the parent's compilation cache (so a shape compiled once on this machine is read from
    disk), the XLA threads and one BLAS thread (as torsionfit/_threads.py: two processes'
    spinning BLAS threads doubled the batch's time).

    The CPU: JAX sizes its CPU thread pool by the CPUs the process may run on, and the XLA
    flags do not keep its compute threads to one; unpinned, each of two workers kept two
    threads busy, four on two cores."""
    from .._threads import one_blas_thread

    if cpu_queue is not None:
        try:
            os.sched_setaffinity(0, {cpu_queue.get(timeout=5.0)})
        except queue.Empty:  # more processes than CPUs handed out: never wait for one
            pass
    one_blas_thread()  # for the worker's life
    if xla_flags is not None:
        os.environ["XLA_FLAGS"] = xla_flags
    if cache_dir:
        from .._cache import enable_compilation_cache

        enable_compilation_cache(cache_dir)


@contextmanager
def executor(scheduler: str | None = None, timeout_s: float = 30.0, workers: int = 1, processes: bool | None = None):
    """A map over ``items``: here (``workers`` 1), in ``workers`` fresh processes of this
    machine (also one, with ``processes``), or on the Dask scheduler at ``scheduler`` (e.g.
    ``tcp://10.0.0.5:8786``); InputError when Dask is missing or the scheduler cannot be
    reached. A worker process that dies raises ``BrokenProcessPool`` from the map."""
    if scheduler is None:
        if workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        if workers == 1 and not processes:
            yield local_map
            return
        # spawn, not fork: a forked JAX runtime (threads, XLA state) is not safe to use
        flags = os.environ.get("XLA_FLAGS") or WORKER_XLA_FLAGS
        cache = jax.config.jax_compilation_cache_dir
        context = multiprocessing.get_context("spawn")
        cpu_queue = None
        if hasattr(os, "sched_setaffinity"):  # Linux
            cpu_queue = context.Queue()
            for cpu in worker_cpus(workers):
                cpu_queue.put(cpu)
        with ProcessPoolExecutor(max_workers=workers, mp_context=context,
                                 initializer=_start_worker, initargs=(cache, flags, cpu_queue)) as pool:
            yield lambda fn, items: pool.map(fn, items)
        return
    try:
        from distributed import Client
    except ImportError:
        raise InputError("--scheduler needs Dask: pip install 'torsionfit[dask]'") from None
    try:
        client = Client(scheduler, timeout=timeout_s)
    except (OSError, TimeoutError, ValueError) as err:
        raise InputError(f"--scheduler {scheduler}: cannot reach a Dask scheduler ({' '.join(str(err).split())})") from None
    with client:
        def dask_map(fn, items: list):
            futures = client.map(fn, items, pure=False)
            return (future.result() for future in futures)

        yield dask_map
