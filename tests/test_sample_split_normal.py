"""The split-normal approximation around the MAP (sample/_split_normal.py)."""

import numpy as np
import pytest

from torsionfit.sample import SplitNormal, split_normal


def _gaussian(sd_neg, sd_pos):
    """Log density (up to a constant) of independent split normals with these widths."""
    sd_neg, sd_pos = np.asarray(sd_neg, float), np.asarray(sd_pos, float)

    def log_density(x):
        x = np.atleast_2d(x)
        return np.sum(-0.5 * (x / np.where(x < 0, sd_neg, sd_pos)) ** 2, axis=1)

    return log_density


def test_a_gaussian_posterior_keeps_the_laplace_widths():
    cov = np.diag([4.0, 0.25, 1.0])
    approx = split_normal(_gaussian(np.sqrt(np.diag(cov)), np.sqrt(np.diag(cov))), np.zeros(3), cov)
    np.testing.assert_allclose(approx.scales, 1.0, atol=0.02)
    x = np.random.default_rng(0).normal(size=(5, 3))
    gaussian = -0.5 * np.sum(x**2 / np.diag(cov), axis=1) - 0.5 * np.sum(np.log(2 * np.pi * np.diag(cov)))
    np.testing.assert_allclose(approx.log_density(x), gaussian, atol=0.05)


def test_each_half_axis_takes_the_width_the_posterior_has():
    """A posterior 3× narrower than its curvature says on one side, 2× wider on another, along
    rotated axes: the measured widths come back to within the grid's interpolation."""
    angle = 0.4
    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    sd = np.array([1.0, 0.2])
    cov = rot @ np.diag(sd**2) @ rot.T
    true_neg, true_pos = sd * np.array([1 / 3, 1.0]), sd * np.array([1.0, 2.0])
    along = _gaussian(true_neg, true_pos)

    def log_density(x):
        return along(np.atleast_2d(x) @ rot)  # coordinates along the axes

    approx = split_normal(log_density, np.zeros(2), cov)
    order = np.argsort(approx.sd)[::-1]  # eigh orders by size: the wide axis last
    widths = approx.widths[order]
    flipped = np.sum(approx.axes[:, order] * rot, axis=0) < 0  # eigh's sign of each axis is arbitrary
    widths[flipped] = widths[flipped][:, ::-1]
    np.testing.assert_allclose(widths, np.stack([true_neg, true_pos], axis=1), rtol=0.03)


def test_a_wall_beyond_the_curvature_shrinks_that_side():
    """Flat near the mode, then a wall at 0.5 sd: the draws stay inside it, where the Laplace
    draws of the same curvature would not (the failure on measured loops)."""
    def log_density(x):
        x = np.atleast_2d(x)[:, 0]
        return -0.5 * x**2 - 200.0 * np.maximum(np.abs(x) - 0.5, 0.0) ** 2

    approx = split_normal(log_density, np.zeros(1), np.eye(1))
    assert np.all(approx.scales < 0.6)
    draws = approx.draw(np.random.default_rng(1), 20_000)
    assert np.mean(np.abs(draws) > 1.0) < 0.1  # the Gaussian of sd 1: 32 %


def test_split_normal_draws_and_density_agree():
    """The density integrates to 1 and the draws follow it: the mass on the negative side is
    σ₋/(σ₋ + σ₊) and each side's spread its width (the density is continuous at the mode)."""
    approx = SplitNormal(mean=np.array([2.0]), axes=np.eye(1), sd=np.array([1.5]), scales=np.array([[0.4, 1.6]]))
    grid = np.linspace(-20, 20, 400_001)
    density = np.exp(approx.log_density(grid[:, None]))
    assert np.sum(density) * (grid[1] - grid[0]) == pytest.approx(1.0, abs=1e-6)
    left, right = approx.log_density(np.array([[2.0 - 1e-9], [2.0 + 1e-9]]))
    assert left == pytest.approx(right, abs=1e-6)
    draws = approx.draw(np.random.default_rng(2), 200_000)[:, 0] - 2.0
    lo, hi = 1.5 * 0.4, 1.5 * 1.6
    assert np.mean(draws < 0) == pytest.approx(lo / (lo + hi), abs=0.005)
    assert np.sqrt(np.mean(draws[draws < 0] ** 2)) == pytest.approx(lo, rel=0.01)
    assert np.sqrt(np.mean(draws[draws > 0] ** 2)) == pytest.approx(hi, rel=0.01)


def test_an_axis_without_width_stays_a_point():
    cov = np.diag([1.0, 0.0])
    approx = split_normal(_gaussian([1.0, 1e-9], [1.0, 1e-9]), np.zeros(2), cov)
    draws = approx.draw(np.random.default_rng(3), 100)
    assert np.all(np.isfinite(draws)) and np.allclose(draws @ approx.axes[:, np.argmin(approx.sd)], 0.0)
