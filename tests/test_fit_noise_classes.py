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
    refit_with_class_noise,
)
from torsionfit.report import FitOptions, campaign_model

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
