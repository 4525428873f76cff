"""Posterior sampling (emcee) and the ArviZ tree: convergence logic, HDF5 resume, NaN-safety,
tree layout, netCDF round trip, diagnostics.

The sampler's machinery is tested on a toy Gaussian problem (known answer, fast); the tree
on a short run of a real small campaign started at the bench's truth (no MAP: its
compilation alone takes ~20 s); the full MAP → converged chain on that campaign, against the
Laplace approximation, is in tests/test_nuts.py beside NUTS on the same campaign.
"""

import math
import re
import warnings
from pathlib import Path
from types import SimpleNamespace

import arviz
import emcee
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr

import torsionfit  # noqa: F401  (enables float64 in JAX)
from torsionfit.sample import (
    ConvergenceWarning,
    SampleResult,
    convergence_summary,
    default_n_walkers,
    load_tree,
    psis_loo,
    run_sampler,
    save_tree,
    to_datatree,
)
from torsionfit.sample import _emcee
from torsionfit.sample._emcee import MOVES_DESCRIPTION, batch_log_density, _LogProb, _regularised_cov, initial_walkers
from torsionfit.sample._laplace_move import LaplaceMove
from torsionfit.sample._tree import _ar1_noise

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
GROUPS = ("posterior", "posterior_predictive", "log_likelihood", "observed_data", "sample_stats")


# --- a toy problem with a known posterior ----------------------------------------------------
class GaussianProblem(eqx.Module):
    """N(mean, cov) in u: what ``run_sampler`` needs of a FitProblem (``dim``, ``log_density``)."""

    mean: jnp.ndarray
    precision: jnp.ndarray

    @property
    def dim(self) -> int:
        return int(self.mean.shape[0])

    def log_density(self, u):
        d = u - self.mean
        return -0.5 * d @ self.precision @ d


def _toy(dim=3, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(dim, dim))
    cov = a @ a.T / dim + np.eye(dim)
    mean = np.arange(dim, dtype=float)
    problem = GaussianProblem(jnp.asarray(mean), jnp.asarray(np.linalg.inv(cov)))
    start = SimpleNamespace(u=mean, cov=cov, names=[f"x{i}" for i in range(dim)])
    return problem, start, mean, cov


FAST = dict(check_every=100, min_steps=300, progress=False)


def test_default_n_walkers():
    for dim in (1, 5, 14, 15, 40):
        n = default_n_walkers(dim)
        assert n % 2 == 0 and n >= 32 and n >= 2 * dim + 2


def test_regularised_cov_is_positive_definite():
    bad = np.array([[1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0]])  # singular, zero variance
    bad[0, 2] = np.nan
    cov = _regularised_cov(bad)
    assert np.all(np.isfinite(cov))
    np.linalg.cholesky(cov)
    assert np.allclose(np.diag(cov)[:2], 1.0)


