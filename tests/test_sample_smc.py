"""Tempered SMC from an approximation to the posterior (sample/_smc.py): it recovers a posterior
its starting approximation misses, and says when it has not."""

import numpy as np
import pytest

from torsionfit.sample import SMCResult, SplitNormal, tempered_smc


def _target(mean, cov):
    """Log density (up to a constant) of N(mean, cov), −inf nowhere."""
    prec = np.linalg.inv(cov)

    def log_p(x):
        d = np.atleast_2d(x) - mean
        return -0.5 * np.einsum("ni,ij,nj->n", d, prec, d)

    return log_p


def _target_and_grad(mean, cov):
    """(log density, gradient) of N(mean, cov) per row."""
    prec = np.linalg.inv(cov)

    def both(x):
        d = np.atleast_2d(x) - mean
        return -0.5 * np.einsum("ni,ij,nj->n", d, prec, d), -d @ prec

    return both


def _banana(b=0.5):
    """A curved ridge in 4 dimensions (Haario et al. 1999): x₁ ~ N(0, 3²), x₂ | x₁ ~
    N(b·(x₁² − 9), 1), the others N(0, 1): log density and gradient. E[x₂] = 0, sd(x₂)² = 1 + 2·(9b)²."""

    def both(x):
        x = np.atleast_2d(x)
        with np.errstate(over="ignore", invalid="ignore"):  # a diverging trajectory: −inf, as the product's
            r = x[:, 1] - b * (x[:, 0] ** 2 - 9.0)
            lp = -0.5 * (x[:, 0] / 3.0) ** 2 - 0.5 * r**2 - 0.5 * np.sum(x[:, 2:] ** 2, axis=1)
            g = np.zeros_like(x)
            g[:, 0] = -x[:, 0] / 9.0 + r * 2.0 * b * x[:, 0]
            g[:, 1] = -r
            g[:, 2:] = -x[:, 2:]
        bad = ~np.isfinite(lp) | ~np.all(np.isfinite(g), axis=1)
        lp[bad], g[bad] = -np.inf, 0.0
        return lp, g

    return both


def _narrow_start(dim, sd=0.3):
    """A split normal at the origin, ``sd`` wide on every axis: too narrow and off-centre for
    the targets below (their Pareto k at its draws is far above 0.7)."""
    return SplitNormal(mean=np.zeros(dim), axes=np.eye(dim), sd=np.full(dim, sd), scales=np.ones((dim, 2)))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_posterior_wider_and_elsewhere_than_the_approximation_is_recovered(seed):
    dim = 6
    rng = np.random.default_rng(100 + seed)
    a = rng.normal(size=(dim, dim))
    cov = a @ a.T / dim + np.eye(dim)  # correlated, sds 1–2
    mean = rng.normal(scale=0.5, size=dim)
    res = tempered_smc(_target(mean, cov), _narrow_start(dim), np.random.default_rng(seed), 1000)
    x = res.chain[:, 0, :]
    assert isinstance(res, SMCResult) and res.converged and res.reason == ""
    assert res.betas[-1] == 1.0 and res.approximation_pareto_k > 0.7
    sd = np.sqrt(np.diag(cov))
    # 1000 nearly independent draws: the mean within 0.2 sd, each sd within 15 %
    assert np.all(np.abs(x.mean(axis=0) - mean) < 0.2 * sd)
    np.testing.assert_allclose(x.std(axis=0), sd, rtol=0.15)
    assert max(res.stage_correlation) <= 0.1


def test_moves_that_cannot_forget_the_start_are_not_converged():
    dim = 6
    res = tempered_smc(_target(np.ones(dim), 4.0 * np.eye(dim)), _narrow_start(dim), np.random.default_rng(0), 300,
                       max_moves=1, min_moves=1, names=[f"p{i}" for i in range(dim)])
    assert not res.converged
    assert "did not forget their start within 1 moves" in res.reason and ", of p" in res.reason


