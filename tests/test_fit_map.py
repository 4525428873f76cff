"""fit/_map.py: starts that reach the same optimum share the later noise passes, and the MAP is
the one every start run through every pass would give (SYNTHETIC tests/benches/stat_rv_white)."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import pytest

from torsionfit.bench import load_bench, simulate
from torsionfit.fit import NoiseOptions, _map, build_problem, fit_map, temperatures_resolving_friction
from torsionfit.model import model_with_effects

BENCH = Path(__file__).parent / "benches" / "stat_rv_white.toml"


def test_same_optimum_merges_agreeing_points_only():
    a = np.array([12.8244, 1.79, -8.14])
    assert _map.same_optimum([a, a * (1 + 1e-9), a + [0, 0, 0.5], a + [0, 0, 0.5 + 1e-9]]) == [0, 0, 2, 2]
    assert _map.same_optimum([a, a * (1 + 1e-4)]) == [0, 1]
    nan = np.full(3, np.nan)
    assert _map.same_optimum([nan, nan, a]) == [0, 1, 2]  # non-finite points are never merged


def test_noise_passes_below_one_is_an_error():
    with pytest.raises(ValueError, match="noise_passes must be at least 1"):
        fit_map(None, noise_passes=0)


@pytest.fixture(scope="module")
def problem():
    campaign = simulate(load_bench(BENCH), seed=3).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    return build_problem(campaign, model)


def test_shared_later_passes_give_the_map_of_every_start_run_alone(problem, monkeypatch):
    calls = []
    solve = _map._solve_pass
    monkeypatch.setattr(_map, "_solve_pass", lambda *a: calls.append(1) or solve(*a))
    result = fit_map(problem, n_starts=4, seed=0, noise_passes=3)
    distinct = len({ld for ld, _ in result.starts})
    assert len(calls) == 4 + 2 * distinct < 12  # the starts met: their later passes are shared
    # every start through all three passes on its own, as before the sharing
    solver = optx.LevenbergMarquardt(rtol=1e-8, atol=1e-10)
    alone = []
    for start in _map.map_starts(problem, 4, 0):
        u_phys, u_noise = jnp.asarray(start), _map.iid_noise(problem)
        for _ in range(3):
            u_phys, u_noise, _, ld = solve(problem, u_phys, u_noise, solver, 300)
        alone.append((np.concatenate([u_phys, u_noise]), float(ld)))
    best_u, best_ld = max(alone, key=lambda x: x[1])
    assert abs(result.log_density - best_ld) < 1e-8 * abs(best_ld)
    assert np.max(np.abs(result.u - best_u) / np.maximum(np.abs(best_u), 1.0)) < 1e-5


def test_the_map_records_the_distinct_optima_of_its_starts_best_first(problem):
    result = fit_map(problem, n_starts=4, seed=0, noise_passes=2)
    lds = [ld for ld, _, _ in result.optima]
    assert result.optima and lds == sorted(lds, reverse=True)
    assert lds[0] == result.log_density and np.array_equal(result.optima[0][1], result.u)
    assert result.optima[0][2] == result.converged
    assert len(result.optima) == len({ld for ld, _ in result.starts if np.isfinite(ld)})


def test_rival_optima_are_far_and_about_as_likely_as_widened():
    cov = np.diag([1.0, 4.0])  # sds 1 and 2
    best = np.array([0.0, 0.0, 9.0])  # the last entry is outside the physics block
    optima = [(-100.0, best, True), (-101.0, np.array([0.0, 8.0, 0.0]), True), (-100.5, np.array([1.0, 0.0, 0.0]), True),
              (-200.0, np.array([10.0, 0.0, 0.0]), True)]
    rivals = _map.rival_optima(best, -100.0, optima, cov)
    assert [r["distance_sd"] for r in rivals] == pytest.approx([4.0, 1.0, 10.0])  # the MAP itself left out
    assert [r["rival"] for r in rivals] == [True, False, False]  # near: within reach; 100 nats down: not
    assert "1 other optimum" in _map.rival_note(rivals) and _map.rival_note(rivals[1:]) == ""
    # widened for misfit (likelihood to the power 1/20), the distant optimum 100 nats down is 5 down
    widened = _map.rival_optima(best, -100.0, optima, cov, likelihood_power=1 / 20)
    assert widened[2]["log_density_gap_widened"] == pytest.approx(5.0) and not widened[2]["rival"]
    assert _map.rival_optima(best, -100.0, optima, cov, likelihood_power=1 / 50)[2]["rival"]
    # a start stopped short of its tolerance is listed, never a rival: it may be on its way to the MAP
    short = _map.rival_optima(best, -100.0, [optima[0], (-101.0, optima[1][1], False)], cov)
    assert short[0]["converged"] is False and short[0]["rival"] is False


def test_the_map_is_the_log_densitys_optimum_in_the_physics(problem):
    """LM minimises the whitened residuals and the physics' share of −Σ log scale_i (the
    errors-in-variables slope widens a sample's scale where the loop is steep): without that
    share its optimum was not the posterior's (|∂ log p/∂u|·sd up to 0.06 here, and on measured
    loops LM never settled), with it the gradient left is the linear block's log det only."""
    result = fit_map(problem, n_starts=2, seed=0)
    n = problem.n_nonlinear
    grad = np.asarray(jax.grad(problem.log_density)(jnp.asarray(result.u)))[:n]
    assert result.converged
    assert np.max(np.abs(grad) * result.sd[:n]) < 0.01


