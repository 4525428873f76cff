"""A gap held by its own friction (``gap_hold``, :class:`HeldGapBacklash`): the flanks cross the
gap once the mesh torque exceeds ±T_h and stay on their side in between — a relay. Its
crossings sit at ±T_h whatever the peak, cycles within ±T_h never cross, T_h → 0 is the smooth
gap, and the fit sees gradients in T_h and in the state before the first sample."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.model import HeldGapBacklash, SmoothBacklash, model_with_effects
from torsionfit.model._inputs import hysteresis_input

PARAMS = {"gap": 1e-3, "gap_torque": 0.3, "gap_hold_torque": 8.0}


def _ramps(*peaks, n=400):
    """Torque (N·m) from 0 through the given turning points, ``n`` samples per ramp."""
    points = (0.0,) + peaks
    return np.concatenate([np.linspace(a, b, n, endpoint=False) for a, b in zip(points[:-1], points[1:])] + [[points[-1]]])


def _crossings(torque, state):
    """Torques where the gap state passes through zero."""
    side = state > 0
    i = np.flatnonzero(side[1:] != side[:-1])
    return np.where(side[i + 1], 1.0, -1.0) * np.abs(torque[i + 1])


def test_switch_and_its_checks():
    model = model_with_effects(["hysteresis"], {"gap_hold": True}, 20.0, free_friction_start=True)
    params = {p.name: p for p in model.parameters()}
    assert {"gap", "gap_torque", "gap_hold_torque", "friction_start", "gap_start"} <= set(params)
    assert params["gap_hold_torque"].vanishes_at_zero and params["gap_start"].constraint == "signed_unit"
    # a simulated run starts at rest (g0 = 0): no start parameter without free starts
    assert "gap_start" not in {p.name for p in model_with_effects(["hysteresis"], {"gap_hold": True}, 20.0).parameters()}
    with pytest.raises(InputError, match=r"\[effects\].gap_hold: expected true, false or \{centred = false\}"):
        model_with_effects(["hysteresis"], {"gap_hold": "yes"}, 20.0)
    with pytest.raises(InputError, match=r"\[effects\].gap_hold: needs a hysteresis run and cannot be combined"):
        model_with_effects(["hysteresis"], {"gap_hold": True, "gap_preload": True}, 20.0)
    with pytest.raises(InputError, match=r"\[effects\].gap_hold: needs a hysteresis run"):
        model_with_effects(["transmission_error"], {"gap_hold": True}, 20.0, fitted=True)


def test_crossings_sit_at_the_hold_torque_whatever_the_peak():
    torque = _ramps(40.0, -40.0, 25.0, -15.0, 30.0)
    state = np.asarray(HeldGapBacklash().state(PARAMS, jnp.asarray(torque), initial_state=-1.0))
    crossed = _crossings(torque, state)
    # one crossing per ramp, at ±T_h (to the ramps' 0.2 N·m sample spacing), peaks 15–40 N·m
    assert list(np.sign(crossed)) == [1, -1, 1, -1, 1]  # the side the flanks cross to
    np.testing.assert_allclose(np.abs(crossed), 8.0, atol=0.21)
    assert np.all(np.abs(state) <= 1.0)


def test_a_band_of_its_own_centre_crosses_at_the_centre_plus_and_minus_the_hold():
    model = model_with_effects(["hysteresis"], {"gap_hold": {"centred": False}}, 20.0)
    names = {p.name: p for p in model.parameters()}
    assert names["gap_centre_torque"].constraint == "real"
    assert "gap_centre_torque" not in {p.name for p in model_with_effects(["hysteresis"], {"gap_hold": True}, 20.0).parameters()}
    tau = _ramps(20.0, -20.0, 20.0)
    held = HeldGapBacklash(centred=False)
    state = np.asarray(held.state({**PARAMS, "gap_centre_torque": 1.5}, jnp.asarray(tau)))
    # up at c + T_h, down at c − T_h (the signed torque: negative going down)
    np.testing.assert_allclose(sorted(_crossings(tau, state)), [-6.5, 9.5, 9.5], atol=0.1)
    # c = 0 is the centred band
    np.testing.assert_allclose(held.state({**PARAMS, "gap_centre_torque": 0.0}, jnp.asarray(tau)),
                               HeldGapBacklash().state(PARAMS, jnp.asarray(tau)))
    with pytest.raises(InputError, match=r"\[effects\].gap_hold: expected true, false or \{centred = false\}"):
        model_with_effects(["hysteresis"], {"gap_hold": {"centre": True}}, 20.0)


def test_cycles_within_the_hold_torque_never_cross():
    torque = _ramps(30.0, 5.0, -5.0, 5.0, -5.0, 5.0)  # loaded to +30 N·m, then ±5 N·m cycles
    state = np.asarray(HeldGapBacklash().state(PARAMS, jnp.asarray(torque)))
    after = state[400:]
    assert np.all(after > 0.999)  # closed on the + flank throughout the small cycles
    # the same cycles around a smooth gap cross it at every reversal
    smooth = np.tanh(torque[400:] / PARAMS["gap_torque"])
    assert np.sum(np.diff(np.sign(smooth)) != 0) >= 4


def test_no_hold_is_the_smooth_gap_and_the_state_is_clamped_to_the_band():
    torque = jnp.asarray(_ramps(10.0, -10.0, 3.0))
    params = {**PARAMS, "gap_hold_torque": 1e-9}
    np.testing.assert_allclose(np.asarray(HeldGapBacklash().run_twist(params, torque)),
                               np.asarray(SmoothBacklash()(params, torque)), atol=1e-8 * PARAMS["gap"])
    # away from a run's history (TE runs, the geometric component) it is the smooth gap
    np.testing.assert_array_equal(np.asarray(HeldGapBacklash()(PARAMS, torque)), np.asarray(SmoothBacklash()(PARAMS, torque)))
    # a start outside the band at the first torque is clamped into it: at +20 N·m the + flank
    state = HeldGapBacklash().state(PARAMS, jnp.asarray([20.0, 19.0]), initial_state=-1.0)
    assert float(state[0]) > 0.999


def test_gradients_in_the_hold_torque_and_the_start_state():
    torque = jnp.asarray(_ramps(4.0, -4.0, 20.0, -20.0))
    backlash = HeldGapBacklash()

    def loss(th, g0):
        return jnp.sum(backlash.run_twist({**PARAMS, "gap_hold_torque": th}, torque, initial_state=g0) ** 2)

    d_hold, d_start = jax.grad(loss, argnums=(0, 1))(8.0, 0.3)
    assert np.isfinite(float(d_hold)) and float(d_hold) != 0.0
    assert np.isfinite(float(d_start)) and float(d_start) != 0.0  # the ±4 N·m cycles keep the start


def test_the_campaign_model_carries_the_gap_state_and_books_the_hold_as_friction():
    model = model_with_effects(["hysteresis"], {"gap_hold": True}, 20.0, free_friction_start=True)
    torque = _ramps(4.0, -4.0, 4.0, -4.0, 40.0, -40.0, 0.0)
    data = hysteresis_input(np.arange(torque.size) * 0.01, torque)
    params = {"stiffness": 600.0, "friction_torque": 1.0, "dahl_torque": 0.5, **PARAMS,
              "friction_start": jnp.zeros(1), "angle_offset": jnp.zeros(1)}
    out = {}
    for g0 in (-0.9, 0.9):
        parts = model.hysteresis_components({**params, "gap_start": jnp.array([g0])}, data, 0, 0)
        np.testing.assert_allclose(np.asarray(parts["total"]), np.asarray(model.predict({**params, "gap_start": jnp.array([g0])}, [data])[0]),
                                   atol=1e-12)
        np.testing.assert_allclose(np.asarray(parts["geometric"]), np.asarray(SmoothBacklash()(PARAMS, jnp.asarray(torque))), atol=1e-15)
        out[g0] = np.asarray(parts["total"])
    # the ±4 N·m play ramps keep the unknown start's side of the gap: the whole gap apart …
    np.testing.assert_allclose(out[0.9][:1600] - out[-0.9][:1600], 0.9 * PARAMS["gap"], rtol=1e-3)
    # … until the first large ramp crosses it; after that the history is the same
    np.testing.assert_allclose(out[0.9][2400:], out[-0.9][2400:], atol=1e-12)


def _friction_bench(tmp_path, hold_Nm=None):
    """SYNTHETIC friction bench (tests/benches/friction/base.toml: 380 and 190 N·m loops after
    ±30 N·m play ramps, 6 N·m Dahl friction) with a 4′ gap, held up to ``hold_Nm`` if given."""
    from pathlib import Path

    from torsionfit.bench import load_bench, simulate

    text = (Path(__file__).parent / "benches" / "friction" / "base.toml").read_text()
    text = text.replace("gap_arcmin = 1.0", "gap_arcmin = 4.0", 1)
    if hold_Nm is not None:
        text = text.replace("[truth]", f"[effects]\ngap_hold = true\n[truth]\ngap_hold_torque_Nm = {hold_Nm}", 1)
    bench = tmp_path / "bench.toml"
    bench.write_text(text)
    return simulate(load_bench(bench), seed=3)


@pytest.mark.slow
def test_a_fit_finds_the_held_gap_on_a_bench_and_no_hold_on_a_free_one(tmp_path):
    """A gap held up to 60 N·m: the ±30 N·m play ramps never cross it, the 190 and 380 N·m loops
    cross it at ±(60 N·m + friction). A fit with ``gap_hold`` finds the hold torque within 5 %;
    on the same bench with a free gap it finds the hold torque well below the friction level
    (the gap crossed where the friction puts it), not the held bench's."""
    from torsionfit.report import FitOptions, fit_campaign

    options = FitOptions(sampler="laplace", effects={"gap_hold": True}, n_starts=2)
    held = fit_campaign(_friction_bench(tmp_path, 60.0).campaign, options, seed=0)
    hold = np.asarray(held.metric_values["gap_hold_torque"])
    assert abs(np.median(hold) - 60.0) < 0.05 * 60.0, np.quantile(hold, [0.025, 0.975])
    free = fit_campaign(_friction_bench(tmp_path).campaign, options, seed=0)
    hold = np.asarray(free.metric_values["gap_hold_torque"])
    assert np.quantile(hold, 0.975) < 3.0, np.quantile(hold, [0.025, 0.975])


