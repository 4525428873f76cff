"""Derived metrics, fit.json and `torsionfit fit` (Laplace path; the emcee path is in
tests/test_sample.py and the statistical tests)."""

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest

import torsionfit
from torsionfit._provenance import command_line, environment
from torsionfit.bench import load_bench, simulate
from torsionfit.cli import EXIT_INPUT_ERROR, main
from torsionfit.fit import rival_note
from torsionfit.model import model_with_effects
from torsionfit.report import FitOptions, derived_metrics_for, fit_campaign, fit_json, summary_table

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
REQUIRED = ("stiffness_rated", "stiffness_elastic", "lost_motion", "backlash", "geometric_gap", "friction_torque")


@pytest.fixture(scope="module")
def noisy_bench(tmp_path_factory):
    text = BENCH.read_text().replace("[truth]", "[noise]\nangle_sd_arcsec = 1.0\n[truth]")
    path = tmp_path_factory.mktemp("bench") / "bench.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def laplace_fit(noisy_bench):
    sim = simulate(load_bench(noisy_bench), seed=4)
    return sim, fit_campaign(sim.campaign, FitOptions(sampler="laplace", n_starts=2), seed=0)


def test_derived_metrics_of_the_truth_match_the_data_only_metrics(noisy_bench):
    """The model's own loop, read exactly, agrees with the data-only reading of the data."""
    from torsionfit.metrics import campaign_metrics

    sim = simulate(load_bench(noisy_bench), seed=4)
    derived = derived_metrics_for(sim.campaign, sim.model)
    truth = dict(zip((s.name for s in derived.specs), np.asarray(derived.evaluate(sim.truth))))
    data = {r["kind"]: r["metrics"] for r in campaign_metrics(sim.campaign)["runs"]}
    hyst = data["hysteresis"]
    assert truth["stiffness_elastic"] == pytest.approx(108.0, rel=1e-3)  # the bench's K
    assert truth["geometric_gap"] == pytest.approx(1.0, rel=1e-9)
    for name, rel in (("stiffness_rated", 0.01), ("lost_motion", 0.05), ("backlash", 0.05), ("dissipated_energy", 0.05)):
        assert truth[name] == pytest.approx(hyst[name]["value"], rel=rel), name
    assert truth["kd_mean[te-5rpm-fw]"] == pytest.approx(data["transmission_error"]["kd"]["value"], rel=0.01)



def test_derived_metrics_compile_once_for_any_loading_rate_and_draw_count(noisy_bench):
    """The loading rate and the rated torque are data, not compile keys; the draws are
    evaluated in fixed chunks (the last padded), each draw as one evaluate() gives it."""
    import dataclasses

    import jax

    from torsionfit.report._derived import _metrics_over_draws

    sim = simulate(load_bench(noisy_bench), seed=4)
    draws = {k: np.stack([np.asarray(v) * f for f in (1.0, 1.01, 0.99)]) for k, v in sim.truth.items()}
    first = derived_metrics_for(sim.campaign, sim.model).over_draws(draws)
    size = _metrics_over_draws._cached._cache_size()
    for rate, rated in ((0.5, 380.0), (40.0, 500.0)):
        runs = tuple(dataclasses.replace(r, loading_rate_Nm_per_s=rate) if r.kind == "hysteresis" else r
                     for r in sim.campaign.runs)
        reducer = dataclasses.replace(sim.campaign.reducer, rated_torque_Nm=rated)
        derived = derived_metrics_for(dataclasses.replace(sim.campaign, runs=runs, reducer=reducer), sim.model)
        assert any(f"{rate:g} N·m/s" in s.description for s in derived.specs)
        derived.over_draws(jax.tree.map(lambda x: x[:2], draws))
    assert _metrics_over_draws._cached._cache_size() == size  # no new compilation
    one = [np.asarray(derived_metrics_for(sim.campaign, sim.model).evaluate(jax.tree.map(lambda x, i=i: x[i], draws)))
           for i in range(3)]
    np.testing.assert_allclose(first, np.stack(one), rtol=1e-12)

