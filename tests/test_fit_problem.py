"""FitProblem's views of all runs at once (``profile_all``, ``pointwise_log_likelihood``, the
closed-form noise update's segment sums) equal the likelihood written run by run, with AR(1)
restarting at each run's first sample (SYNTHETIC campaign of tests/benches/effects/base.toml)."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit import model as m
from torsionfit.bench import load_bench, simulate
from torsionfit.fit._map import _noise_update, _RHO_CAP
from torsionfit.fit._problem import RHO_MAX, FitProblem, NoiseOptions, build_problem

BENCH = Path(__file__).parent / "benches" / "effects" / "base.toml"


@pytest.fixture(scope="module")
def campaign():
    return simulate(load_bench(BENCH), seed=3).campaign


def _run_by_run(problem: FitProblem, u):
    """The likelihood written run by run: (pointwise log-likelihood per run, β, log det A)."""
    _, rho = problem.noise_values(u)
    preds = problem.nonlinear_prediction(u[:problem.n_nonlinear])
    s = jnp.exp(u[problem.n_nonlinear:problem.n_nonlinear + problem.n_runs])
    shapes = problem.noise_shape or [1.0] * problem.n_runs
    scales = [jnp.sqrt((s[r] * w) ** 2 + problem.floors[r] ** 2 + v) for r, (w, v) in enumerate(zip(shapes, problem.eiv_var))]
    scales = [jnp.broadcast_to(x, y.shape) for x, y in zip(scales, problem.y)]
    we = [problem.whiten(y - f, scales[r], rho[r]) for r, (y, f) in enumerate(zip(problem.y, preds))]
    wx = [problem.whiten(x, scales[r], rho[r]) for r, x in enumerate(problem.design)]
    a = sum(w.T @ w for w in wx)
    a = a + 1e-10 * jnp.trace(a) / problem.n_linear * jnp.eye(problem.n_linear)
    beta = jnp.linalg.solve(a, sum(w.T @ v for w, v in zip(wx, we)))
    out = []
    for r, (v, w) in enumerate(zip(we, wx)):
        white = v - w @ beta
        ll = -0.5 * white**2 - 0.5 * jnp.log(2 * jnp.pi) - jnp.log(scales[r])
        out.append(ll.at[0].add(0.5 * jnp.log(1.0 - rho[r] ** 2)))
    return out, beta, jnp.linalg.slogdet(a)[1]


@pytest.mark.parametrize("cycle_noise", [False, True], ids=["one level per run", "cycle-amplitude noise"])
def test_views_of_all_runs_equal_run_by_run(campaign, cycle_noise):
    kinds = tuple(r.kind for r in campaign.runs)
    assert kinds.count("hysteresis") >= 2 and kinds.count("transmission_error") >= 2
    problem = build_problem(campaign, m.CampaignModel(run_kinds=kinds, drift=True),
                            NoiseOptions(ar1=True, cycle_amplitude_noise=cycle_noise))
    u = problem.prior_mean
    rng = np.random.default_rng(0)
    u = jnp.concatenate([u + 0.1 * rng.standard_normal(u.size), jnp.asarray(problem.noise_prior_mean),
                         jnp.asarray(rng.uniform(-1, 1, problem.n_ar1))])
    expected, beta, logdet = _run_by_run(problem, u)
    got = problem.pointwise_log_likelihood(u)
    assert [len(g) for g in got] == [len(y) for y in problem.y]
    for g, e in zip(got, expected):
        np.testing.assert_allclose(g, e, rtol=1e-9, atol=1e-9)
    white, beta_all, logdet_all, _, rho = problem.profile_all(u)
    np.testing.assert_allclose(beta_all, beta, rtol=1e-7)
    np.testing.assert_allclose(logdet_all, logdet, rtol=1e-12)
    assert np.all(np.asarray(rho)[1:] > 0)  # AR(1) in every run: the restarts matter


def test_noise_update_equals_run_by_run(campaign):
    """Closed-form ρ_r and s_r from each run's own residual pairs, none across two runs."""
    kinds = tuple(r.kind for r in campaign.runs)
    problem = build_problem(campaign, m.CampaignModel(run_kinds=kinds), NoiseOptions(ar1=True))
    u = jnp.concatenate([problem.prior_mean, jnp.asarray(problem.noise_prior_mean), jnp.zeros(problem.n_ar1)])
    got = np.asarray(_noise_update(problem, u))
    log_s, logits = [], []
    for r, e in enumerate(problem.residuals(u)):
        e = np.asarray(e)
        rho = np.clip(e[1:] @ e[:-1] / (e[:-1] @ e[:-1]), 0.01, _RHO_CAP)
        logits.append(np.log(rho) - np.log(RHO_MAX - rho))
        var = np.mean((e[1:] - rho * e[:-1]) ** 2)
        floor2 = float(problem.floors[r]) ** 2
        log_s.append(0.5 * np.log(max(var - floor2, 1e-4 * max(floor2, var), 1e-30)))
    np.testing.assert_allclose(got, log_s + logits, rtol=1e-9)
