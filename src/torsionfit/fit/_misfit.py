"""How much structure the noise model leaves in the residuals: the long-run variance of the
whitened residuals over their variance (batch means).

Under the fitted noise model the whitened residuals are white, so the mean of a block of L of
them has variance σ²/L and the ratio is 1 (up to sampling error). Structure the model lacks —
a loop shape it cannot follow, ramp-to-ramp changes — leaves residuals correlated over whole
ramps, and the ratio grows: the data then carry fewer independent pieces of information than
their count, and a posterior that treats them as independent is too narrow by about √ratio.
The posterior is widened by raising the likelihood to the power 1/ratio (a tempered,
"generalised Bayes" posterior; the batch-means version of a sandwich covariance with a scalar
meat). Its Laplace covariance is exact for that density: the likelihood's curvature divided by
the ratio, the prior's kept — so a parameter the data hardly inform stays within its prior
instead of being widened past it (scaling the whole covariance did that: Laplace draws of an
unidentified creep stiffness reached a thousandth of the mesh stiffness on a measured loop).
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from scipy.stats import chi2

from ._map import _laplace_parts  # the MAP fit's program at its optimum

MISFIT_BLOCKS = 20  # blocks per run for the batch means
MISFIT_ALPHA = 0.01  # a ratio is used only when white residuals would exceed it this rarely


def misfit_variance_ratio(problem, u, n_blocks: int = MISFIT_BLOCKS) -> np.ndarray:
    """Per run: L · var(block means of the whitened residuals) / mean(whitened²) at ``u``
    (1 when the run is too short for ``n_blocks`` blocks of 2 samples); under Student-t noise of
    the pseudo-residuals least squares minimises (``FitProblem.objective_residuals``)."""
    # under Student-t noise the pseudo-residuals, whose squares the Laplace curvature is of
    white = problem.split_runs(problem.objective_residuals(_laplace_parts(problem, jnp.asarray(u))[4][0]))
    out = []
    for w, keep in zip(white, problem.kept_samples()):
        w = np.asarray(w, float)[keep]  # the samples in the likelihood
        block = w.size // n_blocks
        if block < 2:
            out.append(1.0)
            continue
        means = w[: n_blocks * block].reshape(n_blocks, block).mean(axis=1)
        out.append(float(block * np.var(means, ddof=1) / max(np.mean(w**2), 1e-300)))
    return np.asarray(out)


def misfit_inflation(problem, u, n_blocks: int = MISFIT_BLOCKS, alpha: float = MISFIT_ALPHA) -> float:
    """One covariance factor ≥ 1 for a fit: the sample-weighted mean of the runs' ratios, used
    only when it exceeds what white residuals give with probability ``alpha`` (χ² of
    ``n_blocks − 1`` degrees of freedom), else 1."""
    ratios = misfit_variance_ratio(problem, u, n_blocks)
    counts = np.array([np.sum(k) for k in problem.kept_samples()], float)
    ratio = float(np.sum(ratios * counts) / np.sum(counts))
    threshold = chi2.ppf(1.0 - alpha, n_blocks - 1) / (n_blocks - 1)
    return ratio if ratio > threshold else 1.0


def tempered_physics_covariance(problem, u, factor: float) -> np.ndarray:
    """Laplace covariance of the physics block under the likelihood to the power 1/``factor``:
    (JₗᵀJₗ/factor + P)⁻¹, Jₗ the Jacobian of the whitened residuals and P the prior's precision
    (the Gauss–Newton curvature ``laplace_covariance`` inverts is JₗᵀJₗ + P)."""
    jac = np.asarray(_laplace_parts(problem, jnp.asarray(u))[0], float)
    n = problem.n_nonlinear
    prior_precision = np.diag(1.0 / np.asarray(problem.prior_sd, float) ** 2)
    # the last n rows of the Jacobian are the prior's pseudo-residuals (u − μ)/sd
    lik = jac[:-n]
    return np.linalg.pinv(lik.T @ lik / float(factor) + prior_precision)


def widened(problem, map_result, factor: float):
    """(problem with likelihood power 1/``factor``, map result with the physics block of its
    Laplace covariance that of the tempered density) — the MAP point kept; unchanged for
    ``factor`` ≤ 1."""
    if not factor > 1.0:
        return problem, map_result
    import dataclasses

    tempered = eqx.tree_at(lambda p: p.likelihood_power, problem, np.float64(1.0 / float(factor)))
    cov = np.array(map_result.cov, float)
    n = problem.n_nonlinear
    cov[:n, :n] = tempered_physics_covariance(problem, map_result.u, factor)
    return tempered, dataclasses.replace(map_result, problem=tempered, cov=cov)


def widen_for_misfit(problem, map_result):
    """:func:`widened` by this fit's :func:`misfit_inflation` at its MAP: (problem, map result)."""
    return widened(problem, map_result, misfit_inflation(problem, map_result.u))


#: an AR(1) coefficient of a hysteresis run at or above this (its bound is 0.995) is a correlation
#: over ≳ 50 samples: rather the model's smooth misfit than a bench's noise. With it the
#: likelihood scores mostly the residuals' increments, and the fit can follow a loop's shape
#: while its level is off — on measured cycloidal loops iid noise (with the widening above)
#: predicted held-out ramps better on 14 of 21 files (scripts/measured_validation.py --ar1)
MISFIT_RHO = 0.98


def misfit_correlated_runs(problem, u) -> dict[int, float]:
    """{run index: ρ} of the AR(1) hysteresis runs whose coefficient at ``u`` is ≥ :data:`MISFIT_RHO`."""
    _, rho = problem.noise_values(jnp.asarray(u))
    return {r: float(rho[r]) for r, kind in enumerate(problem.model.run_kinds)
            if kind == "hysteresis" and problem.ar1[r] and float(rho[r]) >= MISFIT_RHO}