@pytest.mark.parametrize("lost_motion_pct", [3.0, 3.1])
def test_metric_loop_is_exact_at_its_samples(noisy_bench, lost_motion_pct):
    """The metrics' five-step loop is exact at every sample (friction's update is exact along a
    ramp) and every level a metric reads is a sample: 400 samples per step give what 4 000 give,
    but for the loop area's trapezoid error."""
    import dataclasses

    from torsionfit.report._derived import SAMPLES_PER_STEP, _protocol

    sim = simulate(load_bench(noisy_bench), seed=4)
    derived = derived_metrics_for(sim.campaign, sim.model, lost_motion_pct)
    assert derived.protocol.torque_Nm.shape == (5 * (SAMPLES_PER_STEP + 1) + 1,)
    fine = dataclasses.replace(derived, protocol=_protocol(380.0, 5.0, 4000, lost_motion_pct / 100))
    names = [s.name for s in derived.specs]
    coarse, ref = np.asarray(derived.evaluate(sim.truth)), np.asarray(fine.evaluate(sim.truth))
    energy = names.index("dissipated_energy")
    assert coarse[energy] == pytest.approx(ref[energy], rel=1e-4)
    others = [i for i in range(len(names)) if i != energy]
    np.testing.assert_allclose(coarse[others], ref[others], rtol=1e-10)


@pytest.mark.parametrize("effects, reads", [({}, False), ({"kinematic_error": [1, 2]}, True),
                                             ({"thermal_drift": True, "torque_offset": True}, False)])
def test_metrics_read_the_linear_profile_only_when_they_need_it(noisy_bench, effects, reads):
    """The draws' values skip the linear profile (a model run over the data per draw) unless
    the metrics read a linear parameter (kinematic harmonics); the metrics are the same either
    way, since the metrics' runs carry no offsets or drift."""
    import jax

    from torsionfit.report._pipeline import _values_over_draws, prepare_fit

    sim = simulate(load_bench(noisy_bench), seed=4)
    options = FitOptions(sampler="laplace", effects=effects)
    campaign, model, problem = prepare_fit(sim.campaign, options)
    derived = derived_metrics_for(campaign, model)
    assert derived.reads_linear() is reads
    u0 = problem.prior_mean
    rng = np.random.default_rng(0)
    u = np.concatenate([u0 + 0.01 * rng.standard_normal((3, u0.size)), np.zeros((3, problem.dim - u0.size))], axis=1)
    full = _values_over_draws(problem, u, True)
    values = _values_over_draws(problem, u, reads)
    assert ("kin_cos" in values) is reads
    assert ("angle_offset" in values) is reads  # run offsets only come with the profile
    if reads:  # the harmonics' profile matters: zeroing them changes K_d
        zeroed = {**full, "kin_cos": 0 * full["kin_cos"], "kin_sin": 0 * full["kin_sin"]}
        assert not np.allclose(derived.over_draws(zeroed), derived.over_draws(full), rtol=1e-9)
    np.testing.assert_allclose(derived.over_draws(values), derived.over_draws(full), rtol=1e-12)
    if reads:
        assert jax.tree.structure(values) == jax.tree.structure(full)
    else:
        assert set(values) == {p.name for p in problem.physics}


def test_fit_json_has_the_contract(laplace_fit):
    sim, fit = laplace_fit
    doc = json.loads(json.dumps(fit_json(fit)))  # JSON-serialisable
    for name in REQUIRED:
        entry = doc["metrics"][name]
        assert set(entry) >= {"mean", "sd", "hdi95", "unit"}
        assert entry["hdi95"][0] <= entry["mean"] <= entry["hdi95"][1]
    assert "kd_mean[te-5rpm-fw]" in doc["metrics"]
    assert doc["metrics"]["kd_mean[te-5rpm-fw]"]["condition"] == {"torque_Nm": 380.0, "speed_rpm": 5.0, "direction": "forward"}
    assert set(doc["diagnostics"]) >= {"converged", "rhat_max", "ess_min"}
    assert set(doc["rmse"]) == {"hyst-5", "te-5rpm-fw"}
    assert {"twist_elastic_at_rated", "twist_friction_at_rated", "twist_geometric_at_rated"} <= set(doc["components"])


