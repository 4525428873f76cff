"""Friction for real loops: play operators, Maxwell-slip elements, load-dependent levels
(DESIGN §1.1, "What real loops add")."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import torsionfit.model as m


def _play_numpy(lo, hi, x0):
    x, out = np.asarray(x0, float), []
    for a, b in zip(lo, hi):
        x = np.clip(x, a, b)
        out.append(x)
    return np.array(out)


@pytest.mark.parametrize("method", ["serial", "associative"])
def test_play_scan_matches_a_plain_loop(method):
    rng = np.random.default_rng(1)
    tau = np.cumsum(rng.normal(size=(300, 1)), axis=0)
    r = np.array([[0.3, 1.0, 2.5]])
    got = m.play_scan(tau - r, tau + r, 0.7, method)
    np.testing.assert_allclose(np.asarray(got), _play_numpy(tau - r, tau + r, np.full(3, 0.7)), atol=1e-12)


def _triangle(peaks, samples_per_leg=400):
    """0 → +p1 → −p1 → +p2 → −p2 …: a torque sequence with reversals at the given peaks."""
    knots = [0.0]
    for p in peaks:
        knots += [p, -p]
    return np.concatenate([np.linspace(a, b, samples_per_leg, endpoint=False) for a, b in zip(knots[:-1], knots[1:])])


def _flat_span_after_top(friction, params, peak):
    """Torque span over which the mesh torque stays constant after the reversal at +peak."""
    tau = _triangle([peak, peak])
    mesh = tau - np.asarray(friction.friction_torque(params, jnp.asarray(tau)))
    top = int(np.argmax(tau[:1200]))
    after = mesh[top:top + 400]
    stuck = np.abs(after - after[0]) < 1e-9
    n = int(np.argmin(stuck)) if not stuck.all() else len(stuck)
    return tau[top] - tau[top + n - 1]


def test_one_element_is_coulomb_friction():
    """One element sticks over 2·T_f of torque after a reversal, whatever the peak."""
    f = m.MaxwellSlipFriction(n_elements=1)
    p = {"friction_torque": 2.0}
    for peak in (10.0, 40.0):
        assert _flat_span_after_top(f, p, peak) == pytest.approx(4.0, abs=2 * peak / 400 + 1e-9)


def test_load_dependent_friction_widens_the_flat_span_with_the_peak():
    f = m.MaxwellSlipFriction(n_elements=1, load_dependent=True)
    p = {"friction_torque": 1.0, "friction_load_coefficient": 0.2}
    small, large = _flat_span_after_top(f, p, 5.0), _flat_span_after_top(f, p, 40.0)
    # stick until τ(1 + μ) = P(1 − μ) − 2r: span = 2(r + μP)/(1 + μ)
    for peak, got in ((5.0, small), (40.0, large)):
        assert got == pytest.approx(2 * (1.0 + 0.2 * peak) / 1.2, abs=2 * peak / 400 + 1e-9)
    assert large > 3 * small


def test_distributed_elements_make_presliding_gradual():
    """Several elements leave the flat part sooner and curve into sliding: the mesh torque's
    slope after the reversal rises in steps instead of jumping from 0 to 1."""
    tau = _triangle([20.0, 20.0])
    top = int(np.argmax(tau[:1200]))
    one = m.MaxwellSlipFriction(n_elements=1)
    many = m.MaxwellSlipFriction(n_elements=6)
    mesh_one = tau - np.asarray(one.friction_torque({"friction_torque": 3.0}, jnp.asarray(tau)))
    mesh_many = tau - np.asarray(many.friction_torque({"friction_torque": 3.0, "breakaway_spread": 0.8}, jnp.asarray(tau)))
    slope_one = np.unique(np.round(np.diff(mesh_one[top:top + 300]) / np.diff(tau[top:top + 300]), 6))
    slope_many = np.unique(np.round(np.diff(mesh_many[top:top + 300]) / np.diff(tau[top:top + 300]), 6))
    assert set(slope_one) <= {0.0, 1.0}
    assert len(slope_many) >= 6  # 0, 1/6, 2/6, … as the elements break away one by one
    # the mean break-away is about T_f: far from the reversal both slide at the same level
    assert mesh_many[top + 390] == pytest.approx(mesh_one[top + 390], rel=0.05)


def test_dahl_load_dependence_and_te_sliding_level():
    f = m.DahlFriction(load_dependent=True)
    p = {"friction_torque": 1.0, "dahl_torque": 0.2, "friction_load_coefficient": 0.1}
    tau = jnp.linspace(0.0, 30.0, 601)
    ft = np.asarray(f.friction_torque(p, tau))
    assert ft[-1] == pytest.approx(1.0 + 0.1 * 30.0, rel=1e-6)  # saturated: T_f + μ|τ|
    assert float(f.sliding_level(p, -30.0)) == pytest.approx(4.0)
    assert float(m.DahlFriction().sliding_level({"friction_torque": 1.0}, 30.0)) == pytest.approx(1.0)


def test_friction_effects_switch_on_by_name_and_are_differentiable():
    model = m.model_with_effects(("hysteresis", "transmission_error"),
                                 {"load_dependent_friction": True, "distributed_friction": {"elements": 4}}, 20.0)
    assert isinstance(model.friction, m.MaxwellSlipFriction) and model.friction.n_elements == 4
    names = [p.name for p in model.parameters()]
    assert "breakaway_spread" in names and "friction_load_coefficient" in names and "dahl_torque" not in names
    tau = _triangle([10.0, 10.0], 100)
    inputs = [m.hysteresis_input(np.arange(len(tau)) * 0.01, tau), m.te_input(np.linspace(0, 2 * np.pi, 50), 10.0, 5.0, 1)]
    base = dict(stiffness=400.0, friction_torque=1.0, breakaway_spread=0.5, friction_load_coefficient=0.2,
                gap=0.01, gap_torque=0.5, angle_offset=jnp.zeros(1), te_offset=jnp.zeros(1))

    def loss(mu):
        return sum(jnp.sum(y**2) for y in model.predict({**base, "friction_load_coefficient": mu}, inputs))

    g = jax.grad(loss)(0.2)
    assert np.isfinite(float(g)) and float(g) != 0.0
    with pytest.raises(Exception, match="distributed_friction"):
        m.model_with_effects(("hysteresis",), {"distributed_friction": "lots"}, 20.0)
    with pytest.raises(Exception, match="load_dependent_friction"):
        m.model_with_effects(("hysteresis",), {"load_dependent_friction": 0.3}, 20.0)


def test_a_lagged_load_lowers_the_level_at_the_peak_and_keeps_it_past_the_reversal():
    """``load_dependent_friction = {lag = true}``: the level follows |τ| through a first-order
    lag T_L. T_L → 0 is the instantaneous level; with a lag the level at the peak has not caught
    up with it (a shorter flat span after the reversal), and where the torque crosses zero it
    has not come down yet (the gap crossing sees the friction of the last peak)."""
    f_now = m.MaxwellSlipFriction(n_elements=1, load_dependent=True)
    f_lag = m.MaxwellSlipFriction(n_elements=1, load_dependent=True, load_lag=True)
    assert [p.name for p in f_lag.parameters()][-1] == "friction_load_lag_time"
    assert next(p for p in f_lag.parameters() if p.name == "friction_load_lag_time").vanishes_at_zero
    p = {"friction_torque": 1.0, "friction_load_coefficient": 0.2}
    tau = _triangle([40.0, 40.0])
    t = np.arange(len(tau)) * 0.025  # 10 s per leg: 4 N·m/s
    now = np.asarray(f_now.friction_torque(p, jnp.asarray(tau)))
    tiny = np.asarray(f_lag.friction_torque({**p, "friction_load_lag_time": 1e-6}, jnp.asarray(tau), time_s=jnp.asarray(t)))
    np.testing.assert_allclose(tiny, now, atol=1e-5)  # first order in T_L: T_L·μ·d|τ|/dt
    lagged = {**p, "friction_load_lag_time": 2.0}
    load = np.asarray(f_lag.level_load(lagged, jnp.asarray(tau), jnp.asarray(t)))
    top = int(np.argmax(tau[:1200]))
    assert load[top] < 0.9 * tau[top]  # behind the rising load at the peak …
    zero = top + int(np.argmin(np.abs(tau[top:top + 400])))
    assert load[zero] > 0.2 * tau[top]  # … and still well above zero where the torque crosses zero
    with pytest.raises(ValueError, match="needs the samples' times"):
        f_lag.friction_torque(lagged, jnp.asarray(tau))
    model = m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"lag": True}}, 20.0)
    assert model.friction.load_dependent and model.friction.load_lag
    with pytest.raises(Exception, match=r"load_dependent_friction: expected true, false or a table \{lag = true"):
        m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"lag": "yes"}}, 20.0)


def test_a_remembered_peak_sets_each_cycles_level_by_its_own_amplitude():
    """``load_dependent_friction = {memory = true}``: the load the level grows with is a peak of
    |τ| let down by (1 − m)·|Δτ| as the torque travels back, never below |τ|. m → 0 is the
    instantaneous level; with memory a cycle slides at the level its own peak set, so the mesh
    torque crosses zero (the gap) at T_f + μ·peak — near zero torque on a small cycle, far out on
    a large one — where the instantaneous level crosses it at one torque, T_f/(1 − μ), whatever
    the amplitude. Rate-independent: the same torque path at another speed gives the same level."""
    p = {"friction_torque": 0.5, "friction_load_coefficient": 0.2}
    f_now = m.MaxwellSlipFriction(n_elements=1, load_dependent=True)
    f_mem = m.MaxwellSlipFriction(n_elements=1, load_dependent=True, load_memory=True)
    names = [p.name for p in f_mem.parameters()]
    assert names[-1] == "friction_load_memory" and "friction_load_lag_time" not in names
    assert next(p for p in f_mem.parameters() if p.name == "friction_load_memory").vanishes_at_zero
    tau = np.concatenate([_triangle([4.0, 4.0, 4.0]), _triangle([40.0, 40.0])[1:]])
    now = np.asarray(f_now.friction_torque(p, jnp.asarray(tau)))
    tiny = np.asarray(f_mem.friction_torque({**p, "friction_load_memory": 1e-6}, jnp.asarray(tau)))
    np.testing.assert_allclose(tiny, now, atol=1e-4)
    kept = {**p, "friction_load_memory": 0.98}
    load = np.asarray(f_mem.level_load(kept, jnp.asarray(tau)))
    assert np.all(load >= np.abs(tau) - 1e-12)
    small = len(_triangle([4.0, 4.0, 4.0]))

    def crossings(friction, params, part):
        # applied torque where the mesh torque τ − T_fric changes sign on the way down
        mesh = tau - np.asarray(friction.friction_torque(params, jnp.asarray(tau)))
        idx = np.arange(len(tau))[part]
        falling = np.diff(tau[idx]) < 0
        sign = np.where((np.diff(np.sign(mesh[idx])) != 0) & falling)[0]
        return np.abs(tau[idx][sign])

    small_now, large_now = crossings(f_now, p, slice(0, small)), crossings(f_now, p, slice(small, None))
    small_mem, large_mem = crossings(f_mem, kept, slice(0, small)), crossings(f_mem, kept, slice(small, None))
    # instantaneous: T_f/(1 − μ) = 0.625 N·m on both
    np.testing.assert_allclose(np.concatenate([small_now, large_now]), 0.625, atol=0.1)
    # remembered: ≈ T_f + μ·4 = 1.3 on the small cycles, ≈ T_f + μ·40 = 8.5 on the large
    assert np.all(np.abs(small_mem - 1.3) < 0.15) and np.all(np.abs(large_mem - 8.5) < 1.0), (small_mem, large_mem)
    slow = np.repeat(tau, 3)  # the same path at a third of the speed: the same levels
    np.testing.assert_allclose(np.asarray(f_mem.level_load(kept, jnp.asarray(slow)))[::3], load, atol=1e-12)
    for method in ("serial", "associative"):
        np.testing.assert_allclose(np.asarray(f_mem.level_load(kept, jnp.asarray(tau), method=method)), load, atol=1e-12)
    grad = jax.grad(lambda mem: jnp.sum(f_mem.friction_torque({**p, "friction_load_memory": mem}, jnp.asarray(tau))**2))(0.5)
    assert np.isfinite(float(grad)) and float(grad) != 0.0
    model = m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"memory": True}}, 20.0)
    assert model.friction.load_memory and not model.friction.load_lag
    # with a lag as well, the lagged load's peaks are remembered: m → 0 is the lag alone
    both = m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"memory": True, "lag": True}}, 20.0).friction
    assert both.load_memory and both.load_lag
    t = np.arange(len(tau)) * 0.025
    lag_only = m.MaxwellSlipFriction(n_elements=1, load_dependent=True, load_lag=True)
    lagged = {**p, "friction_load_lag_time": 2.0}
    np.testing.assert_allclose(
        np.asarray(both.level_load({**lagged, "friction_load_memory": 1e-9}, jnp.asarray(tau), jnp.asarray(t))),
        np.asarray(lag_only.level_load(lagged, jnp.asarray(tau), jnp.asarray(t))), atol=1e-6)
    with pytest.raises(Exception, match=r"load_dependent_friction: expected true, false or a table"):
        m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"memory": "yes"}}, 20.0)


def _breakaway_span(friction, params, peak):
    """Torque span after the reversal at +peak from the first element's break-away to the
    last's (an element breaks away where its mesh share starts to move)."""
    tau = _triangle([peak, peak], 2000)
    shares = np.asarray(friction.mesh_shares(params, jnp.asarray(tau)))
    top = int(np.argmax(tau[:6000]))
    after = shares[top:top + 2000]
    moved = np.abs(after - after[0]) > 1e-9
    assert moved.any(axis=0).all(), "an element never broke away on the way down"
    breaks = tau[top + np.argmax(moved, axis=0)]
    return float(breaks.max() - breaks.min())


