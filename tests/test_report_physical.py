"""report/_physical.py: a fitted Dahl element whose friction turns faster than the applied
torque after a reversal (the twist runs back: a hook) is named, against the forward model; so
is a compliance whose soft first segment shares the gap's crossing, and a relay gap whose shares
switch in the loaded flanks or never."""

import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit.model import DahlFriction, LinearCompliance, MaxwellSlipFriction, RelayGapBacklash, ThreeSegmentCompliance
from torsionfit.report._physical import (dahl_hook_note, dahl_hook_ratio, dahl_hook_rise_Nm, gap_segment_note,
                                         relay_gap_note, relay_gap_shares, soft_segment_lost_motion_rad)


def _mesh_after_reversal(friction, params, peak_Nm=25.0, step_Nm=0.05):
    """Mesh torque change over the first step after a reversal at +peak, per applied N·m."""
    up = np.arange(0.0, peak_Nm + step_Nm / 2, step_Nm)
    tau = jnp.asarray(np.concatenate([up, peak_Nm - step_Nm * np.arange(1, 4)]))
    mesh = np.asarray(tau - friction.friction_torque(params, tau))
    i = up.size - 1  # the peak
    return (mesh[i + 1] - mesh[i]) / -step_Nm


@pytest.mark.parametrize("dahl_torque,hooks", [(2.2, True), (5.0, True), (6.0, False), (12.0, False)])
def test_the_ratio_says_when_the_model_runs_back(dahl_torque, hooks):
    """T_f = 2.9 N·m (a measured baseline loop's base fit: τ_d = 2.2 N·m): the forward model's
    mesh torque rises as the torque falls just after the peak exactly when the ratio exceeds 1."""
    friction, params = DahlFriction(), {"friction_torque": 2.9, "dahl_torque": dahl_torque}
    ratio = dahl_hook_ratio(friction, params, 25.0)
    assert ratio == pytest.approx(2 * 2.9 / dahl_torque)
    assert (_mesh_after_reversal(friction, params) < 0) == hooks  # per N·m of falling torque: < 0 is rising
    note = dahl_hook_note(friction, params, 25.0)
    assert bool(note) == hooks
    if hooks:
        assert f"τ_d = {dahl_torque:.3g} N·m" in note and "runs back" in note and " at 25 N·m" not in note
    # the rise the note gives is the forward model's: the mesh torque's largest excess over its value at the peak
    up = np.arange(0.0, 25.0 + 0.0025, 0.005)
    tau = jnp.asarray(np.concatenate([up, 25.0 - 0.005 * np.arange(1, 4000)]))
    mesh = np.asarray(tau - friction.friction_torque(params, tau))
    assert dahl_hook_rise_Nm(friction, params, 25.0) == pytest.approx(max(mesh[up.size - 1:].max() - mesh[up.size - 1], 0.0), abs=0.02)


def test_a_load_dependent_level_counts_at_the_largest_load():
    friction = DahlFriction(load_dependent=True)
    params = {"friction_torque": 1.0, "dahl_torque": 10.0, "friction_load_coefficient": 0.2}
    assert dahl_hook_ratio(friction, params, 40.0) == pytest.approx(2 * (1.0 + 0.2 * 40.0) / 10.0 + 0.2)
    assert "reversal at 40 N·m" in dahl_hook_note(friction, params, 40.0)
    assert _mesh_after_reversal(friction, params, peak_Nm=40.0) < 0
    assert dahl_hook_note(friction, params, 2.0) == ""  # small loops: level 1.4 N·m, ratio 0.48


def test_slip_elements_never_hook():
    friction = MaxwellSlipFriction(n_elements=4)
    params = {"friction_torque": 3.0, "breakaway_spread": 0.8}
    assert np.isnan(dahl_hook_ratio(friction, params, 25.0))
    assert dahl_hook_note(friction, params, 25.0) == ""
    assert _mesh_after_reversal(friction, params) >= -1e-12  # stuck elements hold the mesh torque


#: a final fit of the independent simulator's load-dependent loop at 12.5 Hz (SYNTHETIC, 60′ gap):
#: 15′ of gap and a first segment 14× softer below 0.47 N·m
GAP_IN_SEGMENT = {"k1": 67.36, "k2": 971.3, "k3": 1039.9, "t1": 0.4724, "t2_minus_t1": 15.6, "gap": 0.004366}
ARCMIN = np.radians(1.0 / 60.0)


@pytest.mark.parametrize("params", [GAP_IN_SEGMENT, {**GAP_IN_SEGMENT, "k1": 0.6 * GAP_IN_SEGMENT["k2"]}],
                         ids=["soft", "catalog-like"])