def test_a_nested_models_optimum_warm_starts_the_extension(problem):
    """diagnose tries each extension from the current model's optimum too: the extension then
    ends at least as high as that start, whatever its own prior-centred starts find."""
    base = fit_map(problem, n_starts=1, seed=0)
    campaign = simulate(load_bench(BENCH), seed=3).campaign
    names = [r.name for r in campaign.runs]
    model = model_with_effects([r.kind for r in campaign.runs], {"asymmetry": True}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    extended = build_problem(campaign, model)
    base_names = problem.names(tuple(f"run{i}" for i in range(problem.n_runs)))
    start = _map.nested_start(extended, tuple(f"run{i}" for i in range(extended.n_runs)), base.u, base_names)
    ext_names = extended.names(tuple(f"run{i}" for i in range(extended.n_runs)))[:extended.n_nonlinear]
    shared = [j for j, n in enumerate(ext_names) if n in base_names]
    new = [j for j, n in enumerate(ext_names) if n not in base_names]
    assert new and len(shared) == problem.n_nonlinear  # the extension adds parameters, keeps the others
    assert np.allclose(start[shared], [base.u[base_names.index(ext_names[j])] for j in shared])
    assert np.allclose(start[new], np.asarray(extended.prior_mean)[new])
    n = extended.n_nonlinear
    assert start.size == extended.dim  # the base fit's noise block comes along
    assert np.allclose(start[n:], base.u[problem.n_nonlinear:])
    warm = fit_map(extended, names, n_starts=1, seed=0, warm_starts=start[None, :])
    ld_start = float(_map.log_density(extended, jnp.asarray(start)))
    assert warm.log_density >= ld_start
    assert len(warm.starts) == 2  # the warm start, then the prior centre


def test_a_lag_whose_zero_is_the_smaller_model_starts_near_zero(problem):
    """An extension whose new parameter's zero limit is the model without it (the damped gap's
    lag) starts three prior sds below that prior's centre, where it is the smaller model: from
    the prior centre a measured loop's refit drifted to a lag forty ramps long instead."""
    campaign = simulate(load_bench(BENCH), seed=3).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {"gap_lag": True}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    extended = build_problem(campaign, model)
    runs = tuple(f"run{i}" for i in range(extended.n_runs))
    base_u = np.asarray(problem.prior_mean) + 0.1  # any point of the smaller model
    start = _map.nested_start(extended, runs, base_u, problem.names(runs)[:problem.n_nonlinear])
    assert start.size == extended.n_nonlinear  # without the other fit's noise block: the non-linear block
    names = extended.names(runs)[:extended.n_nonlinear]
    j = names.index("gap_lag_time")
    assert extended.vanishing_at_zero() == {j}
    assert np.isclose(start[j], float(extended.prior_mean[j]) - 3.0 * float(extended.prior_sd[j]))
    shared = [i for i, n in enumerate(names) if i != j]
    assert np.allclose(start[shared], base_u[[problem.names(runs).index(names[i]) for i in shared]])
    with pytest.raises(ValueError, match="warm starts have"):
        fit_map(extended, runs, n_starts=1, warm_starts=np.zeros((1, extended.n_nonlinear + 1)))


def test_temperature_term_needs_every_runs_temperature():
    """A temperature-dependent model on runs without a temperature, or all at one, stops with
    one line naming the run or the temperature — never a fit at an assumed ΔT = 0."""
    import dataclasses

    from torsionfit import InputError

    bench = load_bench(Path(__file__).parent / "benches" / "effects" / "te_temperature.toml")
    campaign = simulate(bench, seed=0).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {"temperature_dependence": True},
                               campaign.reducer.rated_torque_Nm)
    problem = build_problem(campaign, model)
    assert campaign.reference_temperature_C == 40.0
    assert [float(i.temperature_delta_K) for i in problem.inputs] == [0.0, -15.0, -15.0, 0.0, 0.0, 15.0, 15.0]
    unknown = dataclasses.replace(campaign, runs=(dataclasses.replace(campaign.runs[0], nominal_temperature_C=None),
                                                  *campaign.runs[1:]))
    with pytest.raises(InputError, match="run 'hyst-40C': temperature_dependence needs every run's temperature"):
        build_problem(unknown, model)
    one = dataclasses.replace(campaign, runs=tuple(dataclasses.replace(r, nominal_temperature_C=40.0) for r in campaign.runs))
    with pytest.raises(InputError, match="two or more temperatures; all runs are at 40 °C"):
        build_problem(one, model)
    # one TE load per temperature and a loop at one: a softer spring and more friction widen
    # the TE span alike — the friction coefficient must be declared away, never guessed
    one_load = dataclasses.replace(campaign, runs=tuple(
        dataclasses.replace(r, torque_Nm=380.0) if r.kind == "transmission_error" else r for r in campaign.runs))
    assert temperatures_resolving_friction(campaign) == [25.0, 40.0, 55.0]
    assert temperatures_resolving_friction(one_load) == [40.0]
    with pytest.raises(InputError, match=r"at: 40 °C\); declare temperature_dependence = \{friction = false\}"):
        build_problem(one_load, model)
    compliance_only = model_with_effects([r.kind for r in campaign.runs], {"temperature_dependence": {"friction": False}},
                                         campaign.reducer.rated_torque_Nm)
    names = [p.name for p in build_problem(one_load, compliance_only).physics]
    assert "temperature_compliance" in names and "temperature_friction" not in names


