"""MAP and Laplace approximation for many units of one shape at once: ``fit_map`` vmapped over
units × starts.

Every unit gets the starts ``fit_map`` would give it (its own seed), the same noise passes and
the same choice of the best start; the Levenberg–Marquardt loops run side by side (a batched
``while_loop`` keeps a finished lane where it stopped, so each unit ends where it would alone).
One compilation per shape and batch size; the per-sample work of the serial scans is shared by
all lanes.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ..fit import MapResult, best_start, iid_noise, laplace_from_parts, map_starts
from ..fit._map import _message, laplace_parts, noise_pass
from ._shape import stack_problems


@eqx.filter_jit
def _all_starts(problems, starts, noise0, solver, max_steps: int, noise_passes: int):
    """(u, solver result of the last pass, log density) per unit × start.
    ``starts`` (units, starts, n_nonlinear), ``noise0`` (units, n_noise)."""

    def one_start(problem, u_phys, u_noise):
        result = ld = None
        for _ in range(noise_passes):
            u_phys, u_noise, result, ld = noise_pass(problem, u_phys, u_noise, solver, max_steps)
        return jnp.concatenate([u_phys, u_noise]), result, ld

    def one_unit(problem, unit_starts, u_noise):
        return jax.vmap(one_start, in_axes=(None, 0, None))(problem, unit_starts, u_noise)

    return eqx.filter_vmap(one_unit)(problems, starts, noise0)


#: per unit at u (units, dim): physics Jacobian, (σ_r, ρ_r) and every parameter value
_laplace_parts = eqx.filter_jit(eqx.filter_vmap(laplace_parts))


def _take(tree, *index):
    return jax.tree.map(lambda x: x[index], tree)


def fit_map_batch(problems: list, run_names: list, seeds: list[int], *, n_starts: int = 4,
                  max_steps: int = 300, noise_passes: int = 3, rtol: float = 1e-8,
                  atol: float = 1e-10) -> list:
    """``fit_map`` of every problem (all of one shape) with its seed, fitted together; one
    ``MapResult`` — or the ``RuntimeError`` ``fit_map`` would raise — per unit."""
    stacked = stack_problems(problems)
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    starts = jnp.asarray(np.stack([map_starts(p, n_starts, s) for p, s in zip(problems, seeds)]))
    noise0 = jnp.stack([iid_noise(p) for p in problems])
    u_all, results, lds = _all_starts(stacked, starts, noise0, solver, max_steps, noise_passes)
    u_all, lds = np.asarray(u_all), np.asarray(lds, dtype=float)
    ok_all = np.asarray(results == optx.RESULTS.successful)
    picked = []
    for i in range(len(problems)):
        messages = [_message(_take(results, i, j)) for j in range(n_starts)]
        try:
            picked.append(best_start(u_all[i], lds[i], ok_all[i], messages) + (messages,))
        except RuntimeError as err:
            picked.append(err)
    u_best = jnp.asarray(np.stack([p[0] if not isinstance(p, Exception) else u_all[i, 0]
                                   for i, p in enumerate(picked)]))
    jac, sigma, rho, values = _laplace_parts(stacked, u_best)
    out = []
    for i, (problem, names, p) in enumerate(zip(problems, run_names, picked)):
        if isinstance(p, Exception):
            out.append(p)
            continue
        u, ld, ok, message, messages = p
        cov = laplace_from_parts(problem, u, jac[i], sigma[i], rho[i])
        out.append(MapResult(problem=problem, run_names=tuple(names), u=u, cov=cov,
                             values={k: np.asarray(v[i]) for k, v in values.items()}, log_density=ld,
                             converged=ok, message=message, starts=list(zip(lds[i].tolist(), messages))))
    return out
