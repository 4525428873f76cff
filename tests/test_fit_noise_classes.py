"""A noise level per cycle class (fit/_noise_classes.py) on the SYNTHETIC friction bench
(tests/benches/friction/base.toml: play ramps before the stiffness ramps)."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from torsionfit.bench import load_bench, simulate
from torsionfit.fit import NoiseOptions, build_problem, fit_map
from torsionfit.fit._noise_classes import (
    amplitude_classes,
    class_noise_shape,
    class_shares,
    excursion_classes,
    first_excursion_index,
    first_excursions,
    refit_with_class_noise,
)
from torsionfit.report import FitOptions, campaign_model, fit_campaign

BENCH = Path(__file__).parent / "benches" / "friction" / "base.toml"


@pytest.fixture(scope="module")
def campaign():
    return simulate(load_bench(BENCH), seed=11).campaign


def test_classes_split_the_play_ramps_from_the_stiffness_ramps(campaign):
    run = campaign.runs[0]  # ±30 N·m play ramps, then the protocol up to the rated 380 N·m
    classes = amplitude_classes(run.torque_Nm)
    assert set(np.unique(classes)) == {0, 1}
    small = np.abs(run.torque_Nm) <= 35.0  # the play ramps' ±30 N·m and the torque noise
    # every sample beyond the play ramps' torque is in the large class; the play ramps are the small one
    assert np.all(classes[~small] == 0)
    # the play ramps up to their last trough; the ramp from there to the protocol's peak is large
    first_large = int(np.argmax(np.abs(run.torque_Nm) > 35.0))
    last_trough = int(np.argmin(run.torque_Nm[:first_large]))
    assert np.mean(classes[:last_trough] == 1) > 0.95
    assert np.all(classes[last_trough + 3:first_large] == 0)


def test_one_amplitude_is_one_class():
    t = np.linspace(0.0, 40.0, 4001)
    assert np.all(amplitude_classes(10.0 * np.sin(2 * np.pi * t / 10.0)) == 0)


def test_a_class_too_small_for_a_level_joins_its_neighbour():
    t = np.linspace(0.0, 40.0, 4001)
    torque = 40.0 * np.sin(2 * np.pi * t / 10.0)
    torque[:30] = np.linspace(0.0, 2.0, 30)  # a few samples of a tiny ramp first
    assert np.all(amplitude_classes(torque, min_samples=50) == 0)


def test_shares_are_the_classes_rms_over_the_largest():
    rng = np.random.default_rng(0)
    classes = np.repeat([0, 1, 0, 1], 5000)
    residual = rng.standard_normal(classes.size) * np.where(classes == 1, 3.0, 1.0)
    shape = class_noise_shape(residual, classes)
    assert shape[classes == 0] == pytest.approx(1.0)
    assert shape[classes == 1][0] == pytest.approx(3.0, rel=0.03)
    # the encoder floor is not the classes' noise
    shape = class_noise_shape(residual, classes, floor_rad=0.9)
    assert shape[classes == 1][0] == pytest.approx(np.sqrt((9 - 0.81) / (1 - 0.81)), rel=0.08)


def test_refit_finds_the_play_ramps_noise_and_one_level_where_there_is_one(campaign):
    """Clean bench: one level (shares ≈ 1); with 4× the angle noise added on the play ramps
    alone, their share ≈ 4 (the noise above the 1″ encoder step)."""
    options = FitOptions(noise=NoiseOptions(ar1=False, cycle_class_noise=True))
    model = campaign_model(campaign, options)

    def shares(camp):
        problem = build_problem(camp, model, options.noise)
        result = fit_map(problem, [r.name for r in camp.runs], n_starts=1, seed=0)
        problem, result = refit_with_class_noise(problem, result)
        return class_shares(problem)

    for run_shares in shares(campaign):
        assert run_shares[0] == 1.0 and run_shares[1] == pytest.approx(1.0, abs=0.25), run_shares
    rng = np.random.default_rng(1)
    sd = np.deg2rad(1.0 / 3600.0) * np.sqrt(15.0)  # 1″ → 4″ in all: √(16 − 1) more
    runs = []
    for run in campaign.runs:
        small = amplitude_classes(run.torque_Nm) == 1
        runs.append(dataclasses.replace(run, angle_rad=run.angle_rad + small * sd * rng.standard_normal(len(run))))
    for run_shares in shares(dataclasses.replace(campaign, runs=tuple(runs))):
        assert run_shares[1] == pytest.approx(4.0, rel=0.2), run_shares


def test_class_noise_and_amplitude_noise_are_exclusive(campaign):
    noise = NoiseOptions(cycle_class_noise=True, cycle_amplitude_noise=True)
    with pytest.raises(ValueError, match="choose one"):
        build_problem(campaign, campaign_model(campaign, FitOptions(noise=noise)), noise)


def test_the_batch_and_diagnose_refuse_class_noise_they_would_not_refit(campaign):
    from torsionfit.batch import BatchOptions
    from torsionfit.diagnose import DiagnoseOptions, diagnose

    noise = NoiseOptions(cycle_class_noise=True)
    with pytest.raises(ValueError, match="not supported by the batch"):
        BatchOptions(fit=FitOptions(noise=noise))
    with pytest.raises(ValueError, match="diagnose: NoiseOptions.cycle_class_noise"):
        diagnose(campaign, DiagnoseOptions(noise=noise))
    # conditioning samples: the batch's MAP is not checked with them, diagnose's screens read every sample
    noise = NoiseOptions(first_excursion_conditioning=True)
    with pytest.raises(ValueError, match="first_excursion_conditioning is not supported by the batch"):
        BatchOptions(fit=FitOptions(noise=noise))
    with pytest.raises(ValueError, match="diagnose: NoiseOptions.first_excursion_conditioning"):
        diagnose(campaign, DiagnoseOptions(noise=noise))


def _ramps(peaks, n=120):
    """Triangular torque through 0 → each peak in turn (N·m), n samples per leg, a little noise."""
    legs = [np.linspace(a, b, n, endpoint=False) for a, b in zip([0.0, *peaks[:-1]], peaks)]
    return np.concatenate(legs) + 0.01 * np.random.default_rng(0).standard_normal(n * len(peaks))


def test_first_excursions_are_the_ramps_that_first_load_beyond_the_earlier_peaks():
    """Play ramps to ±4 N·m, then three large cycles to ±40: the ramps to the first +40 and the
    first −40 are first excursions, the repeats are not, nor a ramp 5 % beyond an earlier peak
    (the margin is 10 %). (The play ramps' turns are within the segmentation's threshold, 5 % of
    the torque range: they are not ramps of their own here.)"""
    peaks = [4, -4, 4, -4, 40, -40, 40, -40, 42, -40, 0]
    tau = _ramps(peaks)
    first = first_excursions(tau)
    leg = np.repeat(np.arange(len(peaks)), 120)
    share = np.array([first[leg == k][10:-10].mean() for k in range(len(peaks))])  # away from the turns
    assert np.all(share[[4, 5]] == 1.0), share
    assert np.all(share[[6, 7, 8, 9, 10]] == 0.0), share
    classes = excursion_classes(tau)
    # class 0 the repeated large cycles, 1 the play ramps, 2 the large first excursions
    assert set(np.unique(classes)) == {0, 1, 2}
    assert np.all(classes[(leg == 4) | (leg == 5)][10:-10] == 2)
    assert np.all(classes[(leg >= 6) & (leg <= 9)][10:-10] == 0)
    # large ramps that all load beyond the earlier peaks: no repeats to set them apart from, no split
    assert set(np.unique(excursion_classes(_ramps([4, -4, 4, -4, 40, -40])))) <= {0, 1}


def test_the_first_excursion_class_needs_the_class_noise(campaign):
    with pytest.raises(ValueError, match="first_excursion_class is a cycle class"):
        build_problem(campaign, campaign_model(campaign, FitOptions()), NoiseOptions(first_excursion_class=True))


def test_conditioning_and_a_class_of_their_own_are_exclusive(campaign):
    noise = NoiseOptions(cycle_class_noise=True, first_excursion_class=True, first_excursion_conditioning=True)
    with pytest.raises(ValueError, match="nothing to weigh"):
        build_problem(campaign, campaign_model(campaign, FitOptions(noise=noise)), noise)


def _shaken(campaign, arcsec_at_peak: float):
    """``campaign`` with a twist the model cannot draw on its first excursions only: a softer
    first loading, ``arcsec_at_peak`` at the rated 380 N·m (a loop that shakes down)."""
    runs = []
    for run in campaign.runs:
        first = excursion_classes(run.torque_Nm) == first_excursion_index(run.torque_Nm)
        extra = first * np.deg2rad(arcsec_at_peak / 3600.0) * run.torque_Nm / 380.0
        runs.append(dataclasses.replace(run, angle_rad=run.angle_rad + extra))
    return dataclasses.replace(campaign, runs=tuple(runs))


def _class_fit(campaign, first: bool):
    noise = NoiseOptions(ar1=False, cycle_class_noise=True, first_excursion_class=first)
    problem = build_problem(campaign, campaign_model(campaign, FitOptions(noise=noise)), noise)
    result = fit_map(problem, [r.name for r in campaign.runs], n_starts=1, seed=0)
    problem, result = refit_with_class_noise(problem, result)
    return float(result.values["stiffness"]), class_shares(problem)


@pytest.mark.extended
def test_a_first_excursion_the_model_cannot_draw_is_weighed_down_and_never_up():
    """SYNTHETIC friction bench with three cycles per run (a first excursion, two repeats), its
    first excursions given 20″ more twist at the peak: as repeats they pull the fitted stiffness
    2 % off the clean fit's; as a class of their own their level comes out several times the
    repeats' and the stiffness within 0.2 % of the clean fit's. With one cycle (the first
    excursions outnumber the repeats) their share is held at 1: the fit is the one without the
    class, not one that weighs the repeats down."""
    bench = load_bench(BENCH)
    three = simulate(dataclasses.replace(bench, runs=tuple(dataclasses.replace(r, cycles=3) for r in bench.runs)),
                     seed=11).campaign
    clean, clean_shares = _class_fit(three, True)
    assert all(s[2] == pytest.approx(1.0, abs=0.3) for s in clean_shares), clean_shares  # nothing to weigh down
    shaken = _shaken(three, 20.0)
    as_repeats, _ = _class_fit(shaken, False)
    apart, shares = _class_fit(shaken, True)
    assert abs(as_repeats / clean - 1) > 0.01
    assert abs(apart / clean - 1) < 0.002 and all(s[2] > 3.0 for s in shares), (clean, apart, shares)
    one = _shaken(simulate(bench, seed=11).campaign, 20.0)
    without, _ = _class_fit(one, False)
    held, one_shares = _class_fit(one, True)
    assert all(s[2] == 1.0 for s in one_shares), one_shares
    assert held == pytest.approx(without, rel=1e-3)


def _conditioned_fit(campaign, conditioning: bool):
    noise = NoiseOptions(ar1=False, first_excursion_conditioning=conditioning)
    problem = build_problem(campaign, campaign_model(campaign, FitOptions(noise=noise)), noise)
    return float(fit_map(problem, [r.name for r in campaign.runs], n_starts=1, seed=0).values["stiffness"])


def test_conditioning_first_excursions_leaves_them_out_of_the_fit():
    """SYNTHETIC friction bench with three cycles per run, the first excursions given 20″ more
    twist at the peak: as conditioning cycles (state, no likelihood) the stiffness is within
    0.2 % of the clean fit's, where weighed as repeats it is 2 % off."""
    bench = load_bench(BENCH)
    three = simulate(dataclasses.replace(bench, runs=tuple(dataclasses.replace(r, cycles=3) for r in bench.runs)),
                     seed=11).campaign
    clean = _conditioned_fit(three, False)
    shaken = _shaken(three, 20.0)
    assert abs(_conditioned_fit(shaken, False) / clean - 1) > 0.01
    assert abs(_conditioned_fit(shaken, True) / clean - 1) < 0.002


