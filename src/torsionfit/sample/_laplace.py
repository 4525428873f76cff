"""Draws of the MAP's Laplace approximation, shaped as a sampler's result (DESIGN §2).

``--sampler laplace`` replaces the posterior by the Gaussian N(û, Σ) in the unconstrained
space u (û the MAP, Σ its covariance). Its draws are independent, so they form one chain;
:class:`LaplaceResult` carries them with the two log densities that say how good the
approximation is — the posterior's (``log_prob``) and the approximation's (``log_q``) — so
that the ArviZ tree of a Laplace fit has the same layout as an emcee or NUTS one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._x64 import in_float64
from ._emcee import SampleResult, _LogProb

__all__ = ["LaplaceResult", "laplace_result"]


@dataclass(frozen=True, eq=False)
class LaplaceResult(SampleResult):
    """Independent draws of u from N(û, Σ): ``chain`` (draws, 1, dim); ``log_prob`` (draws, 1)
    the posterior log density of u (up to a constant, −inf where not finite); ``log_q``
    (draws, 1) the Gaussian's normalised log density. Not a Markov chain: ``tau`` is 1."""

    log_q: np.ndarray | None = None

    sampler = "laplace"


def _gaussian_log_density(x: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """log N(x; mean, cov) per row, through the eigen-decomposition (cov may be near singular,
    as the draws themselves are made with ``method="eigh"``)."""
    w, v = np.linalg.eigh(0.5 * (cov + cov.T))
    w = np.maximum(w, np.finfo(float).tiny)
    z = (x - mean) @ v / np.sqrt(w)
    return -0.5 * np.sum(z**2, axis=1) - 0.5 * np.sum(np.log(2.0 * np.pi * w))


@in_float64
def laplace_result(problem, map_result, draws_u: np.ndarray, names, *, seed: int | None = None,
                   approximation=None) -> LaplaceResult:
    """The :class:`LaplaceResult` of ``draws_u`` (draws, dim), drawn from N(``map_result.u``,
    ``map_result.cov``) or from ``approximation`` (a :class:`~torsionfit.sample.SplitNormal`):
    evaluates the posterior log density at every draw."""
    draws_u = np.asarray(draws_u, dtype=float)
    n, dim = draws_u.shape
    lp = _LogProb(problem, batch=min(n, 256))(draws_u)
    if approximation is not None:
        lq = approximation.log_density(draws_u)
    else:
        lq = _gaussian_log_density(draws_u, np.asarray(map_result.u, float), np.asarray(map_result.cov, float))
    converged = bool(map_result.converged)
    return LaplaceResult(
        chain=draws_u[:, None, :], log_prob=lp[:, None], tau=np.ones(dim), n_steps=n, burn_in=0, thin=1,
        acceptance_fraction=np.ones(1), converged=converged,
        reason="" if converged else f"MAP did not converge: {map_result.message}",
        names=tuple(names), seed=seed,
        moves="independent draws of the Laplace approximation" if approximation is None
        else "independent draws of a split normal along the Laplace approximation's axes",
        log_q=lq[:, None])
