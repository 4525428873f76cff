"""fit/_misfit.py: the long-run variance ratio of the whitened residuals is ~1 when the model
holds and large when the data carry structure the model lacks (SYNTHETIC benches)."""

from pathlib import Path

import numpy as np
import pytest

from torsionfit.bench import load_bench, simulate
from torsionfit.fit import build_problem, fit_map
import jax.numpy as jnp

from torsionfit.fit._misfit import misfit_inflation, misfit_variance_ratio, widened
from torsionfit.model import model_with_effects

BENCH = Path(__file__).parent / "benches" / "stat_rv_white.toml"


def _base_fit(bench_path, seed):
    campaign = simulate(load_bench(bench_path), seed=seed).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    problem = build_problem(campaign, model)
    return problem, fit_map(problem, n_starts=1, seed=0)


def test_white_residuals_leave_the_posterior_as_it_is():
    problem, result = _base_fit(BENCH, seed=3)
    ratios = misfit_variance_ratio(problem, result.u)
    assert np.all(ratios < 2.5), ratios
    assert misfit_inflation(problem, result.u) == 1.0
    assert widened(problem, result, 1.0) == (problem, result)  # nothing to widen: the same objects
    # widened by 4: the likelihood to the power 1/4 (prior and the linear block's term unchanged),
    # the physics block of the Laplace covariance that of the tempered density, the MAP kept
    tempered, wide = widened(problem, result, 4.0)
    u = jnp.asarray(result.u)
    ll = sum(float(jnp.sum(x)) for x in problem.pointwise_log_likelihood(u))
    assert float(tempered.log_density(u)) - float(problem.log_density(u)) == \
        pytest.approx(-0.75 * ll, rel=1e-9, abs=1e-6)
    n = problem.n_nonlinear
    # precision: the likelihood's curvature / 4 + the prior's (untouched), so between the
    # untempered covariance and 4× it, and never wider than the prior in any direction
    prior_precision = np.diag(1.0 / np.asarray(problem.prior_sd) ** 2)
    precision, precision0 = np.linalg.inv(wide.cov[:n, :n]), np.linalg.inv(result.cov[:n, :n])
    np.testing.assert_allclose(precision, (precision0 - prior_precision) / 4.0 + prior_precision,
                               rtol=1e-6, atol=1e-8 * np.abs(precision0).max())
    sd, sd0 = np.sqrt(np.diag(wide.cov[:n, :n])), np.sqrt(np.diag(result.cov[:n, :n]))
    assert np.all(sd >= sd0 * (1 - 1e-9)) and np.all(sd <= 2.0 * sd0 * (1 + 1e-9))
    assert np.all(sd <= np.asarray(problem.prior_sd) * (1 + 1e-9))
    assert np.allclose(wide.cov[n:, n:], result.cov[n:, n:]) and np.array_equal(wide.u, result.u)
    assert wide.problem is tempered


def test_widening_keeps_a_parameter_the_data_do_not_inform_within_its_prior():
    """However large the widening, no sd exceeds its prior's, and as the factor grows the
    covariance tends to the prior's: a direction the data do not inform stays within its prior
    (scaling the whole covariance by the factor took it √factor times past it)."""
    from torsionfit.fit._misfit import tempered_physics_covariance

    problem, result = _base_fit(BENCH, seed=3)
    n = problem.n_nonlinear
    for factor in (4.0, 100.0):
        sd = np.sqrt(np.diag(tempered_physics_covariance(problem, result.u, factor)))
        assert np.all(sd <= np.asarray(problem.prior_sd) * (1 + 1e-9)), factor
    # with factor → ∞ the covariance tends to the prior's
    wide = tempered_physics_covariance(problem, result.u, 1e12)
    np.testing.assert_allclose(np.sqrt(np.diag(wide)), np.asarray(problem.prior_sd), rtol=1e-4)
    assert wide.shape == (n, n)


def test_structure_the_model_lacks_widens_it(tmp_path):
    # the same bench with a strong stiffness asymmetry, fitted by the base model (no asymmetry)
    text = BENCH.read_text().replace("[truth]\n", "[truth]\ncompliance_asymmetry = 0.3\n")
    path = tmp_path / "bench.toml"
    path.write_text(text + "[effects]\nasymmetry = true\n")
    problem, result = _base_fit(path, seed=3)
    # the AR(1) coefficient absorbs part of it (ρ rises): the ratio stays well above the white one
    assert misfit_inflation(problem, result.u) > 2.0


def test_a_slow_misfit_drives_the_ar1_coefficient_to_its_bound_and_is_named():
    """A smooth, ramp-long structure the model lacks (here a slow sinusoid of 20″ against ~1″ of
    noise, added to the readings) drives a hysteresis run's AR(1) coefficient to its bound:
    ``misfit_correlated_runs`` names such runs (fit.json's ``ar1_misfit_runs`` and
    ``noise_note``); a model that holds has none."""
    import dataclasses

    from torsionfit.fit._misfit import MISFIT_RHO, misfit_correlated_runs
    from torsionfit.io import HysteresisRun
    from torsionfit.report._pipeline import noise_note

    campaign = simulate(load_bench(BENCH), seed=3).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    clean = build_problem(campaign, model)
    assert misfit_correlated_runs(clean, fit_map(clean, n_starts=1, seed=0).u) == {}
    arcsec = np.pi / 180 / 3600
    runs = tuple(dataclasses.replace(r, angle_rad=r.angle_rad + 20 * arcsec * np.sin(5 * np.pi * (r.time_s - r.time_s[0]) / np.ptp(r.time_s)))
                 if isinstance(r, HysteresisRun) else r for r in campaign.runs)
    problem = build_problem(dataclasses.replace(campaign, runs=runs), model)
    result = fit_map(problem, n_starts=1, seed=0)
    near = misfit_correlated_runs(problem, result.u)
    hysteresis = [i for i, r in enumerate(runs) if isinstance(r, HysteresisRun)]
    assert sorted(near) == hysteresis and all(MISFIT_RHO <= rho <= 0.995 for rho in near.values()), near
    note = noise_note({"hyst": near[hysteresis[0]]})
    assert "hyst (ρ 0.99" in note and "--ar1 off" in note