def test_map_programs_compile_with_xla_defaults_where_xla_lacks_the_options(monkeypatch):
    """The MAP's XLA options (_map.MAP_COMPILER_OPTIONS) are used where this XLA knows them;
    an XLA without them compiles the MAP's programs with its defaults instead of failing."""
    _map._map_compiler_options.cache_clear()
    monkeypatch.setattr(_map, "MAP_COMPILER_OPTIONS", {"xla_torsionfit_no_such_option": True})
    try:
        assert _map._map_compiler_options() is None
    finally:
        _map._map_compiler_options.cache_clear()


def test_the_newton_step_says_how_far_a_point_is_from_the_optimum(problem):
    """``newton_step``: about 0 at the MAP; half a posterior sd off along one parameter, the
    Gauss–Newton step leads back by that half sd along it (z) and predicts the log density lost
    (λ²/2); a solve stopped by its step budget says so in its message."""
    result = fit_map(problem, n_starts=1, seed=0)
    lam, z = _map.newton_step(problem, result.u)
    assert result.converged and lam < 1e-2 and np.max(np.abs(z)) <= lam + 1e-12
    n = problem.n_nonlinear
    k = int(np.argmax(result.sd[:n]))
    off = result.u.copy()
    off[k] += 0.5 * result.sd[k]
    lam, z = _map.newton_step(problem, off)
    lost = float(_map.log_density(problem, jnp.asarray(result.u)) - _map.log_density(problem, jnp.asarray(off)))
    assert abs(z[k] + 0.5) < 0.05 and np.max(np.abs(np.delete(z, k))) < 0.5
    assert lost > 0 and abs(0.5 * lam**2 - lost) < 0.2 * lost
    short = fit_map(problem, n_starts=1, seed=0, max_steps=2, noise_passes=1)
    assert not short.converged and result.newton_step_sd is None
    assert short.newton_step_sd == pytest.approx(_map.newton_step(problem, short.u)[0])
    assert f"the Gauss–Newton step from there is {short.newton_step_sd:.2g} posterior sd" in short.message
    assert "\n" not in short.message