def test_the_last_stage_gets_its_own_move_budget():
    """``final_max_moves`` lets the moves at β = 1 go on where the stages before stop: the
    same run that cannot forget its start in one move at the last stage does in more."""
    dim = 6
    kwargs = dict(max_moves=3, min_moves=1, names=[f"p{i}" for i in range(dim)])
    target = _target(np.ones(dim), 4.0 * np.eye(dim))
    short = tempered_smc(target, _narrow_start(dim), np.random.default_rng(0), 300, **kwargs)
    long = tempered_smc(target, _narrow_start(dim), np.random.default_rng(0), 300, final_max_moves=200, **kwargs)
    assert long.stage_max_moves[-1] == 200 and set(long.stage_max_moves[:-1]) <= {3}
    assert short.stage_max_moves[-1] == 3 and short.stage_correlation[-1] > 0.1
    assert long.stage_moves[-1] > 3 and long.stage_correlation[-1] <= 0.1
    with pytest.raises(ValueError, match="final_max_moves must be at least max_moves"):
        tempered_smc(target, _narrow_start(dim), np.random.default_rng(0), 300, max_moves=10, final_max_moves=5)


def test_a_posterior_zero_at_every_particle_stops_with_a_reason():
    res = tempered_smc(lambda x: np.full(len(x), -np.inf), _narrow_start(3), np.random.default_rng(0), 100)
    assert not res.converged and res.reason == "no particle has a finite posterior density"


@pytest.mark.parametrize("seed", [0, 1])
def test_hmc_moves_recover_a_posterior_the_approximation_misses(seed):
    """With the posterior's gradient the moves are HMC (the particles' covariance as inverse
    mass): the same correlated Gaussian as the random walk's test, recovered as well."""
    dim = 6
    rng = np.random.default_rng(100 + seed)
    a = rng.normal(size=(dim, dim))
    cov = a @ a.T / dim + np.eye(dim)
    mean = rng.normal(scale=0.5, size=dim)
    both = _target_and_grad(mean, cov)
    res = tempered_smc(lambda x: both(x)[0], _narrow_start(dim), np.random.default_rng(seed), 1000,
                       log_p_and_grad=both)
    x = res.chain[:, 0, :]
    assert res.converged and res.reason == "" and res.betas[-1] == 1.0
    assert len(res.stage_step_size) == len(res.betas) and "HMC" in res.moves
    sd = np.sqrt(np.diag(cov))
    assert np.all(np.abs(x.mean(axis=0) - mean) < 0.2 * sd)
    np.testing.assert_allclose(x.std(axis=0), sd, rtol=0.15)


def test_hmc_moves_leave_a_curved_ridge_invariant():
    """The HMC kernel (the particles' covariance as inverse mass, a step tuned towards 0.65 and
    drawn shorter log-uniformly, trajectories of a fixed length) leaves the posterior invariant: 200 moves of exact draws of a curved ridge keep its
    spread, its skewed mean and the ridge's coordinates within their sampling error."""
    from torsionfit.sample._smc import _Hamiltonian

    both = _banana()
    rng = np.random.default_rng(0)
    n = 2000
    x1 = 3.0 * rng.standard_normal(n)
    x = np.stack([x1, 0.5 * (x1**2 - 9.0) + rng.standard_normal(n), *rng.standard_normal((2, n))], axis=1)
    start = x.copy()
    q = _narrow_start(4, sd=1.0)
    kernel = _Hamiltonian(both, q, 4, leapfrog_steps=None)
    lp, gp = both(x)
    state = [x, lp, q.log_density(x), gp]
    kernel.start_stage(x, 1.0)
    rates = [kernel.move(m, state, rng) for m in range(1, 201)]
    assert 0.3 < np.mean(rates[100:]) < 0.9
    moved = state[0]
    # most particles moved; a few far out on the ridge, where its curvature makes the tuned step
    # too long, stay put (3 % here): the tails are the ridge's slowest part
    assert np.mean(np.any(moved != start, axis=1)) > 0.9
    # sampling error of 2000 draws: sd(x₂) ≈ 6.4 ± 0.27 (the spread of 20 seeds' runs, whose mean
    # is 6.42), mean(x₂) 0 ± 0.15; within three of them
    assert abs(moved[:, 0].std() - 3.0) < 0.2 and abs(moved[:, 1].std() - np.sqrt(1 + 2 * 4.5**2)) < 0.8
    assert abs(moved[:, 1].mean()) < 0.45 and np.all(np.abs(moved[:, 2:].std(axis=0) - 1.0) < 0.1)


