"""Runs whose angle noise lies below the encoder step are named (fit/_quantisation.py)."""

import dataclasses
import warnings
from pathlib import Path

import numpy as np

from torsionfit.bench import load_bench, simulate
from torsionfit.fit import NoiseOptions, build_problem
from torsionfit.fit._quantisation import runs_below_the_encoder_step
from torsionfit.model import model_with_effects

WHITE = Path(__file__).parent / "benches" / "stat_rv_white.toml"
ARCSEC = np.pi / (180 * 3600)


def _problem(angle_sd_arcsec: float):
    bench = load_bench(WHITE)
    bench = dataclasses.replace(bench, noise=dataclasses.replace(bench.noise, angle_sd_arcsec=angle_sd_arcsec))
    campaign = simulate(bench, seed=3).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    return campaign, build_problem(campaign, model, NoiseOptions())


def _u(problem, noise_arcsec: float, ar1_logit: float = -30.0):
    """At the priors' centre, innovation sd ``noise_arcsec`` above the floor, ρ from its logit."""
    return np.concatenate([np.asarray(problem.prior_mean), np.full(problem.n_runs, np.log(noise_arcsec * ARCSEC)),
                           np.full(problem.n_ar1, ar1_logit)])


def test_a_hysteresis_run_whose_noise_is_under_the_floor_is_named_and_te_runs_are_not():
    campaign, problem = _problem(0.0)
    names = [r.name for r in campaign.runs]
    floor = 1.0 / np.sqrt(12.0)  # the bench's 1″ encoder
    below = runs_below_the_encoder_step(problem, _u(problem, 0.1), names)
    assert list(below) == ["hyst-20"], below  # the TE runs' angle is the TE, not one encoder's reading
    assert abs(below["hyst-20"]["floor_arcsec"] - floor) < 1e-9
    assert abs(below["hyst-20"]["noise_arcsec"] - 0.1) < 1e-9
    assert runs_below_the_encoder_step(problem, _u(problem, 1.0), names) == {}
    # AR(1) noise: its marginal sd is compared, s/√(1 − ρ²) — a small innovation of a noise that
    # wanders far is no rounding
    assert problem.ar1[0]
    assert runs_below_the_encoder_step(problem, _u(problem, 0.1, ar1_logit=8.0), names) == {}


def test_a_fit_of_a_loop_whose_only_angle_noise_is_the_rounding_says_so():
    """SYNTHETIC: the encoder's 1″ steps and torque noise only — fit.json's diagnostics name the
    run, the summary prints the line and the fit warns (with 1″ of angle noise above the steps
    the fitted noise is above the floor: the test above)."""
    from torsionfit.report import FitOptions, fit_campaign, fit_json, summary_table

    options = FitOptions(sampler="laplace", n_starts=1, laplace_draws=200, metric_draws=20, progress=False)
    campaign, _ = _problem(0.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        doc = fit_json(fit_campaign(campaign, options, seed=0))
    d = doc["diagnostics"]
    assert list(d["quantisation_runs"]) == ["hyst-20"], d.get("quantisation_runs")
    assert d["quantisation_runs"]["hyst-20"]["noise_arcsec"] < d["quantisation_runs"]["hyst-20"]["floor_arcsec"]
    assert "noise: angle noise below the encoder step on hyst-20" in summary_table(doc)
    assert any("below the encoder step" in str(w.message) for w in caught)
