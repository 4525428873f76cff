"""Separated modes among particles (sample/_modes.py): found where the particles stand apart,
not in one Gaussian, a uniform block or a curved ridge; the correlation within them."""

import numpy as np
import pytest

from torsionfit.sample._modes import separated_modes, within_mode_correlations


def _two_modes(rng, separation, share=0.3, n=1000, dim=6):
    left = rng.random(n) < share
    x = rng.normal(size=(n, dim))
    x[:, 0] += np.where(left, -separation / 2, separation / 2)
    return x, left


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_two_modes_many_widths_apart_are_found_with_their_members(seed):
    x, left = _two_modes(np.random.default_rng(seed), 8.0)
    labels = separated_modes(x[:, :1])  # the coordinate that remembers its start
    assert labels.max() == 1
    agree = np.mean((labels == labels[np.argmin(x[:, 0])]) == left)
    assert agree > 0.99


@pytest.mark.parametrize("seed", [0, 1])
def test_one_gaussian_a_uniform_block_a_curved_ridge_and_modes_barely_apart_are_one_mode(seed):
    rng = np.random.default_rng(seed)
    gaussian = rng.normal(size=(1000, 6)) @ rng.normal(size=(6, 6))
    uniform = rng.random((1000, 3))
    x1 = rng.normal(scale=3.0, size=1000)
    ridge = np.c_[x1, 0.5 * (x1**2 - 9) + rng.normal(size=1000), rng.normal(size=(1000, 2))]
    close = _two_modes(rng, 2.5)[0][:, :1]  # a dip between them, but HMC crosses it
    for x in (gaussian, uniform, ridge, close):
        assert separated_modes(x).max() == 0


def test_a_small_group_is_not_a_mode_three_are_found_and_more_than_four_read_as_one():
    rng = np.random.default_rng(3)
    x = rng.normal(size=(1000, 3))
    x[:20, 0] += 30.0  # 2 % of the particles: below the smallest share of a mode
    assert separated_modes(x).max() == 0
    three = rng.normal(size=(900, 1)) + np.repeat([-15.0, 0.0, 15.0], 300)[:, None]
    assert separated_modes(three).max() + 1 == 3
    # more modes than are looked for: one mode, the stricter reading (no mode's memory excused)
    six = rng.normal(size=(1200, 1)) + np.repeat(20.0 * np.arange(6), 200)[:, None]
    assert separated_modes(six).max() == 0


def test_within_one_mode_the_correlation_is_the_plain_one_and_within_two_it_drops_the_mode():
    rng = np.random.default_rng(4)
    x, left = _two_modes(rng, 8.0, dim=2)
    now = x.copy()
    now[:, 1:] = rng.normal(size=(len(x), 1))  # mixed within the mode; the mode kept
    now[:, 0] = np.where(left, -4.0, 4.0) + rng.normal(size=len(x))
    plain = within_mode_correlations(x, now, np.zeros(len(x), int))
    a, b = x - x.mean(0), now - now.mean(0)
    np.testing.assert_allclose(plain, np.abs((a * b).sum(0)) / np.sqrt((a**2).sum(0) * (b**2).sum(0)))
    assert plain[0] > 0.9
    assert within_mode_correlations(x, now, left.astype(int))[0] < 0.15