def test_toy_converges_and_matches_target():
    problem, start, mean, cov = _toy()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConvergenceWarning)
        res = run_sampler(problem, start, seed=1, **FAST)
    assert isinstance(res, SampleResult)
    assert res.converged and res.reason == ""
    assert res.n_steps > 50 * res.tau_max and res.n_steps >= 300
    assert res.burn_in == math.ceil(2 * res.tau_max)
    assert res.thin == max(1, int(np.min(res.tau) // 2))
    w = default_n_walkers(3)
    assert res.chain.shape == (res.n_draws, w, 3) and res.log_prob.shape == (res.n_draws, w)
    assert res.acceptance_rate.shape == res.log_prob.shape
    assert res.acceptance_fraction.shape == (w,) and 0.2 < res.acceptance_fraction.mean() < 0.8
    assert res.names == ("x0", "x1", "x2")
    draws = res.flat()
    sd = np.sqrt(np.diag(cov))
    # MC error of the mean is ≈ sd / √ESS; ESS is in the hundreds here
    assert np.all(np.abs(draws.mean(0) - mean) < 0.25 * sd)
    assert np.allclose(draws.std(0), sd, rtol=0.15)


def test_same_seed_same_chain():
    problem, start, *_ = _toy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        a = run_sampler(problem, start, seed=3, max_steps=200, **FAST)
        b = run_sampler(problem, start, seed=3, max_steps=200, **FAST)
        c = run_sampler(problem, start, seed=4, max_steps=200, **FAST)
    assert np.array_equal(a.chain, b.chain)
    assert not np.array_equal(a.chain, c.chain)


def test_max_steps_gives_unconverged_with_warning():
    problem, start, *_ = _toy()
    with pytest.warns(ConvergenceWarning, match=r"not converged after 200 steps"):
        res = run_sampler(problem, start, seed=0, max_steps=200, **FAST)
    assert not res.converged
    assert "200" in res.reason and re.search(r"50 × τ_max|τ_max still changing|min_steps", res.reason)
    assert res.n_steps == 200
    assert res.chain.shape[0] >= 2  # burn-in / thinning capped: something is left


def test_hdf5_resume_continues_the_same_chain(tmp_path):
    problem, start, *_ = _toy()
    never = dict(FAST, tau_factor=1e4)  # every run goes to max_steps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        whole = run_sampler(problem, start, seed=5, max_steps=400, backend_path=tmp_path / "a.h5", **never)
        part = run_sampler(problem, start, seed=5, max_steps=200, backend_path=tmp_path / "b.h5", **never)
        first = emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).get_chain()
        assert first.shape[0] == 200 and part.n_steps == 200
        # "interrupted" after 200 steps: resume to 400 (the seed is not used on resume)
        resumed = run_sampler(problem, start, seed=99, max_steps=400, backend_path=tmp_path / "b.h5",
                              resume=True, **never)
    full_a = emcee.backends.HDFBackend(str(tmp_path / "a.h5"), read_only=True).get_chain()
    full_b = emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).get_chain()
    assert full_b.shape == (400, default_n_walkers(3), 3)
    assert np.array_equal(full_b[:200], first)  # the stored part is kept
    assert np.array_equal(full_b, full_a)  # and continued exactly as an uninterrupted run
    assert resumed.n_steps == whole.n_steps == 400
    assert np.array_equal(resumed.chain, whole.chain)
    # without resume the file is overwritten
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        run_sampler(problem, start, seed=5, max_steps=100, backend_path=tmp_path / "b.h5", **never)
    assert emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).iteration == 100


def _interrupted_run(monkeypatch, dies_at: int, *args, **kwargs) -> None:
    """run_sampler(*args, **kwargs) with a KeyboardInterrupt in step ``dies_at`` (while the
    backend stores it)."""
    from torsionfit.sample import _emcee

    real_save, saves = _emcee.BufferedHDFBackend.save_step, []

    def flaky(self, state, accepted):
        saves.append(1)
        if len(saves) == dies_at:
            raise KeyboardInterrupt
        return real_save(self, state, accepted)

    monkeypatch.setattr(_emcee.BufferedHDFBackend, "save_step", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_sampler(*args, **kwargs)
    monkeypatch.setattr(_emcee.BufferedHDFBackend, "save_step", real_save)


def test_interrupted_run_keeps_its_steps_and_resumes_exactly(tmp_path, monkeypatch):
    """A KeyboardInterrupt in the middle of a block: the completed steps are on disk, and a
    resumed run ends with the chain of an uninterrupted one."""
    problem, start, *_ = _toy()
    never = dict(FAST, tau_factor=1e4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        run_sampler(problem, start, seed=7, max_steps=300, backend_path=tmp_path / "a.h5", **never)
        # dies in step 125, after the first block's 100 steps
        _interrupted_run(monkeypatch, 125, problem, start, seed=7, max_steps=300,
                         backend_path=tmp_path / "b.h5", **never)
        stored = emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).iteration
        assert stored == 124  # every completed step, including those of the unfinished block
        res = run_sampler(problem, start, seed=0, max_steps=300, backend_path=tmp_path / "b.h5",
                          resume=True, **never)
        # resuming a chain that already has max_steps: judged as it is, nothing added
        again = run_sampler(problem, start, seed=0, max_steps=300, backend_path=tmp_path / "b.h5",
                            resume=True, **never)
    a = emcee.backends.HDFBackend(str(tmp_path / "a.h5"), read_only=True).get_chain()
    b = emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).get_chain()
    assert res.n_steps == 300 and np.array_equal(a, b)
    assert again.n_steps == 300 and not again.converged and again.reason