def _a_point(problem):
    """A point of ``problem``'s u (the priors' means, noise levels of a few arcsec): the
    identities below hold at any point, so no fit is needed to reach one."""
    import jax.numpy as jnp

    return jnp.asarray(np.concatenate([np.asarray(problem.prior_mean), np.full(problem.n_runs, np.log(1e-5)),
                                       np.zeros(problem.n_ar1)]))


@pytest.mark.parametrize("ar1", [False, True])
def test_samples_out_of_the_likelihood_weigh_nothing(campaign, ar1):
    """With the first excursions conditioning, the log density and the closed-form noise update
    do not move when their angles do (AR(1): the whitening restarts after them); every other
    sample's angle moves both."""
    import jax.numpy as jnp

    from torsionfit.fit._map import _noise_update

    bench = load_bench(BENCH)
    three = simulate(dataclasses.replace(bench, runs=tuple(dataclasses.replace(r, cycles=2) for r in bench.runs)),
                     seed=3).campaign
    noise = NoiseOptions(ar1=ar1, first_excursion_conditioning=True)
    model = campaign_model(three, FitOptions(noise=noise))
    problem = build_problem(three, model, noise)
    keep = problem.kept_samples()
    assert all(0 < np.sum(~k) < k.size for k in keep)  # each run has conditioning samples and others
    u = _a_point(problem)
    assert u.size == problem.dim and np.isfinite(float(problem.log_density(u)))

    import equinox as eqx

    for where, moves in (([~k for k in keep], False), ([k for k in keep], True)):
        # a random move (a constant one the angle offset would absorb)
        rng = np.random.default_rng(1)
        y = [v + jnp.asarray(np.where(w, 3e-5 * rng.standard_normal(w.size), 0.0)) for v, w in zip(problem.y, where)]
        other = eqx.tree_at(lambda p: p.y, problem, y)
        same_density = float(other.log_density(u)) == pytest.approx(float(problem.log_density(u)), rel=1e-12, abs=1e-9)
        same_noise = np.allclose(np.asarray(_noise_update(other, u)), np.asarray(_noise_update(problem, u)), rtol=1e-10)
        assert same_density != moves and same_noise != moves, (where, moves)


