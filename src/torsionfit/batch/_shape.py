"""Problem shape: units whose fitting problems have the same structure and array shapes (run
kinds, run lengths, effects, latent-torque knots, AR(1) flags) share one compiled program and
can be fitted together under ``vmap``."""

import hashlib

import jax
import jax.numpy as jnp

from .._x64 import in_float64
from ..fit import FitProblem


def shape_key(problem: FitProblem) -> str:
    """A short text naming the shape of ``problem`` (equal for problems that stack)."""
    leaves, treedef = jax.tree.flatten(problem)
    text = str(treedef) + repr([(tuple(jnp.shape(x)), str(jnp.result_type(x))) for x in leaves])
    return hashlib.sha1(text.encode()).hexdigest()[:12]


@in_float64
def stack_problems(problems: list[FitProblem]) -> FitProblem:
    """One FitProblem whose every array has a leading unit axis (all of one shape)."""
    keys = {shape_key(p) for p in problems}
    if len(keys) != 1:
        raise ValueError(f"problems of {len(keys)} shapes cannot be stacked")
    return jax.tree.map(lambda *xs: jnp.stack(xs), *problems)


def group_by_shape(keys: list[str | None], group_size: int) -> list[list[int]]:
    """Indices of ``keys`` grouped by equal key (None: not fittable, left out), in order of
    first appearance, each group cut into chunks of at most ``group_size``."""
    if group_size < 1:
        raise ValueError(f"group size must be at least 1, got {group_size}")
    by_key: dict[str, list[int]] = {}
    for i, key in enumerate(keys):
        if key is not None:
            by_key.setdefault(key, []).append(i)
    return [idx[k:k + group_size] for idx in by_key.values() for k in range(0, len(idx), group_size)]
