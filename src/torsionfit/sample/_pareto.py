"""Does an approximation stand for the posterior? The Pareto k̂ of the importance ratios
p/q at draws of the approximation q (Vehtari et al. 2024, "Pareto smoothed importance
sampling"; Yao et al. 2018, "Yes, but did it work?").

A k̂ at most :func:`good_k` (0.7 for a few thousand draws) says the ratios have a finite-variance
tail: the draws, importance-weighted, stand for the posterior. Above it the posterior has mass
where the approximation has little (a q narrower than p, or centred off its mass) and no
weighting of those draws recovers it. A q wider than p gives k̂ below 0.5: a waste of draws,
not a danger.

ArviZ's ``psislw`` takes the *negated* log ratios (its PSIS-LOO passes the log-likelihood, the
ratios being its negative): the sign is handled here, once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["good_k", "importance_pareto_k"]


def good_k(n_draws: int) -> float:
    """The k̂ below which PSIS with ``n_draws`` draws is reliable: min(1 − 1/log10 S, 0.7)."""
    return float(min(1.0 - 1.0 / np.log10(max(n_draws, 11)), 0.7))


def importance_pareto_k(log_p: np.ndarray, log_q: np.ndarray) -> float:
    """Pareto k̂ of the ratios p/q at draws of q: ``log_p`` the posterior's log density (up to a
    constant; −inf where it is zero), ``log_q`` the approximation's, one value per draw. A draw
    of zero posterior density carries no weight. NaN when fewer than 10 draws have weight."""
    from arviz_stats.base import array_stats

    log_ratio = np.asarray(log_p, float) - np.asarray(log_q, float)
    finite = np.isfinite(log_ratio)
    if finite.sum() < 10:
        return float("nan")
    if np.ptp(log_ratio[finite]) <= 1e-9 * max(1.0, float(np.max(np.abs(log_ratio[finite])))):
        return 0.0  # equal weights: the approximation is the posterior (no tail to fit)
    # weightless draws sit far below the others (exp(−700) ≈ 0), out of the right tail the fit reads
    log_ratio = np.where(finite, log_ratio, np.min(log_ratio[finite]) - 700.0)
    _, k = array_stats.psislw(-log_ratio)
    return float(k)
