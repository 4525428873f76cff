"""``posterior.nc`` opened with plain ArviZ, as a user would: for a Laplace fit and an emcee fit
of the same SYNTHETIC small campaign (short settings), ``az.summary`` of the catalog metrics,
``az.loo`` with no argument (every Pareto k finite), ``az.compare`` of the two fits and a plot
(matplotlib Agg); the tree's one sample grid, its metrics (the same draws as fit.json's) and
the constant data a loop is re-plotted from.

The fits start from the bench's truth instead of a MAP (its compilation alone takes ~20 s):
emcee runs 300 steps from there, and the Laplace fit's stand-in for the MAP's Gaussian is the
truth with the covariance of those emcee draws.
"""

import json
import warnings
from types import SimpleNamespace

import arviz as az
import matplotlib
import numpy as np
import pytest

import torsionfit  # noqa: F401
from torsionfit.report import FitOptions, finish_fit, write_fit
from torsionfit.sample import ConvergenceWarning, draw_thinning, psis_loo, run_sampler

from test_sample import small  # noqa: F401  (the SYNTHETIC small campaign, its problem and a start at the truth)

matplotlib.use("Agg")

METRICS = ["stiffness_elastic", "lost_motion", "backlash", "stiffness_loading", "kd_mean"]


@pytest.fixture(scope="module")
def fits(small, tmp_path_factory):
    """{"emcee": ..., "laplace": ...}: the fit, its fit.json and its posterior.nc path."""
    problem = small.problem
    with pytest.warns(ConvergenceWarning):
        res = run_sampler(problem, small.start, seed=0, max_steps=300, check_every=150, progress=False)
    stand_in = SimpleNamespace(u=small.start.u, cov=np.cov(res.flat().T), converged=True, newton_step_sd=None,
                               message="SYNTHETIC stand-in for the MAP: the truth, the emcee draws' covariance")
    out = {}
    for sampler in ("emcee", "laplace"):
        options = FitOptions(sampler=sampler, metric_draws=200, laplace_draws=400, progress=False)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            fit = finish_fit(small.sim.campaign, options, problem.model, problem, stand_in, seed=0,
                             sample_result=res if sampler == "emcee" else None)
        folder = tmp_path_factory.mktemp(sampler)
        write_fit(fit, folder)
        out[sampler] = SimpleNamespace(fit=fit, doc=json.loads((folder / "fit.json").read_text()),
                                       path=folder / "posterior.nc")
    return out


@pytest.mark.parametrize("sampler", ["emcee", "laplace"])
def test_summary_and_loo_in_plain_arviz(fits, sampler):
    f = fits[sampler]
    assert f.path.is_file()  # written by every sampler
    dt = az.from_netcdf(f.path)
    for g in ("posterior", "posterior_predictive", "log_likelihood", "observed_data", "constant_data", "sample_stats"):
        assert g in dt.children, g
    post = dt["posterior"]
    assert dt["sample_stats"].attrs["sampler"] == sampler
    if sampler == "laplace":
        assert post.sizes["chain"] == 1 and "Laplace" in post.attrs["posterior_kind"]

    # the catalog metrics per draw, in fit.json's units, the same draws as fit.json's summaries
    summary = az.summary(dt, var_names=METRICS + ["stiffness"])
    assert np.all(np.isfinite(summary["mean"].to_numpy(dtype=float)))
    for name in ("stiffness_elastic", "lost_motion", "backlash", "stiffness_loading"):
        entry = f.doc["metrics"][name]
        assert post[name].attrs["units"] == entry["unit"] and post[name].attrs["role"] == "metric"
        assert float(post[name].mean()) == pytest.approx(entry["mean"], rel=1e-12)
    assert float(post["stiffness_elastic"].mean()) == pytest.approx(108.0, rel=0.02)  # the bench's K in N·m/arcmin
    te = [r.name for r in small_runs(f) if r.kind == "transmission_error"]
    assert list(post["kd_mean"]["te_run"].values) == te
    assert "friction_torque" in post and "catalog_metric" in post["friction_torque"].attrs  # stored once

    # the log-likelihood on the posterior's own grid, one variable: az.loo needs no argument
    ll = dt["log_likelihood"]
    assert list(ll.data_vars) == ["angle"]
    for d in ("chain", "draw"):
        np.testing.assert_array_equal(ll[d].values, post[d].values)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pareto-k warnings of a short run
        loo = az.loo(dt, pointwise=True)
        ours = psis_loo(dt)
    n_obs = sum(len(y) for y in f.fit.problem.y)
    assert loo.n_data_points == n_obs and loo.n_samples == post.sizes["chain"] * post.sizes["draw"]
    assert np.all(np.isfinite(loo.pareto_k.values)) and np.isfinite(loo.elpd) and np.isfinite(loo.se)
    if sampler == "emcee":
        assert ours.elpd == pytest.approx(loo.elpd)
    else:  # corrected by the importance ratios of the approximation's draws
        assert ours.approx_posterior and np.isfinite(ours.elpd)


def small_runs(f):
    return f.fit.campaign.runs


def test_compare_two_fits_and_plot(fits, tmp_path):
    trees = {name: az.from_netcdf(f.path) for name, f in fits.items()}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        table = az.compare(trees)
    assert set(table.index) == {"emcee", "laplace"} and np.all(np.isfinite(table["elpd"].to_numpy(dtype=float)))
    pc = az.plot_forest(trees["emcee"], var_names=["stiffness_elastic", "lost_motion", "backlash"], backend="matplotlib")
    pc.savefig(tmp_path / "forest.png")
    assert (tmp_path / "forest.png").stat().st_size > 0


def test_a_loop_replots_from_the_file(fits):
    """Torque and time from constant_data, the angle from observed_data, per run by name."""
    dt = az.from_netcdf(fits["emcee"].path)
    obs, const = dt["observed_data"], dt["constant_data"]
    for run in small_runs(fits["emcee"]):
        mine = obs["run"].values == run.name
        np.testing.assert_array_equal(obs["run_sample"].values[mine], np.arange(len(run)))
        if run.kind == "hysteresis":
            np.testing.assert_array_equal(const["torque"].values[mine], run.torque_Nm)
            np.testing.assert_array_equal(const["time"].values[mine], run.time_s)
            np.testing.assert_array_equal(obs["angle"].values[mine], run.angle_rad)
            assert np.all(np.isnan(const["output_angle"].values[mine]))
        else:
            np.testing.assert_array_equal(const["output_angle"].values[mine], run.output_angle_rad)
            np.testing.assert_array_equal(obs["angle"].values[mine], run.te_rad)
    assert const["torque"].attrs["units"] == "N·m" and obs["angle"].attrs["units"] == "rad"


def test_draw_thinning():
    """Every k-th draw of each chain within the limit, the smallest such k, a multiple of step."""
    for n_chain, n_draw, limit, step in [(32, 198, 2000, 1), (32, 198, 100, 1), (4, 500, 2000, 1), (4, 500, 200, 3),
                                         (40, 10, 16, 1)]:
        k = draw_thinning(n_chain, n_draw, limit, step)
        kept = n_chain * len(range(0, n_draw, k))
        assert k % step == 0
        assert kept <= limit or k >= n_draw  # at least one draw per chain
        if k > step:
            assert n_chain * len(range(0, n_draw, k - step)) > limit
    assert draw_thinning(32, 198, 10_000) == 1