def _bad_laplace(dim=3):
    """The toy with a Laplace approximation far off: centred 3 sd away, 100× too narrow."""
    problem, start, mean, cov = _toy(dim)
    bad = SimpleNamespace(u=mean + 3 * np.sqrt(np.diag(cov)), cov=cov * 1e-4, names=start.names)
    return problem, bad, mean, cov


def test_laplace_move_kept_where_its_proposals_are_accepted():
    problem, start, *_ = _toy()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        res = run_sampler(problem, start, seed=1, **FAST)
    assert res.moves == MOVES_DESCRIPTION


def test_laplace_move_retired_where_its_proposals_are_rejected():
    """Its share of the steps goes to DE after the first check; the chain still finds the
    posterior (the walkers start 3 sd off, around the bad approximation)."""
    problem, bad, mean, cov = _bad_laplace()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        res = run_sampler(problem, bad, seed=1, max_steps=3000, **FAST)
    assert res.moves.startswith(MOVES_DESCRIPTION + "; LaplaceMove retired at step 100 (acceptance 0.0")
    draws = res.flat()
    sd = np.sqrt(np.diag(cov))
    assert np.all(np.abs(draws.mean(0) - mean) < 0.25 * sd)
    assert np.allclose(draws.std(0), sd, rtol=0.2)


def test_retired_laplace_move_proposes_as_de():
    move = LaplaceMove(np.zeros(2), np.eye(2))
    assert np.isnan(move.acceptance)
    move.restore({"laplace_proposed": 40, "laplace_accepted": 1, "laplace_retired": 1})
    assert move.retired and move.acceptance == 1 / 40
    assert move.counters() == {"laplace_proposed": 40, "laplace_accepted": 1, "laplace_retired": 1}
    called = []
    move._fallback = SimpleNamespace(propose=lambda model, state: called.append(1) or (state, None))
    move.propose(None, "state")
    assert called == [1] and move.proposed == 40  # a retired move no longer counts


