"""A gap crossed in held steps (``gap_relays``, :class:`RelayGapBacklash`, a Preisach gap):
relays whose up- and down-switches lie on a grid of mesh torques spread over a fitted span about
a fitted centre, each crossing its share of the gap once the torque passes its up-switch and back
past its down-switch. A relay of the grid is
the held gap centred on a torque of its own, a staircase's steps sit at the switches, a cycle
that stays between a relay's switches leaves it alone, and the fit sees gradients in the shares,
the switching width and the state before the first sample."""

from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.model import HeldGapBacklash, RelayGapBacklash, model_with_effects

GAP = 0.02  # rad


def _ramps(*peaks, n=400):
    """Torque (N·m) from 0 through the given turning points, ``n`` samples per ramp."""
    points = (0.0,) + peaks
    return np.concatenate([np.linspace(a, b, n, endpoint=False) for a, b in zip(points[:-1], points[1:])] + [[points[-1]]])


def _params(relays: RelayGapBacklash, shares: dict[int, float], width_Nm=0.02, centre_Nm=0.0, span_Nm=4.0):
    """Parameters putting ``shares`` (relay index → share) of the gap on those relays (the rest
    e^−40 of the largest), the switches spread over ``centre_Nm ± span_Nm``."""
    logits = np.full(relays.n_relays, -40.0)
    for k, w in shares.items():
        logits[k] = np.log(w)
    return {"gap": GAP, "gap_torque": width_Nm, "gap_centre_torque": centre_Nm, "gap_relay_span": span_Nm,
            "gap_relay_logits": jnp.asarray(logits[1:] - logits[0])}


def test_switch_and_its_checks():
    model = model_with_effects(["hysteresis"], {"gap_relays": {"thresholds": 5}}, 20.0, free_friction_start=True)
    params = {p.name: p for p in model.parameters()}
    assert isinstance(model.backlash, RelayGapBacklash) and model.backlash.n_relays == 15
    assert params["gap_relay_logits"].size == 14 and "gap_start" in params
    assert params["gap_centre_torque"].constraint == "real" and params["gap_relay_span"].constraint == "positive"
    assert model_with_effects(["hysteresis"], {"gap_relays": True}, 20.0).backlash.n_relays == 28
    for bad in ("yes", {"thresholds": 1}, {"thresholds": 5.0}, {"span_Nm": 4.0}, {"max_span_Nm": 0.0},
                {"max_span_Nm": True}, {"max_span_Nm": float("inf")}, {"max_span_Nm": "10"}):
        with pytest.raises(InputError, match=r"\[effects\].gap_relays: expected true, false or \{thresholds = G, max_span_Nm = S\}"):
            model_with_effects(["hysteresis"], {"gap_relays": bad}, 20.0)
    with pytest.raises(InputError, match=r"\[effects\].gap_relays: needs a hysteresis run and cannot be combined"):
        model_with_effects(["hysteresis"], {"gap_relays": True, "gap_hold": True}, 20.0)
    with pytest.raises(InputError, match=r"\[effects\].gap_relays: needs a hysteresis run"):
        model_with_effects(["transmission_error"], {"gap_relays": True}, 20.0, fitted=True)


def test_a_bounded_span_is_a_share_of_its_bound_and_no_switch_goes_beyond_it():
    """With ``max_span_Nm`` the fit takes the span as a share of the bound (a unit-interval
    parameter): every switch lies within centre ± bound whatever the share's unconstrained value,
    and a start at a span beyond the bound is clipped inside it."""
    from torsionfit.fit._transform import forward

    model = model_with_effects(["hysteresis"], {"gap_relays": {"max_span_Nm": 10.0}}, 20.0)
    relays = model.backlash
    params = {p.name: p for p in model.parameters()}
    assert relays.max_span_Nm == 10.0 and "gap_relay_span" not in params
    assert params["gap_relay_span_share"].constraint == "unit_interval" and params["gap_relay_span_share"].unit == "1"
    for u in (-30.0, 0.0, 30.0):
        up, down = relays.switches_Nm({"gap_centre_torque": -2.0, "gap_relay_span_share": forward("unit_interval", u)})
        assert np.all(np.abs(np.asarray(up) + 2.0) <= 10.0) and np.all(np.abs(np.asarray(down) + 2.0) <= 10.0)
    assert float(relays.span_Nm({"gap_relay_span_share": 0.25})) == pytest.approx(2.5)
    assert relays.span_values(4.0) == {"gap_relay_span_share": pytest.approx(0.4)}
    assert relays.span_values(40.0)["gap_relay_span_share"] < 1.0
    assert RelayGapBacklash().span_values(40.0) == {"gap_relay_span": 40.0}  # unbounded: as given
    with pytest.raises(ValueError, match="max_span_Nm must be a finite torque > 0"):
        RelayGapBacklash(max_span_Nm=-1.0)


def test_the_grid_pairs_every_up_switch_with_each_down_switch_at_or_below_it():
    relays = RelayGapBacklash(n_thresholds=4)
    up, down = relays.switches_Nm({"gap_centre_torque": 0.5, "gap_relay_span": 3.0})
    assert len(up) == 10 and np.all(up >= down)
    assert sorted(set(np.round(up, 12).tolist())) == [-2.5, -0.5, 1.5, 3.5]
    assert relays.nearest_relay(0.4, -0.2) == list(zip(*relays.unit_switches())).index((1 / 3, -1 / 3))


