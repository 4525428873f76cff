"""MAP and Laplace approximation for many units of one shape: ``fit_map`` of each unit, either
one after another or vmapped over units × starts.

Vmapped, every unit gets the starts ``fit_map`` would give it (its own seed), the same noise
passes, the same sharing of the later passes by starts that reached the same optimum and the
same choice of the best start; the Levenberg–Marquardt loops run side by side (a batched
``while_loop`` keeps a finished lane where it stopped, so each unit ends where it would alone).
On an accelerator the lanes share the serial scans' per-sample steps. On a CPU the lanes'
work adds up (the scan is compute-bound) and every lane steps until the slowest has
converged, so there ``fit_map`` one unit after another is faster (both reuse one compiled
program per shape): ``lanes="auto"`` picks by backend.
"""

from typing import Literal

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._x64 import in_float64
from ..fit import MapResult, best_start, fit_map, iid_noise, laplace_from_parts, map_starts
from ..fit._map import _message, laplace_parts, noise_pass, same_optimum, stopped_short
from ._shape import stack_problems

Lanes = Literal["auto", "serial", "vmap"]


@eqx.filter_jit
def _pass(problems, u_phys, u_noise, solver, max_steps: int):
    """One noise pass per lane: ``problems`` stacked per unit, ``u_phys`` / ``u_noise``
    (units, lanes, ·). Returns (u_phys, u_noise, solver result, log density) per unit × lane.
    Every pass of ``fit_map_batch`` calls this one program (same lane count): one compilation."""

    def one_unit(problem, u_phys, u_noise):
        return jax.vmap(noise_pass, in_axes=(None, 0, 0, None, None))(problem, u_phys, u_noise, solver, max_steps)

    return eqx.filter_vmap(one_unit, in_axes=(eqx.if_array(0), 0, 0))(problems, u_phys, u_noise)


#: per unit at u (units, dim): physics Jacobian, (σ_r, ρ_r) and every parameter value (not the
#: whitened residuals and design, units × samples each, which the batch does not read)
_laplace_parts = eqx.filter_jit(eqx.filter_vmap(lambda problem, u: laplace_parts(problem, u)[:4]))


def _take(tree, *index):
    return jax.tree.map(lambda x: x[index], tree)


def resolve_lanes(lanes: Lanes) -> Literal["serial", "vmap"]:
    """``auto`` → serial on CPU, vmap elsewhere."""
    if lanes == "auto":
        return "serial" if jax.default_backend() == "cpu" else "vmap"
    if lanes not in ("serial", "vmap"):
        raise ValueError(f"lanes must be 'auto', 'serial' or 'vmap', not {lanes!r}")
    return lanes


def _serial(problems, run_names, seeds, **kwargs) -> list:
    out = []
    for problem, names, seed in zip(problems, run_names, seeds):
        try:
            out.append(fit_map(problem, names, seed=seed, **kwargs))
        except Exception as err:  # noqa: BLE001 — that unit's error (e.g. every start failed), not the group's
            out.append(err)
    return out


@in_float64
def fit_map_batch(problems: list, run_names: list, seeds: list[int], *, n_starts: int = 4,
                  max_steps: int = 300, noise_passes: int = 3, rtol: float = 1e-8,
                  atol: float = 1e-10, lanes: Lanes = "auto", polish_steps: int = 300) -> list:
    """``fit_map`` of every problem (all of one shape) with its seed; one ``MapResult`` — or the
    exception ``fit_map`` raises for it (``RuntimeError`` when every start failed) — per unit.
    ``lanes``: see the module docstring."""
    kwargs = dict(n_starts=n_starts, max_steps=max_steps, noise_passes=noise_passes, rtol=rtol, atol=atol,
                  polish_steps=polish_steps)
    if resolve_lanes(lanes) == "serial":
        return _serial(problems, run_names, seeds, **kwargs)
    if noise_passes < 1:
        raise ValueError(f"noise_passes must be at least 1, got {noise_passes}")
    stacked = stack_problems(problems)
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    n_units = len(problems)
    starts = jnp.asarray(np.stack([map_starts(p, n_starts, s) for p, s in zip(problems, seeds)]))
    noise0 = jnp.stack([jnp.tile(iid_noise(p), (n_starts, 1)) for p in problems])  # (units, starts, n_noise)
    first = _pass(stacked, starts, noise0, solver, max_steps)
    # the later passes for each unit's distinct first-pass optima only (as fit_map); every unit
    # keeps n_starts lanes, the spare ones repeating its first representative (same inputs, same
    # steps, so no extra work on an accelerator), so that all passes share one compiled program
    reps = [same_optimum(np.asarray(first[0][i])) for i in range(n_units)]
    distinct = [sorted(set(r)) for r in reps]
    lane_of = np.array([d + [d[0]] * (n_starts - len(d)) for d in distinct])
    pick = lambda x: jnp.stack([x[i][lane_of[i]] for i in range(n_units)])  # noqa: E731
    later = jax.tree.map(pick, first)
    for _ in range(noise_passes - 1):
        later = _pass(stacked, later[0], later[1], solver, polish_steps)
    u_phys, u_noise, results, lds = later
    u_all = np.concatenate([np.asarray(u_phys), np.asarray(u_noise)], axis=-1)
    lds = np.asarray(lds, dtype=float)
    ok_all = np.asarray(results == optx.RESULTS.successful)
    picked = []
    for i in range(n_units):
        col = {j: distinct[i].index(j) for j in distinct[i]}  # start index → lane
        lane = [col[r] for r in reps[i]]
        messages = [_message(_take(results, i, k)) for k in lane]
        try:
            picked.append(best_start(u_all[i, lane], lds[i, lane], ok_all[i, lane], messages)
                          + (messages, lds[i, lane]))
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
        u, ld, ok, message, messages, start_lds = p
        cov = laplace_from_parts(problem, u, jac[i], sigma[i], rho[i])
        step_sd = None
        if not ok:  # as fit_map: how far the optimum is from where the solve stopped
            step_sd, message = stopped_short(problem, tuple(names), u, message)
        out.append(MapResult(problem=problem, run_names=tuple(names), u=u, cov=cov,
                             values={k: np.asarray(v[i]) for k, v in values.items()}, log_density=ld,
                             converged=ok, message=message, starts=list(zip(start_lds.tolist(), messages)),
                             newton_step_sd=step_sd))
    return out
