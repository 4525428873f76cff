"""Double precision where torsionfit computes, without touching the user's JAX configuration.

Fits need float64 (angles of arcseconds on top of offsets of degrees), but switching
``jax_enable_x64`` globally on import would change every other JAX computation of the user's
session. Instead the entry points run under JAX's scoped switch ``jax.enable_x64(True)``
(jax ≥ 0.9; ``jax.experimental.enable_x64`` is gone), which is

- thread-local: a thread started inside the scope does not inherit it, so a function that is
  a thread's target (the batch sampler's) or a worker process's task enters it itself;
- part of the jit cache key: a function jitted once in float32 by the user and once in float64
  by torsionfit is compiled twice, never mixed.
"""

import functools

import jax


def float64():
    """Context manager: JAX computes in float64 inside the block (this thread only); the
    previous setting comes back after it. For calling building blocks (model components,
    ``FitProblem`` methods) directly; torsionfit's entry points enter it themselves."""
    return jax.enable_x64(True)


def in_float64(fn):
    """Decorator: ``fn`` runs under :func:`float64`. Applied where it is defined, so every
    importer, a pickled reference (worker processes, Dask) and a thread's target get the same
    wrapped function."""

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        with jax.enable_x64(True):
            return fn(*args, **kwargs)

    return wrapper
