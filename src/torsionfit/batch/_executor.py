"""Where the work runs: this process, or a Dask distributed cluster (``--scheduler ADDRESS``).
An executor maps a picklable function over a list and yields the results in order, each as
soon as it (and those before it) are done."""

from contextlib import contextmanager

from .._errors import InputError


def local_map(fn, items: list):
    return (fn(x) for x in items)


@contextmanager
def executor(scheduler: str | None = None, timeout_s: float = 30.0):
    """A map over ``items`` here (``scheduler`` None) or on the Dask scheduler at ``scheduler``
    (e.g. ``tcp://10.0.0.5:8786``); InputError when Dask is missing or the scheduler cannot be
    reached."""
    if scheduler is None:
        yield local_map
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