def test_one_relay_is_the_held_gap_centred_on_a_torque_of_its_own():
    relays = RelayGapBacklash()
    torque = jnp.asarray(_ramps(4.0, -4.0, 2.0, -1.0, 25.0, -25.0))
    k = relays.nearest_relay(2 / 3, -2 / 3)
    params = _params(relays, {k: 1.0}, width_Nm=0.1, centre_Nm=0.7, span_Nm=3.0)  # held ±2 N·m about 0.7 N·m
    held = HeldGapBacklash(centred=False).run_twist(
        {"gap": GAP, "gap_torque": 0.1, "gap_hold_torque": 2.0, "gap_centre_torque": 0.7}, torque, initial_state=0.3)
    one = relays.run_twist(params, torque, initial_state=0.3)
    np.testing.assert_allclose(np.asarray(one), np.asarray(held), atol=1e-9 * GAP)


def test_the_staircase_steps_at_the_switches_and_a_cycle_inside_a_relays_band_leaves_it_alone():
    relays = RelayGapBacklash(n_thresholds=5)  # switches at −4, −2, 0, 2, 4 N·m
    a = relays.nearest_relay(0.5, -0.5)  # held ±2 N·m
    b = relays.nearest_relay(0.0, 0.0)  # crossed at zero both ways
    params = _params(relays, {a: 0.7, b: 0.3})
    torque = _ramps(4.0, -4.0, 1.0, -1.0, 4.0, n=800)
    twist = np.asarray(relays.run_twist(params, jnp.asarray(torque), initial_state=-1.0)) / (0.5 * GAP)
    steps = np.flatnonzero(np.abs(np.diff(twist)) > 0.05)
    jumps = [(round(float(torque[i]), 1), round(float(np.sign(twist[i + 1] - twist[i])))) for i in steps]
    # up through 0 (the zero relay) and +2 (the held one); down through 0 and −2; the ±1 N·m
    # cycle crosses only the zero relay and leaves the held one on the − side; then up again
    assert sorted(set(jumps)) == [(-2.0, -1), (0.0, -1), (0.0, 1), (2.0, 1)]
    i_small = slice(3 * 800 + 5, 4 * 800 - 5)  # the ramp from +1 to −1 N·m
    np.testing.assert_allclose(twist[i_small].min(), -1.0, atol=1e-6)  # the held relay stays down
    np.testing.assert_allclose(twist[i_small].max(), -0.4, atol=1e-6)  # the zero relay alone crossed
    assert twist[-1] == pytest.approx(1.0, abs=1e-6)


def test_gradients_in_the_shares_the_width_and_the_start_state():
    relays = RelayGapBacklash()
    torque = jnp.asarray(_ramps(4.0, -4.0, 20.0, -20.0))
    base = _params(relays, {0: 0.2, 9: 0.5, 20: 0.3}, width_Nm=0.3)

    def loss(logits, width, centre, span, g0):
        return jnp.sum(relays.run_twist({**base, "gap_relay_logits": logits, "gap_torque": width, "gap_centre_torque": centre,
                                         "gap_relay_span": span}, torque, initial_state=g0) ** 2)

    grads = jax.grad(loss, argnums=(0, 1, 2, 3, 4))(base["gap_relay_logits"], 0.3, 0.0, 4.0, 0.2)
    d_logits, d_start = grads[0], grads[-1]
    assert np.all(np.isfinite(np.asarray(d_logits))) and np.any(np.asarray(d_logits) != 0.0)
    for d in grads[1:4]:  # width, centre, span
        assert np.isfinite(float(d)) and float(d) != 0.0
    assert np.isfinite(float(d_start)) and float(d_start) != 0.0  # relays the play ramps never switch keep it


def test_the_fit_starts_from_the_held_gap_on_its_nearest_relay():
    """A relay gap's fit starts from the held gap centred on a torque of its own: the smaller
    model's effects swap the relays for it, and the start puts most of the gap on the relay
    nearest the held gap's switches."""
    from torsionfit.report._pipeline import _without_nested

    effects = {"distributed_friction": True, "gap_relays": True}
    assert _without_nested(effects) == {"distributed_friction": True, "gap_hold": {"centred": False}}

    import torsionfit
    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, prepare_fit
    from torsionfit.report._pipeline import gap_on_the_held_relay, moved_start
    base = Path(__file__).parent / "benches" / "friction" / "base.toml"
    campaign = simulate(load_bench(base), seed=3).campaign  # SYNTHETIC
    with torsionfit.float64():
        _, _, problem = prepare_fit(campaign, FitOptions(effects=effects))
        names = [r.name for r in campaign.runs]
        start = moved_start(problem, np.asarray(problem.prior_mean, float), {"gap_relay_span": 3.0})
        start = gap_on_the_held_relay(problem, names, start, 2.1)
        relays = problem.model.backlash
        values = problem.physics_values(start)
        shares = np.asarray(relays.shares(values))
    k = relays.nearest_relay(2 / 3, -2 / 3)  # ±2 of a ±3 N·m span: the nearest to ±2.1
    assert float(values["gap_relay_span"]) == pytest.approx(3.0)
    assert np.argmax(shares) == k and shares[k] == pytest.approx(0.95) and shares.sum() == pytest.approx(1.0)
