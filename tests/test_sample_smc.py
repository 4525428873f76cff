"""Tempered SMC from an approximation to the posterior (sample/_smc.py): it recovers a posterior
its starting approximation misses, and says when it has not."""

import numpy as np
import pytest

from torsionfit.sample import SMCResult, SplitNormal, tempered_smc


def _target(mean, cov):
    """Log density (up to a constant) of N(mean, cov), −inf nowhere."""
    prec = np.linalg.inv(cov)

    def log_p(x):
        d = np.atleast_2d(x) - mean
        return -0.5 * np.einsum("ni,ij,nj->n", d, prec, d)

    return log_p


def _narrow_start(dim, sd=0.3):
    """A split normal at the origin, ``sd`` wide on every axis: too narrow and off-centre for
    the targets below (their Pareto k at its draws is far above 0.7)."""
    return SplitNormal(mean=np.zeros(dim), axes=np.eye(dim), sd=np.full(dim, sd), scales=np.ones((dim, 2)))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_posterior_wider_and_elsewhere_than_the_approximation_is_recovered(seed):
    dim = 6
    rng = np.random.default_rng(100 + seed)
    a = rng.normal(size=(dim, dim))
    cov = a @ a.T / dim + np.eye(dim)  # correlated, sds 1–2
    mean = rng.normal(scale=0.5, size=dim)
    res = tempered_smc(_target(mean, cov), _narrow_start(dim), np.random.default_rng(seed), 1000)
    x = res.chain[:, 0, :]
    assert isinstance(res, SMCResult) and res.converged and res.reason == ""
    assert res.betas[-1] == 1.0 and res.approximation_pareto_k > 0.7
    sd = np.sqrt(np.diag(cov))
    # 1000 nearly independent draws: the mean within 0.2 sd, each sd within 15 %
    assert np.all(np.abs(x.mean(axis=0) - mean) < 0.2 * sd)
    np.testing.assert_allclose(x.std(axis=0), sd, rtol=0.15)
    assert max(res.stage_correlation) <= 0.1


def test_moves_that_cannot_forget_the_start_are_not_converged():
    dim = 6
    res = tempered_smc(_target(np.ones(dim), 4.0 * np.eye(dim)), _narrow_start(dim), np.random.default_rng(0), 300,
                       max_moves=1, min_moves=1, names=[f"p{i}" for i in range(dim)])
    assert not res.converged
    assert "did not forget their start within 1 moves" in res.reason and ", of p" in res.reason


def test_a_posterior_zero_at_every_particle_stops_with_a_reason():
    res = tempered_smc(lambda x: np.full(len(x), -np.inf), _narrow_start(3), np.random.default_rng(0), 100)
    assert not res.converged and res.reason == "no particle has a finite posterior density"