def test_the_fit_reports_its_starts_other_optima_and_a_rival_in_the_summary(laplace_fit):
    """On the virtual bench (SYNTHETIC; the model's own physics) the starts reach no rival: every
    other end point is the MAP or far below it. A rival in the diagnostics is printed as `optima:`."""
    _, fit = laplace_fit
    doc = json.loads(json.dumps(fit_json(fit)))
    others = doc["diagnostics"]["map_other_optima"]
    assert isinstance(others, list) and not any(o["rival"] for o in others)
    assert "map_rival_note" not in doc["diagnostics"] and "optima:" not in summary_table(doc)
    rival = {"log_density_gap": 20.0, "log_density_gap_widened": 0.8, "distance_sd": 240.0, "converged": True, "rival": True}
    doc["diagnostics"]["map_rival_note"] = rival_note([rival])
    line = next(x for x in summary_table(doc).splitlines() if x.startswith("optima:"))
    assert "0.8 below the MAP's log posterior (as widened), 240 posterior sd from it" in line


def test_laplace_fit_recovers_the_bench_truth(laplace_fit):
    sim, fit = laplace_fit
    doc = fit_json(fit)
    derived = derived_metrics_for(sim.campaign, sim.model)
    truth = dict(zip((s.name for s in derived.specs), np.asarray(derived.evaluate(sim.truth))))
    for name in REQUIRED + ("kd_mean[te-5rpm-fw]",):
        lo, hi = doc["metrics"][name]["hdi95"]
        sd = doc["metrics"][name]["sd"]
        # inside the 95 % HDI, or within 3 sd (one seed; calibration is tested in test_fit_statistics)
        assert lo - 3 * sd <= truth[name] <= hi + 3 * sd, (name, truth[name], lo, hi)
    # the three parts add up to the angle at rated torque (stiffness_rated_from_start's twist)
    parts = sum(doc["components"][k]["mean"] for k in doc["components"])
    assert 380.0 / parts == pytest.approx(doc["metrics"]["stiffness_rated_from_start"]["mean"], rel=1e-3)