def test_the_first_segments_lost_motion_is_the_forward_models(params):
    """2·T1·(1/K1 − 1/K2) is the twist across zero torque beyond the second segment's line:
    θ(+T) − θ(−T) − 2T/K2 for T between the knees, off the compliance itself."""
    compliance = ThreeSegmentCompliance()
    t = 4.0  # N·m, well past T1's knee, below T2
    theta = np.asarray(compliance(params, jnp.asarray([-t, t])))
    beyond = theta[1] - theta[0] - 2 * t / params["k2"]
    assert soft_segment_lost_motion_rad(compliance, params) == pytest.approx(beyond, rel=0.01)


def test_a_gap_shared_with_a_soft_first_segment_is_named_with_their_sum():
    compliance = ThreeSegmentCompliance()
    note = gap_segment_note(compliance, GAP_IN_SEGMENT)
    total = (GAP_IN_SEGMENT["gap"] + soft_segment_lost_motion_rad(compliance, GAP_IN_SEGMENT)) / ARCMIN
    assert total == pytest.approx(60.0, rel=0.02)  # the simulator's gap
    assert "14.4× softer" in note and f"{total:.3g}′" in note and "not geometric_gap alone" in note
    assert "95 % HDI 55–65′" in gap_segment_note(compliance, GAP_IN_SEGMENT, (55.0, 65.0))
    # a catalog curve (K1 = 0.6 K2), a segment whose lost motion is small beside the gap, another compliance
    assert gap_segment_note(compliance, {**GAP_IN_SEGMENT, "k1": 0.6 * GAP_IN_SEGMENT["k2"]}) == ""
    assert gap_segment_note(compliance, {**GAP_IN_SEGMENT, "gap": 0.06}) == ""
    assert gap_segment_note(LinearCompliance(), {"stiffness": 971.3, "gap": 0.004366}) == ""


def _relay_params(centre_Nm, span_Nm, weights: dict):
    """A relay gap of 1° whose shares are ``weights`` (relay index → weight; the rest e^−12)."""
    relays = RelayGapBacklash()
    logits = np.full(relays.n_relays, -12.0)
    for k, w in weights.items():
        logits[k] = np.log(w)
    return relays, {"gap": np.radians(1.0), "gap_torque": 0.05, "gap_centre_torque": centre_Nm,
                    "gap_relay_span": span_Nm, "gap_relay_logits": jnp.asarray(logits[1:] - logits[0])}


def test_a_relay_gap_within_its_crossing_is_not_named():
    """95 % of the gap on the relay held ±0.2 N·m about +0.66 N·m (the measured baseline
    initial-pos1 validation fit's span), the rest on its neighbours: within ±25 N·m loops."""
    relays = RelayGapBacklash()
    centre = relays.nearest_relay(1 / 3, -1 / 3)
    relays, params = _relay_params(0.66, 0.2, {centre: 0.95, 0: 0.05})
    assert relay_gap_shares(relays, params, -25.0, 25.0) == pytest.approx((0.0, 0.0), abs=1e-4)
    assert relay_gap_note(relays, params, -25.0, 25.0) == ""


def test_relays_in_the_flanks_and_never_switched_are_named_and_never_switched_ones_draw_nothing():
    """The grid over 4 ± 31 N·m on ±40 N·m loops (a measured split trail's fit): a relay
    switching up at +35 N·m is in a flank; one switching down at −27 N·m and up at +35 N·m is
    never switched by loops within ±25 N·m, and its share adds a constant to the twist there."""
    relays = RelayGapBacklash()
    flank = relays.nearest_relay(1.0, -1.0)  # up +35, down −27 N·m
    middle = relays.nearest_relay(0.0, 0.0)  # both at +4 N·m
    relays, params = _relay_params(4.0, 31.0, {flank: 0.3, middle: 0.7})
    shares = relay_gap_shares(relays, params, -40.0, 40.0)
    assert shares == pytest.approx((0.3, 0.0), abs=1e-4)  # every switch inside ±40: none never switched
    note = relay_gap_note(relays, params, -40.0, 40.0)
    assert "30 % of its share sits on relays switching more than 20 N·m" in note and "0 % on relays" in note
    assert relay_gap_shares(relays, params, -25.0, 25.0) == pytest.approx((0.3, 0.3), abs=1e-4)
    # the forward model: within ±25 N·m the never-switched relay's share adds a constant
    tau = jnp.asarray(25.0 * np.sin(np.linspace(0.0, 6 * np.pi, 600)))
    with_it = np.asarray(relays.run_twist(params, tau))
    _, moved = _relay_params(4.0, 31.0, {middle: 1.0})
    without = np.asarray(relays.run_twist(moved, tau))
    # (the other 26 relays carry e^−12 each, and they do switch: 1e-4 of the gap)
    assert np.ptp(with_it - 0.7 * without) < 1e-4 * np.radians(1.0) < 1e-3 * np.ptp(with_it)