def test_a_map_stopped_at_its_budget_continues_from_where_it_stopped(problem):
    """``continuations``: a solve that ends at its step budget short of the tolerance takes more
    passes of the same budget from where it stopped, until it meets the tolerance, at an optimum
    (each pass re-reads the noise level, as the noise passes do); one that converged takes none
    (it is unchanged)."""
    full = fit_map(problem, n_starts=1, seed=0, noise_passes=1)
    short = fit_map(problem, n_starts=1, seed=0, max_steps=3, noise_passes=1)
    assert full.converged and not short.converged
    continued = fit_map(problem, n_starts=1, seed=0, max_steps=3, noise_passes=1, continuations=200)
    assert continued.converged and continued.newton_step_sd is None and continued.message == "successful"
    assert continued.log_density >= short.log_density
    # at an optimum of physics and noise together: one pass (LM, then the noise re-read) leaves
    # the physics 1.8 posterior sd from the optimum the re-read noise has; the passes close that
    assert _map.newton_step(problem, continued.u)[0] < 0.1 < _map.newton_step(problem, full.u)[0]
    again = fit_map(problem, n_starts=1, seed=0, noise_passes=1, continuations=5)
    np.testing.assert_array_equal(again.u, full.u)


JUMPS = Path(__file__).parent / "benches" / "stat_rv_jumps.toml"


@pytest.fixture(scope="module")
def jumpy():
    """(campaign, its true friction torque, N·m): SYNTHETIC stat_rv_jumps, 4 % of the angle
    samples moved by ±40× the noise."""
    bench = load_bench(JUMPS)
    return simulate(bench, seed=3).campaign, bench.truth["friction_torque"]


def _fit(campaign, dof):
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    problem = build_problem(campaign, model, NoiseOptions(student_t_dof=dof))
    return problem, fit_map(problem, n_starts=2, seed=0)


def test_a_student_t_map_is_its_own_log_densitys_optimum(jumpy):
    """Under Student-t noise LM minimises the t's negative log density (its pseudo-residuals) and
    the scale is the t's EM fixed point: the MAP is the optimum of the density the sampler and
    LOO read. (Minimising the Gaussian's squares, as before, left it off that optimum.)"""
    problem, result = _fit(jumpy[0], 4.0)
    n = problem.n_nonlinear
    grad = np.asarray(jax.grad(problem.log_density)(jnp.asarray(result.u)))
    assert result.converged
    assert np.max(np.abs(grad[:n]) * result.sd[:n]) < 0.01
    # the scale: ∂ log p/∂ log s, against its own sd
    s_sd = result.sd[n:n + problem.n_runs]
    assert np.max(np.abs(grad[n:n + problem.n_runs]) * s_sd) < 0.1


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_student_t_noise_reads_through_the_jumps(seed):
    """SYNTHETIC: 4 % of the samples jump by ±40× the noise. Symmetric jumps do not bias the
    Gaussian fit, they count as noise: its sds of friction and stiffness are 5–6× what the
    white noise alone allows. The Student-t fit (ν = 4) explains them in its tails: sds under
    0.3 of the Gaussian's, the truth within 3 of them."""
    bench = load_bench(JUMPS)
    campaign = simulate(bench, seed=seed).campaign
    fits = {dof: _fit(campaign, dof)[1] for dof in (None, 4.0)}
    for name in ("friction_torque", "stiffness"):
        (gauss, robust) = ((r.sd[r.names.index(name)], np.log(r.values[name] / bench.truth[name])) for r in fits.values())
        assert robust[0] < 0.3 * gauss[0], name
        assert abs(robust[1]) < 3 * robust[0], name


def test_student_t_dof_must_be_positive():
    campaign = simulate(load_bench(BENCH), seed=3).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm)
    for bad in (0.0, -2.0, float("nan")):
        with pytest.raises(ValueError, match="student_t_dof must be a positive number"):
            build_problem(campaign, model, NoiseOptions(student_t_dof=bad))
