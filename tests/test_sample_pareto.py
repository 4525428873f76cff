"""sample/_pareto.py: the Pareto k̂ that says whether draws of an approximation stand for the
posterior — its direction (a q narrower than p is the danger, a wider one is not), weightless
draws, and the fit's note."""

import numpy as np
import pytest
from scipy.stats import norm

from torsionfit.sample import good_k, importance_pareto_k


def _ratios(sd_q: float, n: int = 4000, seed: int = 0):
    x = np.random.default_rng(seed).normal(0.0, sd_q, size=n)
    return norm.logpdf(x), norm.logpdf(x, 0.0, sd_q)  # p = N(0, 1), q = N(0, sd_q²)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_narrower_approximation_is_caught_and_a_wider_one_is_not(seed):
    # weights p/q at draws of q = N(0, 0.4²) have a tail of shape 1 − 0.3² = 0.91: above the threshold
    assert importance_pareto_k(*_ratios(0.3, seed=seed)) > good_k(4000)
    assert importance_pareto_k(*_ratios(2.0, seed=seed)) < 0.5  # wider: bounded weights
    assert importance_pareto_k(*_ratios(1.0, seed=seed)) == 0.0  # exact: equal weights


def test_draws_of_zero_posterior_density_carry_no_weight():
    log_p, log_q = _ratios(1.2)
    k = importance_pareto_k(log_p, log_q)
    log_p[:50] = -np.inf  # outside the support: −inf, never NaN
    assert importance_pareto_k(log_p, log_q) == pytest.approx(k, abs=0.05)
    log_p[:-5] = -np.inf
    assert np.isnan(importance_pareto_k(log_p, log_q))  # too few draws with weight to say anything


def test_the_threshold_follows_the_draws():
    assert good_k(4000) == pytest.approx(0.7) and good_k(100) == pytest.approx(0.5)


def test_the_fit_says_when_its_draws_do_not_stand_for_the_posterior():
    from torsionfit.report._pipeline import pareto_k_note

    assert pareto_k_note(0.4, 2000) == ""
    note = pareto_k_note(1.3, 2000)
    assert "1.30, above 0.70" in note and "--sampler" in note and "\n" not in note
    assert "undefined" in pareto_k_note(float("nan"), 2000)
