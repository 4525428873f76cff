"""Tempered sequential Monte Carlo from an approximation q to the posterior p.

Where the split normal along the Laplace axes does not stand for the posterior (Pareto k of p/q
at its draws above 0.7) no weighting of its draws recovers the posterior, and on measured loops
emcee's walkers and NUTS's trajectories cross it too slowly. Tempering bridges the two: particles
drawn from q are carried through the densities

    π_β(u) ∝ q(u)^(1 − β) · p(u)^β,   β = 0 → 1,

each step's β chosen so that the incremental weights (p/q)^Δβ keep an effective sample size of
``target_ess`` of the particles; the particles are then resampled (systematic) and moved by
random-walk Metropolis steps that leave π_β invariant (proposal: the particles' covariance scaled
by a factor tuned towards an acceptance of 0.234), every other move an independence proposal from
the particles' Gaussian (inflated by ``INDEPENDENT_INFLATION``). The moves go on until every coordinate's
correlation with the particles' positions at the start of the stage has fallen to
``decorrelation`` — the particles have forgotten where resampling put them — or
``max_moves`` is reached, which counts as not converged. At β = 1 the particles are equally
weighted draws of p (Del Moral, Doucet & Jasra 2006; Chopin & Papaspiliopoulos 2020, ch. 17).

The sampler is gradient free and calls the posterior in batches (one compiled program for all
particles): a move of 1000 particles costs about a quarter of a second on a measured loop, whose
tempering took 8–29 stages of up to 100 moves (5–19 min). BlackJAX's tempered SMC would
need q's log density and the whole loop inside one jitted JAX program; here q is the split normal
of :mod:`._split_normal` (NumPy) and the posterior is the batched program emcee calls.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ._emcee import SampleResult
from ._pareto import importance_pareto_k

#: the acceptance the random walk's scale is tuned towards (Roberts, Gelman & Gilks 1997)
TARGET_ACCEPTANCE = 0.234

#: the independence proposal's covariance is the particles' times this squared (heavier reach)
INDEPENDENT_INFLATION = 1.3

__all__ = ["SMCResult", "tempered_smc"]


def _gauss_log(x: np.ndarray, mean: np.ndarray, chol: np.ndarray) -> np.ndarray:
    """log N(x; mean, chol·cholᵀ) up to the constant (the same for every x)."""
    z = np.linalg.solve(chol, (x - mean).T)
    return -0.5 * np.sum(z**2, axis=0)


@dataclasses.dataclass(frozen=True, eq=False)
class SMCResult(SampleResult):
    """Equally weighted particles of the posterior as one chain: ``chain`` (particles, 1, dim),
    ``log_prob`` (particles, 1). ``betas``: the tempering schedule (last 1.0 when it reached the
    posterior); per stage ``moves`` (random-walk steps), ``stage_acceptance`` and
    ``stage_correlation`` (the largest |correlation| of a coordinate with its value at the start
    of the stage, after the moves); ``approximation_pareto_k``: the Pareto k of p/q at q's draws
    (how far the approximation was from the posterior)."""

    betas: tuple = ()
    stage_moves: tuple = ()
    stage_acceptance: tuple = ()
    stage_correlation: tuple = ()
    approximation_pareto_k: float = float("nan")

    sampler = "smc"


def _incremental_weights(log_ratio: np.ndarray, delta: float) -> np.ndarray:
    """(p/q)^Δβ per particle, scaled to a largest of 1 (``log_ratio`` −inf: weight 0; Δβ > 0)."""
    w = delta * log_ratio
    return np.exp(w - np.max(w))


def _next_beta(log_ratio: np.ndarray, beta: float, target_ess: float) -> float:
    """The largest β' ≤ 1 whose incremental weights (p/q)^(β'−β) keep an ESS of ``target_ess``
    of the particles (bisection; the ESS falls as β' grows)."""

    def ess(delta: float) -> float:
        w = _incremental_weights(log_ratio, delta)
        return float(w.sum() ** 2 / (w**2).sum() / w.size)

    if ess(1.0 - beta) >= target_ess:
        return 1.0
    lo, hi = 0.0, 1.0 - beta
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ess(mid) >= target_ess else (lo, mid)
    return beta + max(lo, 1e-12)


def _systematic(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    n = weights.size
    idx = np.searchsorted(np.cumsum(weights), (rng.random() + np.arange(n)) / n)
    return np.minimum(idx, n - 1)


def _correlations(start: np.ndarray, now: np.ndarray) -> np.ndarray:
    """|correlation| of each coordinate between the particles' positions at the start of a stage
    and now (0 for a coordinate that does not vary)."""
    a = start - start.mean(axis=0)
    b = now - now.mean(axis=0)
    den = np.sqrt((a**2).sum(axis=0) * (b**2).sum(axis=0))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 0, np.abs((a * b).sum(axis=0)) / den, 0.0)


def tempered_smc(log_p, approximation, rng: np.random.Generator, n_particles: int = 1000, *,
                 target_ess: float = 0.5, min_moves: int = 5, max_moves: int = 100,
                 decorrelation: float = 0.1, max_stages: int = 200, names=(), seed: int | None = None,
                 progress=None) -> SMCResult:
    """Draws of the posterior ``log_p`` (a function of (n, dim) u → (n,) log density, −inf where
    zero) by tempering from ``approximation`` (``draw(rng, n)``, ``log_density(x)``); see the
    module docstring. ``progress``: called with one line per stage."""
    names = tuple(names)
    x = np.asarray(approximation.draw(rng, n_particles), float)
    n, dim = x.shape
    lq = np.asarray(approximation.log_density(x), float)
    lp = np.asarray(log_p(x), float)
    k_q = importance_pareto_k(lp, lq)
    beta, betas, moves, accept, corr, slowest = 0.0, [], [], [], [], []
    scale = 2.38 / np.sqrt(dim)
    reason = ""
    while beta < 1.0:
        if len(betas) >= max_stages:
            reason = f"the tempering took more than {max_stages} stages (β = {beta:.3g})"
            break
        log_ratio = np.where(np.isfinite(lp), lp - lq, -np.inf)
        if not np.any(np.isfinite(log_ratio)):
            reason = "no particle has a finite posterior density"
            break
        new_beta = _next_beta(log_ratio, beta, target_ess)
        w = _incremental_weights(log_ratio, new_beta - beta)
        idx = _systematic(w / w.sum(), rng)
        x, lp, lq = x[idx], lp[idx], lq[idx]
        beta = new_beta
        betas.append(beta)
        # random-walk Metropolis under π_β with the particles' covariance
        cov = np.cov(x, rowvar=False).reshape(dim, dim)
        chol = np.linalg.cholesky(cov + 1e-12 * (np.trace(cov) / dim + 1e-300) * np.eye(dim))
        mean = x.mean(axis=0)
        ind_chol = INDEPENDENT_INFLATION * chol
        start = x.copy()
        rates = []
        for m in range(1, max_moves + 1):
            # every other move proposes afresh from the particles' Gaussian (inflated): where π_β is
            # near it one accepted move forgets the start; the random walk handles the rest
            independent = m % 2 == 0
            if independent:
                prop = mean + rng.standard_normal((n, dim)) @ ind_chol.T
            else:
                prop = x + scale * rng.standard_normal((n, dim)) @ chol.T
            lp_new = np.asarray(log_p(prop), float)
            lq_new = np.asarray(approximation.log_density(prop), float)
            log_a = beta * (lp_new - lp) + (1.0 - beta) * (lq_new - lq)
            if independent:
                log_a = log_a - _gauss_log(prop, mean, ind_chol) + _gauss_log(x, mean, ind_chol)
            ok = np.log(rng.random(n)) < np.where(np.isfinite(log_a), log_a, -np.inf)
            x[ok], lp[ok], lq[ok] = prop[ok], lp_new[ok], lq_new[ok]
            if not independent:
                rates.append(float(ok.mean()))
                scale *= float(np.exp(rates[-1] - TARGET_ACCEPTANCE))  # the population's rate, not a particle's
            if m >= min_moves and np.max(_correlations(start, x)) <= decorrelation:
                break
        by_coordinate = _correlations(start, x)
        moves.append(m)
        accept.append(float(np.mean(rates)))
        corr.append(float(np.max(by_coordinate)))
        slowest.append(int(np.argmax(by_coordinate)))
        if progress is not None:
            progress(f"[smc] stage {len(betas)}: β = {beta:.4f}, {m} moves, acceptance {accept[-1]:.2f}, "
                     f"correlation with the stage's start {corr[-1]:.2f}")
    if not reason and max(corr, default=0.0) > decorrelation:
        stuck = [i + 1 for i, c in enumerate(corr) if c > decorrelation]
        worst = slowest[int(np.argmax(corr))]
        who = names[worst] if worst < len(names) else f"u[{worst}]"
        reason = (f"the particles did not forget their start within {max_moves} moves at stage(s) "
                  f"{', '.join(map(str, stuck))} (largest correlation {max(corr):.2f} > {decorrelation}, of {who})")
    converged = not reason
    return SMCResult(
        chain=x[:, None, :], log_prob=lp[:, None], tau=np.ones(dim), n_steps=int(sum(moves)), burn_in=0, thin=1,
        acceptance_fraction=np.array([float(np.mean(accept)) if accept else 0.0]), converged=converged,
        reason=reason, names=names, seed=seed,
        moves=(f"tempered SMC from the split normal: {n} particles, {len(betas)} stages, random-walk Metropolis "
               "moves with the particles' covariance alternating with independence proposals from their Gaussian"),
        betas=tuple(betas), stage_moves=tuple(moves), stage_acceptance=tuple(accept), stage_correlation=tuple(corr),
        approximation_pareto_k=float(k_q))