def test_fit_command_laplace(tmp_path, noisy_bench, capsys):
    """``torsionfit fit``: the summary on stdout, progress on stderr, the provenance in fit.json
    (``--quiet`` is checked on the split fit below)."""
    assert main(["simulate", str(noisy_bench), "-o", str(tmp_path / "c"), "--seed", "2"]) == 0
    capsys.readouterr()
    argv = ["fit", str(tmp_path / "c"), "-o", str(tmp_path / "fit"), "--sampler", "laplace", "--seed", "1"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    out, err = captured.out, captured.err.splitlines()
    assert err[0].startswith("[fit] read ") and "runs" in err[0]
    assert any(line.startswith("[fit] MAP from 4 starts") for line in err)
    assert any(line.startswith("[fit] MAP converged") or line.startswith("[fit] MAP not converged") for line in err)
    assert "stiffness_rated" in out and "SYNTHETIC" in out
    doc = json.loads((tmp_path / "fit" / "fit.json").read_text())
    assert doc["diagnostics"]["sampler"] == "laplace"
    assert doc["provenance"] == {"torsionfit_version": torsionfit.__version__, "seed": 1, "command": command_line(argv),
                                 "environment": environment()}
    # the model holds on its own bench: no AR(1) coefficient near the bound, no noise note
    assert doc["diagnostics"]["ar1_misfit_runs"] == {} and "noise_note" not in doc["diagnostics"]
    assert "\nnoise: " not in out
    figures = {p.name for p in (tmp_path / "fit" / "figures").iterdir()}
    assert {"loop-hyst-5.png", "components-hyst-5.png", "te-vs-angle.png", "kd-vs-speed.png", "pairs.png"} <= figures


def test_split_normal_laplace_keeps_the_widths_of_a_gaussian_posterior(laplace_fit):
    """On its own bench the model's physics posterior is Gaussian: the split normal measured
    along the Laplace axes keeps their widths (the noise axes are not Gaussian and may move)."""
    from torsionfit.report._pipeline import laplace_approximation

    _, fit = laplace_fit
    n = fit.problem.n_nonlinear
    approx = laplace_approximation(fit.problem, fit.map_result, "split")
    physics = np.linalg.norm(approx.axes[:n], axis=0) > 0.99
    assert physics.sum() == n
    np.testing.assert_allclose(approx.scales[physics], 1.0, atol=0.1)
    assert laplace_approximation(fit.problem, fit.map_result, "gaussian") is None
    with pytest.raises(Exception, match="laplace shape must be one of gaussian, split, got 'skewed'"):
        laplace_approximation(fit.problem, fit.map_result, "skewed")


def test_split_normal_of_a_widened_posterior_is_centred_at_its_mode(laplace_fit):
    """Widened (likelihood to the power 1/k), the prior weighs more and the density's peak moves
    off the MAP: the split normal is centred at that peak, where the gradient vanishes."""
    import jax
    import jax.numpy as jnp

    from torsionfit.fit._misfit import widened
    from torsionfit.report._pipeline import laplace_approximation

    _, fit = laplace_fit
    problem, map_result = widened(fit.problem, fit.map_result, 50.0)
    approx = laplace_approximation(problem, map_result, "split")
    grad = jax.grad(problem.log_density)
    at_map, at_centre = (np.linalg.norm(np.asarray(grad(jnp.asarray(u)))) for u in (map_result.u, approx.mean))
    assert float(problem.log_density(jnp.asarray(approx.mean))) > float(problem.log_density(jnp.asarray(map_result.u)))
    assert at_centre < 1e-3 * at_map


def test_the_optima_mixture_keeps_one_component_where_the_starts_found_one_optimum(laplace_fit):
    """A unimodal (bench) posterior: an 'other optimum' that is the MAP itself, or a point on its
    slope 8 sd off (a start that stopped short), moves to the mode and is the same component —
    the mixture is the split normal alone, weight 1."""
    from torsionfit.fit._misfit import widened
    from torsionfit.report._pipeline import laplace_approximation, optima_mixture

    _, fit = laplace_fit
    problem, map_result = widened(fit.problem, fit.map_result, 4.0)
    main = laplace_approximation(problem, map_result, "split")
    n = problem.n_nonlinear
    sd = np.sqrt(np.diag(map_result.cov))
    off = np.array(map_result.u, float)
    off[:n] += 8.0 * sd[:n] / np.sqrt(n)
    mix, rows = optima_mixture(problem, map_result, main, [np.asarray(map_result.u), off])
    assert len(mix.components) == 1 and mix.components[0] is main
    assert rows == [{"weight": 1.0, "log_density_gap": 0.0, "distance_sd": 0.0}]


def test_the_optima_mixture_needs_the_split_shape(noisy_bench):
    sim = simulate(load_bench(noisy_bench), seed=4)
    with pytest.raises(Exception, match="optima_mixture needs laplace_shape='split'"):
        fit_campaign(sim.campaign, FitOptions(sampler="laplace", n_starts=1, optima_mixture=True), seed=0)


def test_laplace_note_names_physics_axes_far_from_gaussian():
    from torsionfit.report._pipeline import laplace_note
    from torsionfit.sample import SplitNormal

    axes = np.eye(3)  # axes 0, 1: physics (n_physics = 2); axis 2: noise
    def approx(scales):
        return SplitNormal(mean=np.zeros(3), axes=axes, sd=np.ones(3), scales=np.asarray(scales, float))
    off = approx([[1.0, 1.0], [0.3, 1.1], [5.0, 5.0]])
    note = laplace_note(off, "gaussian", 2)
    assert "along 1 of its 2 physics axes" in note and "0.30–1.10" in note and "--laplace-shape split" in note
    assert laplace_note(off, "split", 2) == ""  # the split normal draws: nothing to say
    assert laplace_note(approx([[1.0, 0.9], [1.2, 1.0], [5.0, 0.1]]), "gaussian", 2) == ""  # the noise axis alone
    assert laplace_note(None, "gaussian", 2) == ""


def test_widened_gaussian_laplace_fit_measures_its_half_axes(laplace_fit):
    """A widened fit drawing from the Gaussian records the split normal's half-axis range (and a
    note when a physics axis is far from Gaussian); an unwidened one measures nothing."""
    from torsionfit.fit._misfit import widened
    from torsionfit.report._pipeline import finish_fit, laplace_approximation

    sim, fit = laplace_fit
    assert fit.diagnostics["laplace_scale_range"] is None and "laplace_note" not in fit.diagnostics
    assert "laplace_pareto_k" not in fit.diagnostics  # nothing measured, nothing to check against
    problem, map_result = widened(fit.problem, fit.map_result, 50.0)
    options = FitOptions(sampler="laplace", n_starts=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        wide = finish_fit(sim.campaign, options, problem.model, problem, map_result, seed=0)
    measured = laplace_approximation(problem, map_result, "split")
    assert wide.diagnostics["laplace_scale_range"] == [float(measured.scales.min()), float(measured.scales.max())]
    n = problem.n_nonlinear
    physics = np.linalg.norm(measured.axes[:n], axis=0) > np.sqrt(0.5)
    far = np.any((measured.scales[physics] < 0.5) | (measured.scales[physics] > 2.0))
    assert ("laplace_note" in wide.diagnostics) == bool(far)
    k = wide.diagnostics["laplace_pareto_k"]  # the Gaussian's draws against the widened posterior
    assert np.isfinite(k) and ("laplace_pareto_k_note" in wide.diagnostics) == (k > 0.7)


def test_fit_command_laplace_split(tmp_path, noisy_bench, capsys):
    assert main(["simulate", str(noisy_bench), "-o", str(tmp_path / "c"), "--seed", "2", "--quiet"]) == 0
    assert main(["fit", str(tmp_path / "c"), "-o", str(tmp_path / "fit"), "--sampler", "laplace",
                 "--laplace-shape", "split", "--seed", "1", "--quiet"]) == 0
    assert capsys.readouterr().err == ""  # --quiet: no progress
    diag = json.loads((tmp_path / "fit" / "fit.json").read_text())["diagnostics"]
    assert diag["sampler"] == "laplace" and diag["laplace_shape"] == "split"
    lo, hi = diag["laplace_scale_range"]
    assert 0 < lo <= hi
    # a near-Gaussian posterior (a clean bench): the split normal's draws stand for it
    assert diag["laplace_pareto_k"] <= 0.7 and "laplace_pareto_k_note" not in diag, diag["laplace_pareto_k"]


@pytest.mark.parametrize("flag, fragment", [
    ("warp_drive", "unknown effect 'warp_drive'"),
    ("kinematic_error=[1, 2", "not a TOML value"),
])
def test_fit_command_rejects_bad_effects(tmp_path, flag, fragment, capsys):
    main(["simulate", str(BENCH), "-o", str(tmp_path / "c")])
    capsys.readouterr()
    code = main(["fit", str(tmp_path / "c"), "-o", str(tmp_path / "f"), "--with", flag, "--sampler", "laplace"])
    assert code == EXIT_INPUT_ERROR
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1


def test_fit_of_a_run_that_never_loads_is_a_clear_error(tmp_path, capsys):
    folder = tmp_path / "c"
    folder.mkdir()
    t = np.arange(50) * 0.1
    rows = "\n".join(f"{a},{0.01 * np.sin(a)},{0.1 * a}" for a in t)
    (folder / "flat.csv").write_text("time_s,torque_Nm,angle_arcmin\n" + rows + "\n")
    (folder / "campaign.toml").write_text(
        '[reducer]\nname = "flat"\nrated_torque_Nm = 100\n[[runs]]\nname = "flat"\nkind = "hysteresis"\n'
        'file = "flat.csv"\npeak_torque_Nm = 0.01\n'
    )
    code = main(["fit", str(folder), "-o", str(tmp_path / "f"), "--sampler", "laplace"])
    assert code == EXIT_INPUT_ERROR
    err = capsys.readouterr().err
    assert "never loads" in err and "flat" in err and err.count("\n") == 1


def test_model_play_and_loading_stiffness_match_the_data_only_reading(tmp_path):
    """SYNTHETIC bench with play ramps and real-loop friction (load-dependent Maxwell-slip):
    the truth model's ``play`` and ``stiffness_loading``, read off its own noise-free record of
    the data's cycle amplitudes, agree with the data-only reading of the simulated data; a
    campaign without hysteresis cycles has neither."""
    from torsionfit.metrics import campaign_metrics

    text = BENCH.read_text().replace("[truth]", "[effects]\nload_dependent_friction = true\ndistributed_friction = true\n[truth]\n"
                                     "friction_load_coefficient = 0.15\nbreakaway_spread = 0.6")
    text = text.replace("dahl_torque_Nm = 4.0\n", "").replace("loading_rate_Nm_per_s = 5.0", "loading_rate_Nm_per_s = 5.0\nplay_cycles = 3\nplay_torque_Nm = 40.0")
    path = tmp_path / "bench.toml"
    path.write_text(text)
    sim = simulate(load_bench(path), seed=4)
    derived = derived_metrics_for(sim.campaign, sim.model)
    truth = dict(zip((s.name for s in derived.specs), np.asarray(derived.evaluate(sim.truth))))
    data = {r["kind"]: r["metrics"] for r in campaign_metrics(sim.campaign)["runs"]}["hysteresis"]
    assert truth["play"] == pytest.approx(data["play"]["value"], rel=0.05)
    assert truth["stiffness_loading"] == pytest.approx(data["stiffness_loading"]["value"], rel=0.05)
    # load-dependent friction: loading branches steeper in torque than the spring (1 − μ)
    assert truth["stiffness_loading"] > 1.05 * truth["stiffness_elastic"]
    te_only = derived_metrics_for(simulate(load_bench(Path(__file__).parent / "benches" / "stat_te_only.toml"), seed=1).campaign,
                                  sim.model)
    assert "play" not in [s.name for s in te_only.specs]


def test_the_model_read_off_the_record_starts_from_the_runs_fitted_state(tmp_path):
    """SYNTHETIC bench whose slip elements break away above the play ramps' torque: the state
    they start in holds through every play ramp. The model's ``play`` read off the data's own
    record is the play of the model's prediction of that record from the run's fitted state at
    its first sample (``friction_start``), not from rest — which draws another play ramp loop."""
    from torsionfit.fit._problem import model_inputs
    from torsionfit.metrics import cycle_classes, play_of
    from torsionfit.report._pipeline import campaign_model

    effects = {"load_dependent_friction": True, "distributed_friction": True}
    text = BENCH.read_text().replace("[truth]", "[effects]\nload_dependent_friction = true\ndistributed_friction = true\n[truth]\n"
                                     "friction_load_coefficient = 0.15\nbreakaway_spread = 0.6")
    text = text.replace("dahl_torque_Nm = 4.0\n", "").replace("friction_torque_Nm = 6.0", "friction_torque_Nm = 30.0")
    text = text.replace("loading_rate_Nm_per_s = 5.0", "loading_rate_Nm_per_s = 5.0\nplay_cycles = 3\nplay_torque_Nm = 40.0")
    path = tmp_path / "bench.toml"
    path.write_text(text)
    with torsionfit.float64():
        sim = simulate(load_bench(path), seed=4)
        model = campaign_model(sim.campaign, FitOptions(effects=effects))
        derived = derived_metrics_for(sim.campaign, model)
        at = [s.name for s in derived.specs].index("play")
        run = sim.campaign.runs[0]
        plays = {}
        for start in (0.0, 0.9, -0.9):
            values = {**sim.truth, "friction_start": np.array([start])}
            theta = np.asarray(model.predict(values, model_inputs(sim.campaign))[0])
            own = play_of(cycle_classes(np.asarray(run.time_s), np.asarray(run.torque_Nm), theta).smallest)
            plays[start] = np.degrees(own) * 60.0  # arcmin
            assert float(np.asarray(derived.evaluate(values))[at]) == pytest.approx(plays[start], rel=1e-6)
    # the start state moves the play ramps' loop (else the check above could not fail)
    assert abs(plays[0.9] - plays[0.0]) > 0.1 * plays[0.0] and abs(plays[-0.9] - plays[0.0]) > 0.1 * plays[0.0]


def test_a_fit_with_parts_that_vanish_at_zero_starts_from_the_model_without_them():
    from torsionfit.report._pipeline import _without_nested

    effects = {"gap_lag": True, "load_dependent_friction": {"lag": True}, "distributed_friction": True}
    assert _without_nested(effects) == {"load_dependent_friction": True, "distributed_friction": True}
    assert _without_nested({"load_dependent_friction": True, "gap_lag": False}) == {"load_dependent_friction": True, "gap_lag": False}


def test_a_fit_with_an_odd_stepped_gap_starts_from_the_plain_gap():
    """An odd number of gap steps has one at zero torque, so the plain gap is a case of it: the
    fit first fits without the steps and starts with most of the gap on that middle step; an
    even number has no such case and fits without that start."""
    import jax.numpy as jnp

    from torsionfit.model import SmoothBacklash
    from torsionfit.report._pipeline import _without_nested, gap_on_the_middle_step, prepare_fit

    campaign = simulate(load_bench(BENCH), seed=1).campaign  # SYNTHETIC
    rated = float(campaign.reducer.rated_torque_Nm)
    odd = {"gap_steps": {"steps": 7, "span_Nm": 0.05 * rated}, "distributed_friction": True}
    _, model, problem = prepare_fit(campaign, FitOptions(effects=odd, progress=False))
    assert _without_nested(odd, model) == {"distributed_friction": True}
    even = {"gap_steps": {"steps": 6, "span_Nm": 0.05 * rated}}
    _, even_model, even_problem = prepare_fit(campaign, FitOptions(effects=even, progress=False))
    assert _without_nested(even, even_model) == even
    with pytest.raises(ValueError, match="odd number of steps"):
        gap_on_the_middle_step(even_problem, [r.name for r in campaign.runs], np.asarray(even_problem.prior_mean))
    names = [r.name for r in campaign.runs]
    start = gap_on_the_middle_step(problem, names, np.asarray(problem.prior_mean))
    values = problem.physics_values(jnp.asarray(start[:problem.n_nonlinear]))
    shares = np.asarray(model.backlash.shares(values))
    assert shares[3] > 0.9 and shares[3] == shares.max()
    # the stepped gap at that start is the plain gap with the same β and τ_β, within the 6 % off the middle
    tau = jnp.linspace(-rated, rated, 401)
    stepped, plain = np.asarray(model.backlash(values, tau)), np.asarray(SmoothBacklash()(values, tau))
    assert np.max(np.abs(stepped - plain)) <= 0.07 * float(values["gap"])


def test_the_gap_with_a_soft_first_segment_is_a_metric_of_three_segment_models(noisy_bench):
    """``gap_with_first_segment`` = β + 2·T1·(1/K1 − 1/K2) (floored at 0) for a three-segment
    compliance, and no metric for a linear one (whose gap alone is its gap-like lost motion)."""
    from torsionfit.report._pipeline import _values_over_draws, prepare_fit

    sim = simulate(load_bench(noisy_bench), seed=4)
    assert "gap_with_first_segment" not in {s.name for s in derived_metrics_for(sim.campaign, sim.model).specs}
    campaign, model, problem = prepare_fit(sim.campaign, FitOptions(sampler="laplace",
                                                                    effects={"stiffness_nonlinearity": "three_segment"}))
    derived = derived_metrics_for(campaign, model)
    names = [s.name for s in derived.specs]
    values = {k: float(np.asarray(v)[0]) for k, v in _values_over_draws(problem, np.asarray(problem.prior_mean)[None], False).items()}
    arcmin = np.radians(1.0 / 60.0)
    for k1, expected in ((values["k2"] / 14.0, 2.0 * values["t1"] * (14.0 - 1.0) / values["k2"]), (2.0 * values["k2"], 0.0)):
        out = dict(zip(names, np.asarray(derived.evaluate({**values, "k1": k1}))))
        assert out["gap_with_first_segment"] == pytest.approx((values["gap"] + expected) / arcmin, rel=1e-9)
        assert out["geometric_gap"] == pytest.approx(values["gap"] / arcmin, rel=1e-9)


@pytest.mark.parametrize("moves, final, wanted", [(100, 100, (100, 100)), (300, 100, (300, 300)),
                                                  (100, 300, (100, 300)), (300, 500, (300, 500))])
def test_smc_gets_the_moves_allowed_at_every_stage_and_at_the_last(monkeypatch, moves, final, wanted):
    """``smc_max_moves`` is every stage's budget and the last stage gets at least as many."""
    import torsionfit.sample
    import torsionfit.sample._emcee as emcee_module
    from torsionfit.report import _pipeline

    seen = {}
    monkeypatch.setattr(_pipeline, "laplace_approximation", lambda *a, **k: "approximation")
    monkeypatch.setattr(emcee_module, "_LogProb", lambda problem, batch: "log_p")
    monkeypatch.setattr(emcee_module, "_LogProbGrad", lambda problem, batch: "log_p_and_grad")
    monkeypatch.setattr(torsionfit.sample, "tempered_smc", lambda *a, **k: seen.update(k))
    map_result = dataclasses.make_dataclass("MapResult", ["u", "names"])(np.zeros(2), ("a", "b"))
    options = FitOptions(sampler="smc", smc_max_moves=moves, smc_final_max_moves=final, progress=False)
    _pipeline.run_smc(None, map_result, options, 0)
    assert (seen["max_moves"], seen["final_max_moves"]) == wanted


def test_smc_sampler_draws_the_posterior_and_reports_its_schedule(noisy_bench, tmp_path):
    """``sampler="smc"``: tempered SMC from the split normal; on the model's own bench the
    posterior is near Gaussian, so the particles agree with the Laplace draws' spread, and
    fit.json carries the schedule and whether every stage's moves forgot their start. Keeping
    the chain (``backend_path``) keeps SMC's state in ``chain-smc.npz``; resumed, the finished
    run's particles come back as they were."""
    sim = simulate(load_bench(noisy_bench), seed=4)
    options = FitOptions(sampler="smc", n_starts=2, smc_particles=200, progress=False, backend_path=str(tmp_path / "chain.h5"))
    fit = fit_campaign(sim.campaign, options, seed=0)
    assert (tmp_path / "chain-smc.npz").is_file()
    again = fit_campaign(sim.campaign, dataclasses.replace(options, resume=True), seed=0)
    np.testing.assert_array_equal(again.draws_u, fit.draws_u)
    d = fit.diagnostics
    assert d["sampler"] == "smc" and d["smc_particles"] == 200 and d["smc_betas"][-1] == 1.0
    assert d["converged"] == (d["reason"] == "") and d["converged"], d["reason"]
    assert len(d["smc_moves"]) == len(d["smc_betas"]) and d["smc_correlation_max"] <= 0.1
    assert d["smc_max_moves"] == [100] * len(d["smc_betas"])
    assert len(d["smc_modes"]) == len(d["smc_betas"]) and sum(d["smc_mode_shares"]) == pytest.approx(1.0)
    assert len(d["smc_leapfrog_steps"]) == len(d["smc_betas"]) and all(1 <= s <= 64 for s in d["smc_leapfrog_steps"])
    assert 0.0 < d["smc_correlation_floor"] < 0.2
    assert fit.draws_u.shape[0] == 200
    # the Laplace approximation holds on the model's own bench: the same spread within a third
    cov_sd = np.sqrt(np.diag(fit.map_result.cov))
    ratio = fit.draws_u.std(axis=0)[: len(cov_sd)] / cov_sd
    assert np.median(ratio) == pytest.approx(1.0, abs=0.33)
    doc = fit_json(fit)
    assert doc["diagnostics"]["sampler"] == "smc" and doc["metrics"]["stiffness_rated"]["hdi95"]
