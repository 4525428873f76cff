"""report/_follows.py: a fit that does not follow its data is reported not converged, whatever
the optimiser said (SYNTHETIC data from the virtual bench)."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from torsionfit.bench import load_bench, simulate
from torsionfit.io import HysteresisRun
from torsionfit.report import FitOptions
from torsionfit.report._follows import runs_left_by_posterior, runs_not_followed, straight_line_rmse

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"


def _run(name, torque, angle):
    t = np.arange(len(torque), dtype=float)
    return HysteresisRun(name=name, time_s=t, torque_Nm=np.asarray(torque, float), angle_rad=np.asarray(angle, float))


def test_straight_line_rmse_is_the_least_squares_line():
    tau = np.linspace(-10.0, 10.0, 201)
    assert straight_line_rmse(tau, 0.3 + 2e-3 * tau) == pytest.approx(0.0, abs=1e-15)
    # a square loop of half-width w about the line: every sample is w away from it
    w = 1e-3
    tau2 = np.concatenate([tau, tau[::-1]])
    angle = 2e-3 * tau2 + np.where(np.arange(tau2.size) < tau.size, -w, w)
    assert straight_line_rmse(tau2, angle) == pytest.approx(w, rel=1e-9)


def test_only_hysteresis_runs_worse_than_their_line_are_named():
    tau = np.linspace(-5.0, 5.0, 50)
    rng = np.random.default_rng(0)
    angle = 1e-3 * tau + 1e-4 * rng.standard_normal(tau.size)
    line = straight_line_rmse(tau, angle)
    good, bad = _run("good", tau, angle), _run("bad", tau, angle)
    got = runs_not_followed([good, bad], [np.full(tau.size, 0.5 * line), np.full(tau.size, 2.0 * line)])
    assert [b["run"] for b in got] == ["bad"]
    assert got[0]["rmse_arcsec"] == pytest.approx(2.0 * got[0]["line_rmse_arcsec"])
    # residuals that do not belong to the run's samples are not judged
    assert runs_not_followed([bad], [np.full(tau.size - 1, 2.0 * line)]) == []


def test_a_posterior_that_leaves_the_map_or_the_line_is_named():
    """The posterior's median is held to the straight line and to twice the MAP's RMSE."""
    tau = np.linspace(-5.0, 5.0, 50)
    angle = 1e-3 * tau + np.where(np.arange(tau.size) % 2, 1e-4, -1e-4)
    line = straight_line_rmse(tau, angle)
    run = _run("loop", tau, angle)
    small = np.full(tau.size, 0.1 * line)
    assert runs_left_by_posterior([run], [1.5 * small], [small]) == []
    far = runs_left_by_posterior([run], [2.5 * small], [small])
    assert [b["run"] for b in far] == ["loop"] and far[0]["map_rmse_arcsec"] < far[0]["rmse_arcsec"]
    assert runs_left_by_posterior([run], [np.full(tau.size, 1.1 * line)], [np.full(tau.size, 0.9 * line)])


@pytest.fixture(scope="module")
def prepared():
    from torsionfit.fit import fit_map
    from torsionfit.report._pipeline import prepare_fit

    sim = simulate(load_bench(BENCH), seed=2)
    options = FitOptions(sampler="laplace", n_starts=1, misfit_inflation=False)
    campaign, model, problem = prepare_fit(sim.campaign, options)
    map_result = fit_map(problem, [r.name for r in campaign.runs], n_starts=1, seed=0)
    return campaign, options, model, problem, map_result


def test_a_good_fit_follows_its_data(prepared):
    from torsionfit.report._pipeline import finish_fit

    fit = finish_fit(*prepared, seed=0)
    assert fit.diagnostics["follows_data"] is True
    assert fit.diagnostics["converged"] is True


def test_a_converged_optimum_far_from_the_data_is_not_converged(prepared):
    """An optimiser's "successful" at a point whose loop misses the data is not a result."""
    from torsionfit.report._pipeline import finish_fit

    campaign, options, model, problem, map_result = prepared
    assert map_result.converged
    names = problem.names([r.name for r in campaign.runs])
    u = np.array(map_result.u, dtype=float)
    # a much softer mesh: every loaded sample misses the data by far more than a line does
    i = next(k for k, n in enumerate(names) if "stiffness" in n)
    u[i] -= 3.0
    bad = dataclasses.replace(map_result, u=u)
    with pytest.warns(UserWarning, match="worse than a straight line"):
        fit = finish_fit(campaign, options, model, problem, bad, seed=0)
    d = fit.diagnostics
    assert d["follows_data"] is False and d["converged"] is False
    assert "straight line" in d["reason"] and d["not_followed"]
    assert d["map_converged"] is True  # the optimiser's word, kept beside the verdict