@pytest.mark.parametrize("dies_at", [60, 125])
def test_resume_with_a_retired_laplace_move_is_exact(tmp_path, monkeypatch, dies_at):
    """Interrupted before (60) or after (125) the Laplace move is retired at step 100: the
    resumed chain is the uninterrupted one (the move's counters are stored with every step)."""
    problem, bad, *_ = _bad_laplace()
    never = dict(FAST, tau_factor=1e4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        whole = run_sampler(problem, bad, seed=7, max_steps=300, backend_path=tmp_path / "a.h5", **never)
        _interrupted_run(monkeypatch, dies_at, problem, bad, seed=7, max_steps=300,
                         backend_path=tmp_path / "b.h5", **never)
        res = run_sampler(problem, bad, seed=0, max_steps=300, backend_path=tmp_path / "b.h5",
                          resume=True, **never)
    a = emcee.backends.HDFBackend(str(tmp_path / "a.h5"), read_only=True).get_chain()
    b = emcee.backends.HDFBackend(str(tmp_path / "b.h5"), read_only=True).get_chain()
    assert "retired at step 100" in whole.moves and res.moves == whole.moves
    assert np.array_equal(a, b) and np.array_equal(res.chain, whole.chain)


def test_resume_rejects_another_problem(tmp_path):
    problem, start, *_ = _toy(3)
    other, other_start, *_ = _toy(4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        run_sampler(problem, start, seed=0, max_steps=100, backend_path=tmp_path / "c.h5", **FAST)
        with pytest.raises(ValueError, match="dimension"):
            run_sampler(other, other_start, seed=0, max_steps=200, backend_path=tmp_path / "c.h5",
                        resume=True, **FAST)


def test_ar1_noise_has_the_stated_variance_and_correlation():
    rho, n = 0.8, 200_000
    x = np.asarray(_ar1_noise(jax.random.PRNGKey(0), jnp.full(n, 2.0), rho, None))
    assert np.var(x) == pytest.approx(4.0 / (1 - rho**2), rel=0.05)
    assert np.corrcoef(x[1:], x[:-1])[0, 1] == pytest.approx(rho, abs=0.01)


# --- a real small campaign ----------------------------------------------------------------
@pytest.fixture(scope="module")
def small(tmp_path_factory):
    """A base-model campaign at 1 Hz (a few hundred samples per run), its problem, and a
    start at the bench's truth (a stand-in for the MAP, which takes long to compile)."""
    from torsionfit.bench import load_bench, simulate
    from torsionfit.fit import build_problem
    from torsionfit.model import model_with_effects

    path = tmp_path_factory.mktemp("bench") / "bench.toml"
    path.write_text(BENCH.read_text().replace("sample_rate_Hz = 5.0", "sample_rate_Hz = 1.0"))
    sim = simulate(load_bench(path), seed=0)
    runs = [r.name for r in sim.campaign.runs]
    model = model_with_effects([r.kind for r in sim.campaign.runs], {}, sim.campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    problem = build_problem(sim.campaign, model)
    truth = {k: np.asarray(v) for k, v in sim.truth.items()}
    truth.setdefault("friction_start", np.zeros(model.n_hysteresis))
    u = np.concatenate([problem.physics_u(truth), np.zeros(problem.n_torque_lines),
                        np.full(problem.n_runs, np.log(1e-6)), np.zeros(problem.n_ar1)])
    sd = np.concatenate([0.01 * np.asarray(problem.prior_sd), np.full(problem.n_runs + problem.n_ar1, 0.1)])
    start = SimpleNamespace(u=u, cov=np.diag(sd**2), names=problem.names(runs))
    return SimpleNamespace(sim=sim, runs=runs, problem=problem, start=start)


@pytest.fixture(scope="module")
def short_tree(small):
    with pytest.warns(ConvergenceWarning):
        res = run_sampler(small.problem, small.start, seed=0, max_steps=300, check_every=150,
                          progress=False)
    tree = to_datatree(small.problem, res, small.runs, campaign=small.sim.campaign, seed=0)
    return res, tree


def test_log_density_never_nan(small):
    logp = _LogProb(small.problem)
    dim = small.problem.dim
    absurd = np.array([
        np.full(dim, 1e300), np.full(dim, -1e300), np.full(dim, 800.0), np.full(dim, -800.0),
        np.full(dim, np.nan), np.full(dim, np.inf),
        np.where(np.arange(dim) == 0, 1e308, small.start.u),
    ])
    # padded to 32 rows with a sensible point: the batch shape the sampler compiles anyway
    batch = np.concatenate([absurd, np.tile(small.start.u, (32 - len(absurd), 1))])
    lp = logp(batch)
    assert lp.shape == (32,)
    assert not np.any(np.isnan(lp))
    assert np.all(lp[:len(absurd)] == -np.inf)
    assert np.all(np.isfinite(lp[len(absurd):]))


def test_log_density_in_fixed_batches_pads_without_changing_values(small):
    """Calls of any size are evaluated in chunks of one batch shape (one compilation): a row's
    value does not depend on the chunk or the padding it was evaluated with."""
    logp = _LogProb(small.problem, batch=16)
    rng = np.random.default_rng(4)
    rows = small.start.u + 1e-3 * rng.standard_normal((21, small.problem.dim))
    together = logp(rows)  # one full chunk and one padded chunk of 5 rows
    assert together.shape == (21,)
    shifted = logp(np.concatenate([rows[5:], rows[:5]]))  # the last 5 rows now in the full chunk
    np.testing.assert_allclose(together, np.concatenate([shifted[-5:], shifted[:-5]]), rtol=1e-12)
    assert np.all(np.isfinite(together))


def test_bound_log_density_is_batch_log_density_and_shares_its_program(small):
    """emcee's log-density splits the problem once: the same values bit for bit as the
    filter_jit one, and a problem differing only in its arrays' values (here the observed
    twist) reuses the compiled program instead of compiling again."""
    rng = np.random.default_rng(5)
    rows = small.start.u + 1e-3 * rng.standard_normal((16, small.problem.dim))
    bound = _emcee.bound_log_density(small.problem)
    np.testing.assert_array_equal(np.asarray(bound(rows)), np.asarray(batch_log_density(small.problem, rows)))
    programs = _emcee._split_program()._cache_size()
    arrays, _ = eqx.partition(small.problem, eqx.is_array)
    shifted = jax.tree.map(lambda x: x * (1 + 1e-3) if np.ndim(x) and np.size(x) > 100 else x, arrays)
    other = eqx.combine(shifted, eqx.partition(small.problem, eqx.is_array)[1])
    values = np.asarray(_emcee.bound_log_density(other)(rows))
    assert _emcee._split_program()._cache_size() == programs
    assert not np.array_equal(values, np.asarray(bound(rows)))  # the new arrays are used
    np.testing.assert_array_equal(values, np.asarray(batch_log_density(other, rows)))


def test_initial_walkers_are_finite_even_from_a_wide_laplace(small):
    cov = np.diag(np.full(small.problem.dim, 4.0))  # very wide: many draws are invalid
    walkers = initial_walkers(small.problem, small.start.u, cov, 32, np.random.default_rng(0))
    assert walkers.shape == (32, small.problem.dim)
    assert np.all(np.isfinite(_LogProb(small.problem)(walkers)))


def test_datatree_layout(small, short_tree):
    res, tree = short_tree
    problem, runs = small.problem, small.runs
    assert set(GROUPS) <= set(tree.children)
    post = tree["posterior"]
    n_walkers, n_draws = res.n_walkers, res.n_draws
    assert (post.sizes["chain"], post.sizes["draw"]) == (n_walkers, n_draws)
    for p in problem.model.parameters():
        assert p.name in post.data_vars, p.name
        assert post[p.name].attrs["units"] == p.unit
        assert post[p.name].dims[:2] == ("chain", "draw")
    assert post["stiffness"].dims == ("chain", "draw")
    assert post["stiffness"].attrs["units"] == "N·m/rad"
    assert post["angle_offset"].dims == ("chain", "draw", "hysteresis_run")
    assert list(post["hysteresis_run"].values) == ["hyst-5"]
    assert post["noise_sigma"].dims == ("chain", "draw", "run") and post["noise_sigma"].attrs["units"] == "rad"
    assert post["ar1_rho"].dims == ("chain", "draw", "ar1_run")
    assert post["torque_line_correction"].sizes["torque_line"] == problem.n_torque_lines
    assert {post[k].attrs["role"] for k in post.data_vars} == {"model", "noise", "latent"}
    # posterior values are the draws mapped to SI (stiffness = exp(u[0]))
    np.testing.assert_allclose(post["stiffness"].values, np.exp(res.chain[..., 0].T), rtol=1e-12)
    np.testing.assert_allclose(post["torque_line_correction"].values,
                               np.transpose(res.chain[..., problem.n_model:problem.n_nonlinear], (1, 0, 2)))

    # every sample of every run on one observation dim, the same (chain, draw) grid as the posterior
    n_obs = sum(len(y) for y in problem.y)
    for g in ("posterior_predictive", "log_likelihood"):
        da = tree[g]["angle"]
        assert list(tree[g].data_vars) == ["angle"]  # az.loo needs no var_name
        assert da.dims == ("chain", "draw", "observation") and da.sizes["observation"] == n_obs
        assert (da.sizes["chain"], da.sizes["draw"]) == (n_walkers, n_draws)
        np.testing.assert_array_equal(da["draw"].values, post["draw"].values)
        assert np.all(np.isfinite(da.values))
    obs = tree["observed_data"]
    for r, run in enumerate(runs):
        mine = obs["run"].values == run
        np.testing.assert_array_equal(obs["angle"].values[mine], np.asarray(problem.y[r]))
        np.testing.assert_array_equal(obs["run_sample"].values[mine], np.arange(len(problem.y[r])))
    hyst = small.sim.campaign.runs[0]
    const = tree["constant_data"]
    np.testing.assert_array_equal(const["torque"].values[obs["run"].values == hyst.name], hyst.torque_Nm)
    np.testing.assert_array_equal(const["time"].values[obs["run"].values == hyst.name], hyst.time_s)
    assert const["torque"].attrs["units"] == "N·m"
    # the predictive scatters around the data at about the noise level
    resid = tree["posterior_predictive"]["angle"].values - obs["angle"].values
    assert np.sqrt(np.mean(resid**2)) < 10 * float(post["noise_sigma"].max())
    stats = tree["sample_stats"]
    assert stats["lp"].dims == ("chain", "draw") and stats["acceptance_rate"].dims == ("chain", "draw")
    np.testing.assert_allclose(stats["lp"].values, res.log_prob.T)
    for key in ("tau_max", "n_steps", "burn_in", "thin", "converged"):
        assert key in stats.attrs
    assert stats.attrs["converged"] == 0 and stats.attrs["n_steps"] == 300 and stats.attrs["tree_thin"] == 1


def test_netcdf_round_trip(short_tree, tmp_path):
    _, tree = short_tree
    path = tmp_path / "posterior.nc"
    save_tree(tree, path)
    back = load_tree(path)
    assert set(GROUPS) <= set(back.children)
    xr.testing.assert_identical(back["posterior"].to_dataset(), tree["posterior"].to_dataset())
    xr.testing.assert_allclose(back["log_likelihood"].to_dataset(), tree["log_likelihood"].to_dataset())
    assert back["posterior"]["stiffness"].attrs["units"] == "N·m/rad"
    assert back["sample_stats"].attrs["thin"] == tree["sample_stats"].attrs["thin"]
    # ArviZ's own loader reads it as it is
    with arviz.from_netcdf(path) as az_tree:
        np.testing.assert_array_equal(az_tree["posterior"]["gap"].values, tree["posterior"]["gap"].values)
        assert float(arviz.rhat(az_tree, var_names=["stiffness"])["stiffness"]) > 0


def test_convergence_summary_keys(small, short_tree):
    _, tree = short_tree
    s = convergence_summary(tree)
    for key in ("rhat_max", "ess_min", "rhat", "ess", "converged", "tau_max"):
        assert key in s
    model_names = {p.name for p in small.problem.model.parameters()}
    assert {k.split("[")[0] for k in s["rhat"]} == model_names  # model parameters only
    assert "angle_offset[hyst-5]" in s["rhat"]
    assert s["rhat_max"] == pytest.approx(max(v for v in s["rhat"].values() if np.isfinite(v)))
    assert s["ess_min"] == pytest.approx(min(v for v in s["ess"].values() if np.isfinite(v)))
    assert s["converged"] is False


def test_psis_loo_runs_on_the_tree(short_tree):
    _, tree = short_tree
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # Pareto-k warnings on a 300-step chain are expected
        pooled = psis_loo(tree)
        one = psis_loo(tree, run="hyst-5")
        plain = arviz.loo(tree)
    n_obs = tree["observed_data"]["angle"].size
    assert pooled.n_data_points == n_obs and np.isfinite(pooled.elpd) and np.isfinite(pooled.se)
    assert pooled.elpd == pytest.approx(plain.elpd)
    assert one.n_data_points == int(np.sum(tree["observed_data"]["run"].values == "hyst-5"))
    with pytest.raises(ValueError, match="no run 'nope'"):
        psis_loo(tree, run="nope")


def test_linear_parameters_drawn_from_their_conditional_posterior(small):
    """One u repeated: with ``linear="sample"`` the spread of the linear parameters is their
    conditional posterior N(β̂(u), A⁻¹); with ``"profile"`` they are β̂(u) = full_values(u)."""
    problem = small.problem
    u = small.start.u
    n_draws, n_walkers = 64, 32
    res = SampleResult(chain=np.tile(u, (n_draws, n_walkers, 1)), log_prob=np.zeros((n_draws, n_walkers)),
                       tau=np.ones(problem.dim), n_steps=n_draws, burn_in=0, thin=1,
                       acceptance_fraction=np.zeros(n_walkers), converged=False, reason="test",
                       names=tuple(problem.names(small.runs)))
    prof = to_datatree(problem, res, small.runs, linear="profile")["posterior"]
    drawn = to_datatree(problem, res, small.runs)["posterior"]
    full = problem.full_values(jnp.asarray(u))
    assert np.allclose(prof["te_offset"].values, float(np.ravel(full["te_offset"])[0]))
    # A from the whitened design matrices, as the likelihood builds it
    _, rho = problem.noise_values(jnp.asarray(u))
    _, beta_hat, _, scales = problem.profile(jnp.asarray(u), return_scales=True)
    wx = [np.asarray(problem.whiten(x, scales[r], rho[r])) for r, x in enumerate(problem.design)]
    sd = np.sqrt(np.diag(np.linalg.inv(sum(w.T @ w for w in wx))))
    beta = np.stack([drawn["angle_offset"].values[..., 0].ravel(), drawn["te_offset"].values.ravel()], axis=1)
    assert np.all(np.abs(beta.mean(0) - np.asarray(beta_hat)) < 4 * sd / np.sqrt(len(beta)))
    np.testing.assert_allclose(beta.std(0), sd, rtol=0.1)
    with pytest.raises(ValueError, match="linear"):
        to_datatree(problem, res, small.runs, linear="nope")


# emcee to convergence on this campaign from its MAP, against the Laplace approximation and NUTS:
# tests/test_nuts.py::test_nuts_agrees_with_emcee_where_both_converge (one emcee run serves both)


# --- the Laplace independence move -------------------------------------------------------------
@pytest.mark.parametrize("shift, scale", [(0.0, 1.0), (1.0, 0.5), (-0.5, 2.5)])
def test_laplace_move_alone_samples_the_target_even_from_a_wrong_approximation(shift, scale):
    """The independence move is Metropolis–Hastings with the Hastings factor ln q(x) − ln q(x'):
    its stationary law is the target whatever q is. A q shifted by 1 sd and 2× too narrow, or
    2.5× too wide, still gives the target's mean and sd (a wrong factor would not)."""
    from torsionfit.sample._laplace_move import LaplaceMove

    problem, _, mean, cov = _toy()
    sd = np.sqrt(np.diag(cov))
    move = LaplaceMove(mean + shift * sd, scale**2 * cov)
    walkers = 32
    sampler = emcee.EnsembleSampler(walkers, 3, _LogProb(problem, batch=walkers // 2), vectorize=True,
                                    moves=[(move, 1.0)])
    rng = np.random.default_rng(0)
    sampler.random_state = np.random.RandomState(0).get_state()
    sampler.run_mcmc(mean + rng.standard_normal((walkers, 3)) * sd, 3000, progress=False)
    draws = sampler.get_chain(discard=500, flat=True)
    assert np.all(np.abs(draws.mean(0) - mean) < 0.15 * sd)
    assert np.allclose(draws.std(0), sd, rtol=0.12)


def test_laplace_move_rejects_a_covariance_of_the_wrong_shape():
    from torsionfit.sample._laplace_move import LaplaceMove

    with pytest.raises(ValueError, match="cov must be 3×3"):
        LaplaceMove(np.zeros(3), np.eye(2))


def test_sampler_matches_the_target_when_the_laplace_approximation_is_off():
    """run_sampler's mixture, started from an approximation shifted by 1 sd and 3× too narrow."""
    problem, start, mean, cov = _toy()
    sd = np.sqrt(np.diag(cov))
    wrong = SimpleNamespace(u=mean + sd, cov=cov / 9.0, names=start.names)
    res = run_sampler(problem, wrong, seed=2, **FAST)
    draws = res.flat()
    assert res.converged
    assert np.all(np.abs(draws.mean(0) - mean) < 0.25 * sd)
    assert np.allclose(draws.std(0), sd, rtol=0.15)