def test_a_conditioned_fit_reports_its_conditioning_samples_and_its_loo_reads_the_others():
    """SYNTHETIC friction bench, three cycles: fit.json counts each run's conditioning samples,
    the tree's log-likelihood holds the other samples only (constant zeros would stop PSIS) and
    PSIS-LOO runs on it, per run too."""
    from torsionfit.sample._tree import psis_loo

    bench = load_bench(BENCH)
    three = simulate(dataclasses.replace(bench, runs=tuple(dataclasses.replace(r, cycles=3) for r in bench.runs)),
                     seed=11).campaign
    noise = NoiseOptions(ar1=False, first_excursion_conditioning=True)
    fit = fit_campaign(three, FitOptions(noise=noise, sampler="laplace", progress=False, n_starts=1))
    kept = fit.problem.kept_samples()
    assert fit.diagnostics["conditioning_samples"] == {r.name: int(np.sum(~k)) for r, k in zip(three.runs, kept)}
    assert all(0 < n < len(r) // 2 for r, n in zip(three.runs, fit.diagnostics["conditioning_samples"].values()))
    from torsionfit.report import fit_json, summary_table

    line = [x for x in summary_table(fit_json(fit)).splitlines() if x.startswith("conditioning")]
    assert line and all(f"{r.name} {n}" in line[0] for r, n in zip(three.runs, fit.diagnostics["conditioning_samples"].values()))
    tree = fit.tree
    assert tree["log_likelihood"]["angle"].shape[-1] == sum(int(np.sum(k)) for k in kept)
    assert tree["observed_data"]["angle"].shape[-1] == sum(len(r) for r in three.runs)
    assert np.isfinite(psis_loo(tree).elpd) and np.isfinite(psis_loo(tree, run=three.runs[0].name).elpd)


def test_declared_conditioning_rows_are_the_option_by_hand(campaign):
    """A run's conditioning rows ([runs.condition]) leave the likelihood as the option's first
    excursions do: the same rows declared give the same kept samples and the same log density;
    both together keep the samples neither leaves out."""
    from torsionfit.fit._noise_classes import conditioning_keep

    declared = dataclasses.replace(campaign, runs=tuple(
        dataclasses.replace(r, conditioning=~conditioning_keep(r.torque_Nm)) for r in campaign.runs))
    by_option = NoiseOptions(ar1=False, first_excursion_conditioning=True)
    model = campaign_model(campaign, FitOptions(noise=by_option))
    a = build_problem(campaign, model, by_option)
    b = build_problem(declared, model, NoiseOptions(ar1=False))
    assert all(np.array_equal(x, y) for x, y in zip(a.kept_samples(), b.kept_samples()))
    assert not all(k.all() for k in a.kept_samples())
    u = _a_point(b)
    assert float(a.log_density(u)) == pytest.approx(float(b.log_density(u)), rel=1e-12)
    first_rows = dataclasses.replace(campaign, runs=tuple(
        dataclasses.replace(r, conditioning=np.arange(len(r)) < 20) for r in campaign.runs))
    both = build_problem(first_rows, model, by_option).kept_samples()
    assert all(np.array_equal(k, x & (np.arange(len(k)) >= 20)) for k, x in zip(both, a.kept_samples()))