def test_the_hop_to_the_hold_moves_only_what_it_names_and_skips_a_model_without_a_hold(tmp_path):
    """``moved_start`` moves the named physics values and nothing else; ``hop_to_the_hold``
    returns the fit it was given, without a fit, when the model holds no gap."""
    import torsionfit
    from torsionfit.report import FitOptions, prepare_fit
    from torsionfit.report._pipeline import hop_to_the_hold, moved_start

    bench = _friction_bench(tmp_path, 60.0).campaign
    with torsionfit.float64():
        _, _, problem = prepare_fit(bench, FitOptions(effects={"gap_hold": True}))
        u = np.concatenate([np.asarray(problem.prior_mean, float), np.zeros(problem.dim - problem.n_nonlinear)])
        start = moved_start(problem, u, {"friction_torque": 2.5, "gap_hold_torque": 30.0})
        values = problem.physics_values(start[:problem.n_nonlinear])
        assert float(values["friction_torque"]) == pytest.approx(2.5) and float(values["gap_hold_torque"]) == pytest.approx(30.0)
        assert np.count_nonzero(start != u) == 2
        with pytest.raises(ValueError, match="no parameter gap_hold_torque_Nm"):
            moved_start(problem, u, {"gap_hold_torque_Nm": 30.0})
        campaign, _, free = prepare_fit(bench, FitOptions())
        sentinel = object()  # no hold: returned as it is, nothing read from it
        assert hop_to_the_hold(campaign, free, sentinel, FitOptions(), seed=0) is sentinel

