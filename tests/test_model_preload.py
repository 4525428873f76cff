"""A preloaded second load path (``preload_stiffening``, split-pinwheel designs): below the
lift-off torque T_s the compliance is (1 − s)·C, beyond it the base slope returns, the twist
continuous; s = 0 is the base curve; odd and increasing on a nonlinear base too."""

import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.model import LinearCompliance, PowerLawCompliance, PreloadedCompliance, model_with_effects

K = 1000.0  # N·m/rad


def test_switch_and_its_checks():
    model = model_with_effects(["hysteresis"], {"preload_stiffening": True, "asymmetry": True}, 100.0)
    names = [p.name for p in model.parameters()]
    assert {"preload_stiffening", "preload_lift_torque", "compliance_asymmetry"} <= set(names)
    assert next(p for p in model.parameters() if p.name == "preload_stiffening").vanishes_at_zero
    with pytest.raises(InputError, match=r"\[effects\].preload_stiffening: expected true or false"):
        model_with_effects(["hysteresis"], {"preload_stiffening": "yes"}, 100.0)


def test_stiffer_inside_the_lift_off_torque_and_the_base_slope_beyond():
    curve = PreloadedCompliance(LinearCompliance())
    params = {"stiffness": K, "preload_stiffening": 0.6, "preload_lift_torque": 5.0}
    tau = jnp.linspace(-20.0, 20.0, 4001)
    theta = np.asarray(curve(params, tau))
    slope = np.gradient(theta, np.asarray(tau))
    inside, beyond = np.abs(tau) < 4.9, np.abs(tau) > 5.1
    np.testing.assert_allclose(slope[inside], 0.4 / K, rtol=1e-9)  # (1 − s)/K: two paths in parallel
    np.testing.assert_allclose(slope[beyond], 1.0 / K, rtol=1e-9)  # one path lifted off
    np.testing.assert_allclose(theta, -theta[::-1], atol=1e-15)  # odd
    # continuous at the lift-off: 0.4·5/K there, then 1/K per N·m more
    np.testing.assert_allclose(float(curve(params, 10.0)), (0.4 * 5.0 + 5.0) / K, rtol=1e-12)
    zero = {**params, "preload_stiffening": 0.0}
    np.testing.assert_allclose(np.asarray(curve(zero, tau)), np.asarray(tau) / K, rtol=1e-12)


def test_increasing_on_a_power_law_and_the_fit_sees_gradients_in_both_parameters():
    import jax

    curve = PreloadedCompliance(PowerLawCompliance(reference_torque_Nm=10.0))
    params = {"elastic_rated_twist": (10.0 / 600.0) ** (1 / 1.6), "power_exponent": 1.6, "preload_stiffening": 0.8, "preload_lift_torque": 3.0}
    tau = jnp.linspace(-12.0, 12.0, 4801)
    theta = np.asarray(curve(params, tau))
    assert np.all(np.diff(theta) > 0)
    grad = jax.grad(lambda p: jnp.sum(curve(p, tau) ** 2))(params)
    assert all(np.isfinite(float(v)) for v in grad.values())
    assert float(grad["preload_stiffening"]) != 0.0 and float(grad["preload_lift_torque"]) != 0.0


def test_a_fit_finds_the_preloaded_path_on_a_bench(tmp_path):
    """SYNTHETIC friction bench (tests/benches/friction/base.toml: 380 N·m loops with ±30 N·m play
    ramps, 6 N·m Dahl friction, 1′ gap) with a second path taking 60 % of the compliance below
    50 N·m: a fit with ``preload_stiffening`` finds both within their 95 % intervals, and the
    interval of s excludes the base curve (0)."""
    from pathlib import Path

    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, fit_campaign

    text = (Path(__file__).parent / "benches" / "friction" / "base.toml").read_text()
    text = text.replace("[truth]", "[effects]\npreload_stiffening = true\n[truth]\npreload_stiffening = 0.6\n"
                        "preload_lift_torque_Nm = 50.0", 1)
    bench = tmp_path / "bench.toml"
    bench.write_text(text)
    sim = simulate(load_bench(bench), seed=3)
    fit = fit_campaign(sim.campaign, FitOptions(sampler="laplace", effects={"preload_stiffening": True}, n_starts=2), seed=0)
    share = np.asarray(fit.metric_values["preload_stiffening"])
    lift = np.asarray(fit.metric_values["preload_lift_torque"])
    lo, hi = np.quantile(share, [0.025, 0.975])
    assert lo < 0.6 < hi and lo > 0.2
    lo, hi = np.quantile(lift, [0.025, 0.975])
    assert lo < 50.0 < hi


def test_a_fit_finds_the_residual_play_of_a_preloaded_gap_on_a_bench(tmp_path):
    """SYNTHETIC friction bench (as above) whose 4′ gap is held closed below 60 N·m, a quarter of
    it crossed at zero torque (``gap_preload = {residual_play = true}``): the ±30 N·m play ramps
    see that quarter alone, the 190 and 380 N·m loops all of it. A fit with the effect finds
    the residual share and the preload torque within 5 %, and the interval of the share
    excludes the plain preloaded gap (0). Recovery, not coverage: with 1″ noise on the 1″
    encoder these intervals are ±0.5 % wide and the truth sat at their edge (seeds 3 and 4:
    share 0.2502–0.2524 and 0.2481–0.2500)."""
    from pathlib import Path

    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, fit_campaign

    text = (Path(__file__).parent / "benches" / "friction" / "base.toml").read_text()
    text = text.replace("gap_arcmin = 1.0", "gap_arcmin = 4.0", 1)
    text = text.replace("[truth]", "[effects]\ngap_preload = {residual_play = true}\n[truth]\ngap_preload_torque_Nm = 60.0\n"
                        "gap_residual_share = 0.25\ngap_residual_torque_Nm = 1.0", 1)
    bench = tmp_path / "bench.toml"
    bench.write_text(text)
    sim = simulate(load_bench(bench), seed=3)
    effects = {"gap_preload": {"residual_play": True}}
    fit = fit_campaign(sim.campaign, FitOptions(sampler="laplace", effects=effects, n_starts=2), seed=0)
    share = np.asarray(fit.metric_values["gap_residual_share"])
    preload = np.asarray(fit.metric_values["gap_preload_torque"])
    assert abs(np.median(share) - 0.25) < 0.05 * 0.25 and np.quantile(share, 0.025) > 0.1, np.quantile(share, [0.025, 0.975])
    assert abs(np.median(preload) - 60.0) < 0.05 * 60.0, np.quantile(preload, [0.025, 0.975])
