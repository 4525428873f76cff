"""The mixture of split normals over a posterior's optima (sample/_mixture.py)."""

import numpy as np
import pytest

from torsionfit.sample import SplitNormalMixture, evidence_log_weights, split_normal

#: a two-mode posterior in 2-D: masses 0.3 and 0.7, the lighter mode the higher peak (narrower)
MASSES = np.array([0.3, 0.7])
CENTRES = np.array([[0.0, 0.0], [6.0, -4.0]])
SDS = np.array([[0.5, 0.4], [1.5, 1.0]])


def _log_posterior(x):
    """Unnormalised (× e³): the two Gaussians' mixture."""
    x = np.atleast_2d(x)
    parts = [np.log(m) + np.sum(-0.5 * ((x - c) / s) ** 2 - np.log(np.sqrt(2 * np.pi) * s), axis=1)
             for m, c, s in zip(MASSES, CENTRES, SDS)]
    return np.logaddexp.reduce(parts, axis=0) + 3.0


def _mixture():
    components = tuple(split_normal(_log_posterior, c, np.diag(s**2)) for c, s in zip(CENTRES, SDS))
    lp = _log_posterior(CENTRES)
    lq = np.array([q.log_density(c[None])[0] for q, c in zip(components, CENTRES)])
    return SplitNormalMixture(components, evidence_log_weights(lp, lq))


def test_the_evidence_weights_are_the_modes_masses():
    """The higher peak carries the smaller mass: weights by the peaks' heights alone would invert
    them; by each component's volume they come back."""
    mix = _mixture()
    np.testing.assert_allclose(mix.weights, MASSES, atol=0.01)
    assert _log_posterior(CENTRES[:1])[0] > _log_posterior(CENTRES[1:])[0]


def test_draws_fall_in_each_mode_by_its_weight_and_are_shuffled():
    mix = _mixture()
    x = mix.draw(np.random.default_rng(3), 20_000)
    near_second = np.linalg.norm(x - CENTRES[1], axis=1) < np.linalg.norm(x - CENTRES[0], axis=1)
    assert np.mean(near_second) == pytest.approx(0.7, abs=0.02)
    assert 0.55 < np.mean(near_second[:1000]) < 0.85  # not all of one component first
    np.testing.assert_allclose(x[near_second].std(axis=0), SDS[1], rtol=0.05)


def test_the_density_is_normalised_and_its_gradient_exact():
    mix = _mixture()
    g = np.linspace(-12, 16, 561)
    xx, yy = np.meshgrid(g, g)
    grid = np.stack([xx.ravel(), yy.ravel()], axis=1)
    mass = np.sum(np.exp(mix.log_density(grid))) * (g[1] - g[0]) ** 2
    assert mass == pytest.approx(1.0, abs=1e-3)
    x = np.array([[1.0, -0.5], [4.0, -3.0], [3.0, -2.0]])
    h = 1e-6
    numeric = np.stack([(mix.log_density(x + h * e) - mix.log_density(x - h * e)) / (2 * h) for e in np.eye(2)], axis=1)
    np.testing.assert_allclose(mix.grad_log_density(x), numeric, rtol=1e-5, atol=1e-6)


def test_bad_weights_say_so():
    q = _mixture().components
    with pytest.raises(ValueError, match="2 components but 1 weights"):
        SplitNormalMixture(q, np.zeros(1))
    with pytest.raises(ValueError, match="do not sum to 1"):
        SplitNormalMixture(q, np.zeros(2))
    with pytest.raises(ValueError, match="evidence is not finite"):
        evidence_log_weights([0.0, -np.inf], [0.0, 0.0])
