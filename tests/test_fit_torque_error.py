"""The errors-in-variables variance read from the data (fit/_torque_error.py)."""

from pathlib import Path

import jax.numpy as jnp
import numpy as np

from torsionfit.bench import load_bench, simulate
from torsionfit.fit import NoiseOptions, build_problem
from torsionfit.fit._torque_error import angle_variance_from_torque_error
from torsionfit.model import model_with_effects

BENCHES = Path(__file__).parent / "benches"


def _triangle(n_ramp: int = 200, peak: float = 10.0):
    up = np.linspace(-peak, peak, n_ramp)
    return np.concatenate([up, up[::-1][1:], up[1:]])


def test_on_a_straight_branch_it_is_the_slope_times_the_torque_sd():
    """θ = c·τ: the secant over τ̂ ± s is c·s wherever ±s stays inside the ramp."""
    tau = _triangle()
    compliance = 1e-4  # rad/(N·m)
    sd = np.full(tau.size, 0.05)
    var = angle_variance_from_torque_error(compliance * tau, tau, tau, sd**2)
    inner = np.abs(tau) < 9.0
    np.testing.assert_allclose(np.sqrt(var[inner]), compliance * 0.05, rtol=1e-6)


def test_a_jump_is_bounded_by_the_angle_the_data_move():
    """A gap crossed in one sample (a vertical step of the branch): a linearised slope would be
    unbounded there, the secant is at most half the step."""
    tau = _triangle()
    gap = 1e-2
    theta = 1e-4 * tau + 0.5 * gap * np.sign(tau)
    var = angle_variance_from_torque_error(theta, tau, tau, np.full(tau.size, 0.2**2))
    sd = np.sqrt(var)
    near = np.abs(tau) < 0.2
    assert sd.max() <= 0.5 * gap + 1e-4 * 0.2 + 1e-12
    assert sd[near].max() > 0.25 * gap  # the step is seen where ±s straddles it
    assert sd[np.abs(tau) > 1.0].max() < 1e-4  # far from it, the elastic slope's share only


def test_no_torque_error_no_variance_and_short_runs_are_zero():
    tau = _triangle()
    assert not np.any(angle_variance_from_torque_error(1e-4 * tau, tau, tau, np.zeros(tau.size)))
    assert not np.any(angle_variance_from_torque_error(tau[:5], tau[:5], tau[:5], np.ones(5)))


def test_no_parameter_can_widen_it():
    """The variance is a property of the data: two very different physics give the same scales
    (a model-linearised variance let the fit widen its own error bars by steepening the loop)."""
    campaign = simulate(load_bench(BENCHES / "stat_rv_white.toml"), seed=1).campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    problem = build_problem(campaign, model, NoiseOptions())
    noise = jnp.concatenate([jnp.full(problem.n_runs, -40.0), jnp.zeros(problem.n_ar1)])
    u0 = jnp.concatenate([problem.prior_mean, noise])
    u1 = jnp.concatenate([problem.prior_mean + 2.0 * problem.prior_sd, noise])
    for a, b in zip(problem.sample_scales(u0), problem.sample_scales(u1)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
    assert max(float(jnp.max(v)) for v in problem.eiv_var) > 0.0


def _play_then_stiffness_ramps(seed: int = 0):
    """A bench file's torque as the measured ones run it: five ±4 N·m play cycles, then ±40 N·m
    ramps (the play ramps retreat by 10 % of the range), with sensor noise."""
    def tri(peak, n):
        up = np.linspace(-peak, peak, n)
        return np.concatenate([up, up[::-1][1:]])
    tau = np.concatenate([np.linspace(0, -4, 30)] + [tri(4.0, 60)[1:] for _ in range(5)]
                         + [np.linspace(-4, 40, 300)[1:]] + [tri(40.0, 550)[::-1][1:] for _ in range(2)])
    return tau + np.random.default_rng(seed).normal(0.0, 0.05, tau.size)


def test_play_ramps_of_a_large_file_are_ramps_of_their_own():
    """The fit's ramps split at the ±4 N·m play ramps' reversals: the denoiser keeps their
    corners (with the metrics' 10 % threshold it smoothed across them and rounded each peak by
    ~0.3 N·m on the measured files) and each play ramp has a latent torque line of its own."""
    from torsionfit.fit._denoise import denoise_torque

    tau = _play_then_stiffness_ramps()
    smooth, _, lines = denoise_torque(tau, return_lines=True)
    play = slice(30, 30 + 5 * 118)
    peaks = np.sort(np.abs(smooth[play]))[-10:]
    assert np.all(peaks > 3.85), peaks  # every play-ramp corner kept (true peak 4.0)
    assert np.unique(lines.ramp[play]).size >= 10, np.unique(lines.ramp[play])



def test_on_straight_ramps_the_ramp_lines_are_the_whole_denoised_error():
    """A triangle program with white torque noise: each ramp's smoother is (nearly always: the
    window is chosen by cross-validation) its least-squares line, so the denoised torque's error
    is one line per ramp. Over 400 noise draws its level and tilt scatter as the lines' prior sd
    say, and nothing is left per sample."""
    from torsionfit.fit._denoise import denoise_torque
    from torsionfit.fit._torque_error import ramp_line_basis

    true = _triangle(120, 10.0)
    noise_sd = 0.3
    rng = np.random.default_rng(4)
    coefs, left, sds, whole = [], [], [], 0
    for _ in range(400):
        tau = true + rng.normal(0.0, noise_sd, true.size)
        smooth, var, lines = denoise_torque(tau, return_lines=True)
        basis, sd, rest = ramp_line_basis(lines, var)
        error = smooth - true
        c, *_ = np.linalg.lstsq(basis, error, rcond=None)
        coefs.append(c)
        left.append(np.std(error - basis @ c) / np.std(error))
        sds.append(sd)
        whole += bool(np.all(rest < 1e-9 * var.max()))
    assert whole >= 0.9 * len(coefs), whole
    assert basis.shape[1] == 6  # three ramps, a level and a tilt each
    ratio = np.std(coefs, axis=0) / np.mean(sds, axis=0)
    assert np.all((ratio > 0.85) & (ratio < 1.15)), ratio
    assert np.mean(np.array(left) < 0.05) >= 0.9, np.quantile(left, [0.5, 0.9])


def test_a_curved_ramps_lines_and_rest_add_up_to_its_variance():
    """A curved ramp (a narrower smoothing window): the lines take the ramp-long part of each
    sample's variance, the rest stays per sample, and the two add up to the smoother's."""
    from torsionfit.fit._denoise import denoise_torque
    from torsionfit.fit._torque_error import ramp_line_basis

    x = np.linspace(0.0, 1.0, 400)
    tau = np.concatenate([10.0 * x**3, 10.0 * x[::-1][1:] ** 3])
    tau = tau + np.random.default_rng(1).normal(0.0, 0.05, tau.size)
    _, var, lines = denoise_torque(tau, return_lines=True)
    basis, sd, rest = ramp_line_basis(lines, var)
    line_var = (basis**2) @ (sd**2)
    assert rest.max() > 0.0
    np.testing.assert_allclose(np.maximum(line_var, var), line_var + rest, rtol=1e-9, atol=1e-15)
