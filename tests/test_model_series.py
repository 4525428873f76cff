"""Compliance ahead of the friction (``series_compliance``): a share φ of the compliance sees the
applied torque. φ = 0 is the base model; right after a reversal, while friction holds, the
twist moves with slope φ·C′(τ); the gap still sees the mesh torque; the parts sum up."""

import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.model import model_with_effects
from torsionfit.model._inputs import hysteresis_input, te_input

PARAMS = {"stiffness": 1000.0, "friction_torque": 5.0, "dahl_torque": 0.2, "gap": 0.02, "gap_torque": 1.0,
          "angle_offset": jnp.zeros(1)}


def _loop():
    t = np.linspace(0.0, 40.0, 8001)
    return t, 50.0 * np.sin(2 * np.pi * t / 20.0)


def test_switch_and_its_checks():
    model = model_with_effects(["hysteresis", "transmission_error"], {"series_compliance": True}, 100.0)
    names = [p.name for p in model.parameters()]
    assert "series_share" in names
    assert next(p for p in model.parameters() if p.name == "series_share").vanishes_at_zero
    with pytest.raises(InputError, match=r"\[effects\].series_compliance: expected true or false"):
        model_with_effects(["hysteresis"], {"series_compliance": "yes"}, 100.0)


def test_zero_share_is_the_base_model_and_a_share_moves_the_twist_while_friction_holds():
    t, tau = _loop()
    data = hysteresis_input(t, tau)
    base = model_with_effects(["hysteresis"], {}, 100.0)
    series = model_with_effects(["hysteresis"], {"series_compliance": True}, 100.0)
    y0 = np.asarray(base.predict(PARAMS, [data])[0])
    np.testing.assert_allclose(np.asarray(series.predict({**PARAMS, "series_share": 0.0}, [data])[0]), y0, atol=1e-15)
    # friction that holds after a reversal: a Dahl torque of twice the level keeps the mesh
    # torque still at first (dτ_m/dτ = 1 − 2T_f/τ_d·e^(−Δτ/τ_d))
    holding = {**PARAMS, "dahl_torque": 2.0 * PARAMS["friction_torque"]}
    t = np.linspace(0.0, 40.0, 8001)
    tau = 50.0 * (1.0 - 2.0 * np.abs(((t / 20.0) % 1.0) - 0.5) * 2.0)  # triangle ±50 N·m, 20 s period
    data = hysteresis_input(t, tau)
    y0 = np.asarray(base.predict(holding, [data])[0])
    y = np.asarray(series.predict({**holding, "series_share": 0.4}, [data])[0])
    falling = (t > 30.0) & (tau < 49.8) & (tau > 49.0)  # 0.2–1 N·m below the peak at 30 s
    base_slope = np.polyfit(tau[falling], y0[falling], 1)[0]
    slope = np.polyfit(tau[falling], y[falling], 1)[0]
    stiffness = PARAMS["stiffness"]
    assert abs(base_slope) < 0.1 / stiffness  # the base model: nearly flat while friction holds
    assert 0.4 / stiffness < slope < 0.5 / stiffness  # φ·C′ = 0.4/K, plus (1 − φ) of the base's slope
    # sliding, far from the peak, both have the loading slope 1/K
    sliding = (t > 34.0) & (t < 39.0) & (tau < -15.0)
    np.testing.assert_allclose(np.polyfit(tau[sliding], y[sliding], 1)[0], 1 / stiffness, rtol=0.02)


def test_components_sum_and_the_share_is_booked_to_friction():
    t, tau = _loop()
    data = hysteresis_input(t, tau)
    series = model_with_effects(["hysteresis"], {"series_compliance": True}, 100.0)
    params = {**PARAMS, "series_share": 0.3}
    comps = series.components(params, [data])[0]
    np.testing.assert_allclose(np.asarray(comps["total"]), np.asarray(series.predict(params, [data])[0]), atol=1e-12)
    # the elastic part is C(τ) as in the base model; what friction does to the spring shrinks by
    # 1 − φ: the friction part moves by φ·(C(τ) − C(τ_m)) = φ·(τ − τ_m)/K, the same mesh torque
    base = model_with_effects(["hysteresis"], {}, 100.0).components(PARAMS, [data])[0]
    np.testing.assert_allclose(np.asarray(comps["elastic"]), np.asarray(base["elastic"]), atol=1e-15)
    np.testing.assert_allclose(np.asarray(comps["mesh_torque"]), np.asarray(base["mesh_torque"]), atol=1e-12)
    moved = 0.3 * (tau - np.asarray(base["mesh_torque"])) / PARAMS["stiffness"]
    np.testing.assert_allclose(np.asarray(comps["friction"]) - np.asarray(base["friction"]), moved, atol=1e-12)


def test_te_run_sees_the_share_at_the_load():
    series = model_with_effects(["transmission_error"], {"series_compliance": True}, 100.0)
    base = model_with_effects(["transmission_error"], {}, 100.0)
    phi = np.linspace(0.0, 2 * np.pi, 50)
    data = te_input(phi, 40.0, 1.0, 1)
    params = {**PARAMS, "te_offset": jnp.zeros(1)}
    p_series = {**params, "series_share": 0.25}
    y = np.asarray(series.te_components(p_series, data, 0)["total"])
    y0 = np.asarray(base.te_components(params, data, 0)["total"])
    # linear compliance: the friction's share of the twist shrinks by 1 − φ: 5 N·m of friction
    np.testing.assert_allclose(y0 - y, 0.25 * 5.0 / PARAMS["stiffness"], rtol=1e-9)


def test_a_fit_with_the_share_recovers_it_on_a_bench(tmp_path):
    """SYNTHETIC friction bench (tests/benches/friction/base.toml: 380 N·m loops with play ramps,
    6 N·m Dahl friction, 1′ gap) with half the compliance ahead of the friction: a fit with
    ``series_compliance`` finds the share, and its 95 % interval excludes the base model (0)."""
    from pathlib import Path

    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, fit_campaign

    text = (Path(__file__).parent / "benches" / "friction" / "base.toml").read_text()
    text = text.replace("[truth]", "[effects]\nseries_compliance = true\n[truth]\nseries_share = 0.5", 1)
    bench = tmp_path / "bench.toml"
    bench.write_text(text)
    sim = simulate(load_bench(bench), seed=3)
    fit = fit_campaign(sim.campaign, FitOptions(sampler="laplace", effects={"series_compliance": True}, n_starts=2), seed=0)
    share = np.asarray(fit.metric_values["series_share"])
    lo, hi = np.quantile(share, [0.025, 0.975])
    assert lo < 0.5 < hi and lo > 0.1