def _funnel(dim=5, sd_v=1.5):
    """Neal's funnel in ``dim`` dimensions: v ~ N(0, sd_v²), x_i | v ~ N(0, e^v) — one coordinate
    setting the others' spread, as a component's size sets how well its shape is known."""

    def both(x):
        x = np.atleast_2d(x)
        v, r = x[:, 0], x[:, 1:]
        with np.errstate(over="ignore", invalid="ignore"):
            lp = -0.5 * (v / sd_v) ** 2 - 0.5 * np.sum(r**2, axis=1) * np.exp(-v) - 0.5 * (dim - 1) * v
            g = np.empty_like(x)
            g[:, 0] = -v / sd_v**2 + 0.5 * np.sum(r**2, axis=1) * np.exp(-v) - 0.5 * (dim - 1)
            g[:, 1:] = -r * np.exp(-v)[:, None]
        bad = ~np.isfinite(lp) | ~np.all(np.isfinite(g), axis=1)
        lp[bad], g[bad] = -np.inf, 0.0
        return lp, g

    return both


def _funnel_run(seed):
    dim = 5
    both = _funnel(dim)
    start = SplitNormal(mean=np.r_[1.0, np.zeros(dim - 1)], axes=np.eye(dim), sd=np.r_[0.3, np.ones(dim - 1)],
                        scales=np.ones((dim, 2)))
    return tempered_smc(lambda x: both(x)[0], start, np.random.default_rng(seed), 1000, log_p_and_grad=both)


@pytest.mark.parametrize("seed", [0, 1])
def test_hmc_moves_reach_the_neck_of_a_funnel(seed):
    """Where one coordinate sets the others' spread (v: its 5 % quantile −2.47, sd 1.5) the step
    tuned over the population is too long for the particles in the neck: the moves' steps drawn
    shorter (log-uniformly, trajectories of a fixed length) reach it."""
    res = _funnel_run(seed)
    v = res.chain[:, 0, 0]
    assert res.converged, res.reason
    assert abs(v.std() / 1.5 - 1.0) < 0.1 and abs(np.percentile(v, 5) + 2.47) < 0.25
    assert all(1 <= s <= 64 for s in res.stage_leapfrog_steps) and "trajectories" in res.moves


def test_with_one_tuned_step_the_moves_miss_the_funnels_neck(monkeypatch):
    """The control: every move at the population's tuned step 'converges' by the rule and
    leaves the neck short (sd(v) 1.27–1.35 of 1.5, its 5 % quantile −1.6 to −1.9 of −2.47)."""
    import torsionfit.sample._smc as smc

    monkeypatch.setattr(smc, "HMC_STEP_SPREAD", 1.0)
    res = _funnel_run(0)
    v = res.chain[:, 0, 0]
    assert res.converged and v.std() < 1.4 and np.percentile(v, 5) > -2.2


@pytest.mark.parametrize("n, dim", [(500, 31), (200, 10)])
def test_the_correlation_floor_is_that_of_positions_independent_of_the_start(n, dim):
    """The decorrelation check's noise: the largest |correlation| over ``dim`` coordinates of
    positions independent of the start, at one check in two (and in ten), as simulated."""
    from torsionfit.sample._smc import correlation_floor, particles_resolving

    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((2, 400, n, dim))
    largest = np.array([np.abs(np.corrcoef(x, y, rowvar=False)[:dim, dim:].diagonal()).max() for x, y in zip(a, b)])
    assert np.median(largest) == pytest.approx(correlation_floor(n, dim), rel=0.05)
    assert abs(np.mean(largest > correlation_floor(n, dim, 0.9)) - 0.1) < 0.04
    assert correlation_floor(particles_resolving(0.1, dim), dim, 0.9) <= 0.1 < correlation_floor(
        particles_resolving(0.1, dim) - 20, dim, 0.9)


def test_a_stall_within_the_checks_noise_says_the_particles_are_too_few():
    """60 particles in 12 coordinates: particles that forgot their start show a largest
    correlation of about 0.25 (a check passes a 0.1 rule about once in a thousand), so the rule
    is not met, and the reason says why."""
    dim = 12
    both = _target_and_grad(np.zeros(dim), np.eye(dim))
    lines = []
    res = tempered_smc(lambda x: both(x)[0], _narrow_start(dim, sd=0.8), np.random.default_rng(0), 60,
                       log_p_and_grad=both, max_moves=30, progress=lines.append)
    assert not res.converged and "60 particles cannot resolve it" in res.reason and "particles resolve 0.1" in res.reason
    assert res.correlation_floor == pytest.approx(0.25, abs=0.01) and "cannot resolve a correlation of 0.1" in lines[0]


