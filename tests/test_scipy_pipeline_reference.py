"""The NumPy/SciPy pipeline of benchmarks/bench_full_fit.py computes torsionfit's posterior.

Not a timing test: it keeps the full-fit benchmark honest — the NumPy log-density (walker-
vectorised and single-point), its least-squares residuals and its parameter layout equal
torsionfit's ``FitProblem`` for the configurations the benchmark compares.
"""

import importlib.util
import sys
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

pytest.importorskip("scipy", reason="the NumPy/SciPy benchmark pipeline needs scipy (not a torsionfit dependency)")

from torsionfit.bench import load_bench, simulate  # noqa: E402
from torsionfit.fit import NoiseOptions, build_problem  # noqa: E402
from torsionfit.fit._map import _lm_objective_residuals, _lm_residuals  # noqa: E402
from torsionfit.model import model_with_effects  # noqa: E402

_BENCH = Path(__file__).resolve().parents[1] / "benchmarks"
_spec = importlib.util.spec_from_file_location("_bench_scipy_pipeline", _BENCH / "_scipy_pipeline.py")
sp = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = sp  # dataclasses look the module up while the class is created
_spec.loader.exec_module(sp)


@pytest.fixture(scope="module")
def sim():
    return simulate(load_bench(_BENCH / "benches" / "full_fit_2k.toml"))


def _pair(sim, latent_torque, ar1):
    c = sim.campaign
    model = model_with_effects([r.kind for r in c.runs], {}, c.reducer.rated_torque_Nm, free_friction_start=True)
    problem = build_problem(c, model, NoiseOptions(ar1=ar1), latent_torque=latent_torque)
    return problem, sp.build(c, latent_torque=latent_torque, ar1=ar1)


def _points(problem, truth, rng, n=6):
    """Points around the truth (where the posterior is) and around the prior centre (far out)."""
    u_truth = np.concatenate([
        np.asarray(problem.physics_u({**{k: np.asarray(v) for k, v in truth.items()}, "friction_start": 0.1})),
        np.zeros(problem.n_torque_lines), np.asarray(problem.noise_prior_mean) - 1.0, np.zeros(problem.n_ar1),
    ])
    u_prior = np.concatenate([np.asarray(problem.prior_mean), np.asarray(problem.noise_prior_mean),
                              np.zeros(problem.n_ar1)])
    near = u_truth + 0.01 * rng.standard_normal((n // 2, problem.dim))
    far = u_prior + 0.3 * rng.standard_normal((n - n // 2, problem.dim))
    return np.concatenate([near, far])


@pytest.mark.parametrize("latent_torque, ar1", [(True, None), (False, False)],
                         ids=["default fit_campaign configuration", "no knots, iid noise"])
def test_numpy_log_density_equals_torsionfit(sim, latent_torque, ar1):
    problem, npb = _pair(sim, latent_torque, ar1)
    run = [sim.campaign.runs[0].name]
    assert npb.names() == problem.names(run)
    assert npb.dim == problem.dim and npb.ar1 == problem.ar1[0]
    np.testing.assert_array_equal(npb.prior_mean, np.asarray(problem.prior_mean))
    np.testing.assert_array_equal(npb.prior_sd, np.asarray(problem.prior_sd))

    u = _points(problem, sim.truth, np.random.default_rng(3))
    want = np.asarray(jax.jit(jax.vmap(problem.log_density))(jnp.asarray(u)))
    assert np.all(np.isfinite(want))
    got = npb.log_density(u)  # walker-vectorised (the emcee path)
    got_one = np.array([npb.log_density(x) for x in u])  # Python-float recurrence
    np.testing.assert_allclose(got, want, rtol=1e-8, atol=0)
    np.testing.assert_allclose(got_one, want, rtol=1e-8, atol=0)
    # the closed-form-per-run variant measured beside the loop (not the compared pipeline)
    np.testing.assert_allclose(npb.log_density(u, recurrence="runs"), want, rtol=1e-8, atol=0)
    # what emcee uses is differences of log-densities: those agree in absolute terms too
    np.testing.assert_allclose(np.diff(got), np.diff(want), rtol=0, atol=1e-6)
    # the points are not in a flat region: the log-density varies by many units among them
    assert np.ptp(want[:3]) > 10

    # the optimiser's residual vector (whitened residuals, prior pseudo-residuals) and the
    # Laplace covariance's (the same without the likelihood's power, here 1)
    n = problem.n_nonlinear
    for jax_residuals in (_lm_objective_residuals, _lm_residuals):
        compiled = eqx.filter_jit(jax_residuals)
        for x in u[:2]:
            r_jax = np.asarray(compiled(jnp.asarray(x[:n]), (problem, jnp.asarray(x[n:]))))
            r_np = npb.lm_residuals(x[:n], x[n:])
            np.testing.assert_allclose(r_np, r_jax, rtol=0, atol=1e-8 * np.max(np.abs(r_jax)))
    r_batch = npb.lm_residuals(u[:2, :n], u[0, n:])
    np.testing.assert_allclose(r_batch[:, 0], npb.lm_residuals(u[0, :n], u[0, n:]), rtol=1e-12, atol=1e-12)


def test_numpy_log_density_rejects_non_finite(sim):
    """Non-finite u, and u whose log-density is NaN, give −inf, as in torsionfit."""
    problem, npb = _pair(sim, True, None)
    u = np.tile(np.concatenate([npb.prior_mean, [npb.noise_prior_mean, 0.0]]), (3, 1))
    u[1, 0] = np.nan
    u[2, 3] = 1e6  # gap = exp(1e6) = inf: inf · tanh(0) = NaN at the first sample
    lp = npb.log_density(u)
    assert np.isfinite(lp[0]) and lp[1] == -np.inf and lp[2] == -np.inf
    assert npb.log_density(u[1]) == -np.inf and npb.log_density(u[2]) == -np.inf
    want = np.asarray(jax.jit(jax.vmap(problem.log_density))(jnp.asarray(u)))
    np.testing.assert_array_equal(np.isfinite(lp), np.isfinite(want))