def test_a_common_load_growth_keeps_the_breakaway_spread_and_the_mean_level():
    """``load_dependent_friction = {growth = "common"}``: the load adds μ|τ| to every element's
    level instead of scaling each (R_k = r_k + μ|τ|). The spread of break-away levels in N·m
    stays as the load grows — gradual pre-sliding after a small reversal, a sharp knee after a
    large one — while the mean level, T_f + μ|τ|, is the proportional growth's."""
    p = {"friction_torque": 1.0, "breakaway_spread": 0.6, "friction_load_coefficient": 0.3}
    prop = m.MaxwellSlipFriction(n_elements=6, load_dependent=True)
    common = m.MaxwellSlipFriction(n_elements=6, load_dependent=True, load_growth="common")
    levels = np.asarray(prop.breakaway_levels(p))
    small_p, large_p = _breakaway_span(prop, p, 10.0), _breakaway_span(prop, p, 40.0)
    small_c, large_c = _breakaway_span(common, p, 10.0), _breakaway_span(common, p, 40.0)
    # common: element k sticks after the reversal at P until τ − P + R_k(P) = −R_k(τ), i.e.
    # τ(1 + μ) = P(1 − μ) − 2r_k (every break-away at τ > 0 here): a span 2(r_max − r_min)/(1 + μ)
    # whatever the peak
    expected = 2 * (levels[-1] - levels[0]) / 1.3
    assert small_c == pytest.approx(expected, rel=0.02) and large_c == pytest.approx(expected, rel=0.02)
    # proportional: each level scales with 1 + μ|τ|/T_f, so the span grows with the peak
    assert large_p > 2.5 * small_p and large_p > 5 * large_c
    # the same mean level while sliding: far from the reversal the mesh torques agree
    tau = _triangle([40.0, 40.0])
    mesh_p = tau - np.asarray(prop.friction_torque(p, jnp.asarray(tau)))
    mesh_c = tau - np.asarray(common.friction_torque(p, jnp.asarray(tau)))
    top = int(np.argmax(tau[:1200]))
    np.testing.assert_allclose(mesh_c[top + 390], mesh_p[top + 390], rtol=0.02)
    model = m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"lag": True, "growth": "common"},
                                                   "distributed_friction": True}, 20.0)
    assert model.friction.load_growth == "common" and model.friction.load_lag
    with pytest.raises(Exception, match="growth = 'common' needs distributed_friction"):
        m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"growth": "common"}}, 20.0)
    with pytest.raises(Exception, match="growth one of proportional, common"):
        m.model_with_effects(("hysteresis",), {"load_dependent_friction": {"growth": "sum"}, "distributed_friction": True}, 20.0)
    with pytest.raises(ValueError, match="load_growth must be one of"):
        m.MaxwellSlipFriction(load_growth="sum")
