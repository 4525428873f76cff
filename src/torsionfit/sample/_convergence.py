"""The convergence rule every sampler is judged by: rank-normalised split R̂ ≤ ``rhat_max``
(1.01) and bulk and tail effective sample sizes ≥ ``min_ess`` (400) for every entry of u
(Vehtari et al. 2021, as ``arviz_stats`` computes them). R̂ and ESS are rank based, so they
hold for the physical values (monotone maps of u) alike. emcee's walkers count as chains: they
are not independent (the moves use the others' positions), but a walker stuck apart from the
rest shows in R̂ all the same."""

import warnings

import numpy as np
from arviz_stats.base import array_stats
from arviz_stats.validate import validate_ci_prob

#: the rule's thresholds (DESIGN §2)
RHAT_MAX = 1.01
MIN_ESS = 400.0


def chain_diagnostics(chain: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(R̂, bulk ESS, tail ESS) per entry of u from draws (draws, chains, dim), by
    ``arviz_stats`` (rank-normalised split R̂; NaN for an entry that never moved).

    Its NumPy functions, with the defaults of its xarray ones (R̂ "rank", the tail ESS at
    ``stats.ci_prob``), which give the same numbers bit for bit: an xarray DataArray made xarray
    import Dask to check for Dask arrays, 0.2–0.45 s of the first call in a process (a quarter of
    an emcee run's own work on the 10k loop of benchmarks/bench_full_fit.py)."""
    ary = np.transpose(np.asarray(chain, dtype=float), (2, 1, 0))  # (u, chain, draw)
    axes = {"chain_axis": -2, "draw_axis": -1}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        rhat = np.asarray(array_stats.rhat(ary, method="rank", **axes), dtype=float)
        bulk = np.asarray(array_stats.ess(ary, method="bulk", **axes), dtype=float)
        tail = np.asarray(array_stats.ess(ary, method="tail", prob=validate_ci_prob(None), **axes), dtype=float)
    return rhat, bulk, tail


def rhat_ess_shortfall(rhat, bulk, tail, n_draws: int, names, rhat_max: float = RHAT_MAX,
                       min_ess: float = MIN_ESS, per: str = "draws per chain") -> str:
    """"" when R̂ and ESS meet the rule, else the shortfall naming the worst entry of u."""
    def who(i):
        return names[i] if names is not None and i < len(names) else f"u[{i}]"

    r = np.where(np.isfinite(rhat), rhat, np.inf)
    if np.max(r) > rhat_max:
        i = int(np.argmax(r))
        return f"R̂ = {r[i]:.3f} > {rhat_max} for {who(i)} after {n_draws} {per}"
    e = np.minimum(np.where(np.isfinite(bulk), bulk, 0.0), np.where(np.isfinite(tail), tail, 0.0))
    if np.min(e) < min_ess:
        i = int(np.argmin(e))
        kind = "bulk" if bulk[i] <= tail[i] else "tail"
        return f"{kind} ESS = {e[i]:.0f} < {min_ess:g} for {who(i)} after {n_draws} {per}"
    return ""