def test_the_split_normals_gradient_is_its_log_densitys():
    q = SplitNormal(mean=np.array([0.5, -1.0]), axes=np.array([[0.6, -0.8], [0.8, 0.6]]), sd=np.array([1.0, 2.0]),
                    scales=np.array([[0.5, 1.5], [2.0, 0.7]]))
    x = np.random.default_rng(0).normal(size=(20, 2)) * 2.0
    eps = 1e-6
    numeric = np.stack([(q.log_density(x + eps * e) - q.log_density(x - eps * e)) / (2 * eps) for e in np.eye(2)], axis=1)
    np.testing.assert_allclose(q.grad_log_density(x), numeric, rtol=1e-5, atol=1e-7)


@pytest.mark.xfail(strict=True, reason="known limit: on a strongly curved ridge the decorrelation rule passes while "
                                       "the particles leave the ridge's far ends short (sd(x2) 4.7–6.1 of 6.4 over "
                                       "seeds 0–5; 3.2–3.5 when every move took the tuned step)")
def test_smc_reaches_the_far_ends_of_a_strongly_curved_ridge():
    """The decorrelation rule says the particles forgot where resampling put them, not that
    they reached every part of the posterior: from a narrow start on the curved ridge, HMC
    moves 'converge' by it; the ridge's spread is what is asked of them here."""
    both = _banana()
    res = tempered_smc(lambda x: both(x)[0], _narrow_start(4, sd=1.0), np.random.default_rng(0), 1000,
                       log_p_and_grad=both)
    assert res.converged, res.reason  # the rule is met …
    x = res.chain[:, 0, :]
    assert abs(x[:, 1].std() / np.sqrt(1 + 2 * 4.5**2) - 1.0) < 0.2  # … the spread is not


def _two_modes_target(dim=4, separation=8.0, left_share=0.3):
    """(log density, gradient) of a mixture of two unit Gaussians ``separation`` apart along x₁,
    the left one holding ``left_share`` of the mass."""
    centres = np.zeros((2, dim))
    centres[:, 0] = -separation / 2, separation / 2
    log_w = np.log([left_share, 1.0 - left_share])

    def both(x):
        x = np.atleast_2d(x)
        parts = np.stack([log_w[i] - 0.5 * np.sum((x - centres[i]) ** 2, axis=1) for i in range(2)])
        lp = np.logaddexp(parts[0], parts[1])
        r = np.exp(parts - lp)
        return lp, -(r[0][:, None] * (x - centres[0]) + r[1][:, None] * (x - centres[1]))

    return both


@pytest.mark.parametrize("seed", [0, 1])
def test_two_modes_the_moves_cannot_cross_get_their_shares_from_the_weights_and_converge(seed):
    """HMC does not cross between modes 8 sd apart: the separating coordinate remembers which
    side a particle started on (correlation ~0.6 after 100 moves, not converged when it was read
    over all particles). Read within the modes the particles sit in, the moves decorrelate them;
    the modes' shares come from the tempering's weights, and are the target's."""
    both = _two_modes_target()
    start = SplitNormal(mean=np.zeros(4), axes=np.eye(4), sd=np.array([4.0, 1.5, 1.5, 1.5]), scales=np.ones((4, 2)))
    res = tempered_smc(lambda x: both(x)[0], start, np.random.default_rng(seed), 1000, log_p_and_grad=both)
    x = res.chain[:, 0, :]
    assert res.converged and res.reason == ""
    assert max(res.stage_modes) == 2 and sorted(res.mode_shares) == pytest.approx([0.3, 0.7], abs=0.05)
    assert np.mean(x[:, 0] < 0) == pytest.approx(0.3, abs=0.05)
    left, right = x[x[:, 0] < 0], x[x[:, 0] > 0]
    assert left[:, 0].mean() == pytest.approx(-4.0, abs=0.2) and right[:, 0].std() == pytest.approx(1.0, rel=0.15)
