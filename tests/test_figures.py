"""Fit figures a reader can use: physical units, posterior-predictive bands that hold the
nominal share of SYNTHETIC data, the true walker count, no one-point curves, bands in the
`make run` loop figure."""

import dataclasses
import warnings
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest

from torsionfit.bench import load_bench, simulate
from torsionfit.plots import (
    component_draws,
    kd_figure,
    pairs_figure,
    plot_loop_components,
    predictive_draws,
    te_figure,
    trace_figure,
    write_fit_figures,
)
from torsionfit.report import FitOptions, fit_campaign

#: one Laplace fit (~1 min on 2 shared cores) behind every test here
pytestmark = pytest.mark.slow

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
SOURCE = "SYNTHETIC test campaign"


@pytest.fixture(scope="module")
def laplace_fit(tmp_path_factory):
    """Laplace fit of a SYNTHETIC campaign (one loop, one TE run at one speed) with 1″ noise."""
    text = BENCH.read_text().replace("[truth]", "[noise]\nangle_sd_arcsec = 1.0\n[truth]")
    path = tmp_path_factory.mktemp("bench") / "bench.toml"
    path.write_text(text)
    sim = simulate(load_bench(path), seed=4)
    return fit_campaign(sim.campaign, FitOptions(sampler="laplace", n_starts=2, progress=False,
                                                 laplace_draws=1000, metric_draws=200), seed=0)


def _band_share(fit, run_index: int, seed: int) -> float:
    """Share of the run's samples inside the 95 % posterior-predictive band of 400 draws."""
    rng = np.random.default_rng(seed)
    u = fit.draws_u[rng.choice(len(fit.draws_u), 400, replace=False)]
    run = fit.campaign.runs[run_index]
    idx = np.arange(len(run))
    comps = component_draws(fit.problem, u, run_index, idx)
    observed = np.asarray(run.angle_rad if run.kind == "hysteresis" else run.te_rad)
    lo, hi = np.percentile(predictive_draws(fit.problem, u, run_index, idx, comps["total"], rng), [2.5, 97.5],
                           axis=0)
    return float(np.mean((observed >= lo) & (observed <= hi)))


@pytest.mark.parametrize("kind", ["hysteresis", "transmission_error"])
def test_predictive_band_holds_about_95_percent_of_the_data(laplace_fit, kind):
    """The band adds the noise to the model's spread: ~95 % of SYNTHETIC data fall inside
    (the model-only band of a TE run at 380 N·m holds a small share of it)."""
    i = next(k for k, r in enumerate(laplace_fit.campaign.runs) if r.kind == kind)
    assert 0.90 <= _band_share(laplace_fit, i, seed=1) <= 0.99


def test_pairs_are_in_physical_units(laplace_fit):
    fig = pairs_figure(laplace_fit, SOURCE)
    labels = [ax.get_xlabel() for ax in fig.axes if ax.get_xlabel()]
    assert "stiffness (N·m/arcmin)" in labels and "gap (arcmin)" in labels and "friction_torque (N·m)" in labels
    col = labels.index("stiffness (N·m/arcmin)")
    low, high = fig.axes[-len(labels) + col].get_xlim()  # bottom row, the stiffness column
    assert low < 108.0 < high and high - low < 5.0  # around the bench's 108 N·m/arcmin, not 3.7e5 N·m/rad
    plt.close(fig)


def test_trace_is_in_physical_units_with_the_true_walker_count(laplace_fit):
    from torsionfit.sample import ConvergenceWarning, run_sampler

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)  # a short chain, for the figure only
        result = run_sampler(laplace_fit.problem, laplace_fit.map_result, seed=0, n_walkers=40, max_steps=60,
                             check_every=30, min_steps=30, progress=False)
    fig = trace_figure(dataclasses.replace(laplace_fit, sample_result=result), SOURCE)
    title = fig._suptitle.get_text()
    assert "emcee trace, 16 of 40 walkers" in title
    assert fig.axes[0].get_ylabel() == "stiffness\n(N·m/arcmin)"
    low, high = fig.axes[0].get_ylim()
    assert 100.0 < low < 108.0 < high < 116.0
    assert "unconstrained" not in fig.axes[-1].get_xlabel()
    plt.close(fig)


def test_kd_at_one_speed_is_a_point_with_its_interval(laplace_fit):
    fig = kd_figure(laplace_fit, SOURCE)
    ax = fig.axes[0]
    assert "one speed per condition" in " ".join(ax.get_title().split())
    (line,) = [ln for ln in ax.get_lines() if len(ln.get_xdata()) == 1 and ln.get_marker() == "o"]
    assert line.get_linestyle() == "None"  # a point, no curve
    assert ax.get_xlim()[0] == 0.0
    plt.close(fig)


def test_te_figure_labels(laplace_fit):
    rng = np.random.default_rng(0)
    i = next(k for k, r in enumerate(laplace_fit.campaign.runs) if r.kind == "transmission_error")
    run = laplace_fit.campaign.runs[i]
    idx = np.arange(len(run))
    comps = component_draws(laplace_fit.problem, laplace_fit.draws_u[:50], i, idx)
    total = comps["total"] - comps["offset"]
    measured = np.asarray(run.te_rad) - np.median(comps["offset"], axis=0)
    fig = te_figure([(run, idx, measured, predictive_draws(laplace_fit.problem, laplace_fit.draws_u[:50], i, idx,
                                                           total, rng))], SOURCE)
    ax = fig.axes[0]
    assert ax.get_xlabel() == "output angle (°)" and ax.get_ylabel() == "TE − TE₀ (arcmin)"
    assert "posterior predictive" in ax.get_legend().get_title().get_text()
    plt.close(fig)


def test_write_fit_figures_writes_no_trace_for_laplace_draws(laplace_fit, tmp_path):
    names = sorted(p.name for p in write_fit_figures(laplace_fit, tmp_path))
    assert names == ["components-hyst-5.png", "kd-vs-speed.png", "loop-hyst-5.png", "pairs.png", "te-vs-angle.png"]


def test_loop_components_figure_draws_bands(laplace_fit):
    """`make run`'s loop figure: a shaded band around the model when draws are given."""
    run = laplace_fit.campaign.runs[0]
    idx = np.arange(len(run))
    draws = component_draws(laplace_fit.problem, laplace_fit.draws_u[:100], 0, idx)
    fig = plot_loop_components(run, laplace_fit.map_result.components()[0], source=SOURCE, draws=draws,
                               draws_label="95 % of 100 Laplace draws")
    loop = fig.axes[0]
    assert len(loop.collections) == 1  # the band
    assert any(t.get_text().startswith("model, 95 % of 100 Laplace draws (at most ")
               for t in loop.get_legend().get_texts())
    plt.close(fig)
