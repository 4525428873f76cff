"""Forward model: gradients, scan equivalence, physics checks (DESIGN §1)."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import torsionfit.model as m
from torsionfit import InputError
from torsionfit.units import ANGLE_UNITS

RATED = 100.0  # N·m


def five_step(rated_Nm=RATED, rate_Nm_per_s=10.0, samples_per_step=400):
    """The paper's protocol 0→+T→0→−T→0→+T as (time, torque), loaded at a constant rate."""
    step = rated_Nm / rate_Nm_per_s
    knots_t = step * np.arange(6)
    knots_tau = rated_Nm * np.array([0, 1, 0, -1, 0, 1.0])
    t = np.linspace(0, knots_t[-1], 5 * samples_per_step + 1)
    return t, np.interp(t, knots_t, knots_tau)


def base_params(**over):
    p = dict(
        stiffness=2.0e5,  # N·m/rad
        friction_torque=3.0,
        dahl_torque=1.5,
        gap=2e-4,
        gap_torque=2.0,
        angle_offset=jnp.array([1e-4]),
    )
    p.update(over)
    return p


def full_model_and_data():
    """Every component switched on, one hysteresis and two TE runs."""
    model = m.CampaignModel(
        run_kinds=("hysteresis", "transmission_error", "transmission_error"),
        compliance=m.AsymmetricCompliance(m.ThreeSegmentCompliance(), switch_width_Nm=5.0),
        creep=m.Creep(),
        kinematic=m.KinematicHarmonics(orders=(1, 2, 14)),
        speed=m.SpeedDependence(viscous=True, compliance_order=2),
        temperature=m.TemperatureDependence(),
        drift=True,
        torque_offset=True,
    )
    t, tau = five_step(samples_per_step=60)
    phi = np.linspace(0, 2 * np.pi, 200)
    inputs = [
        m.hysteresis_input(t, tau, temperature_delta_K=-10.0),
        m.te_input(phi, 80.0, 5.0, +1),
        m.te_input(phi, 80.0, 10.0, -1, temperature_delta_K=15.0),
    ]
    params = dict(
        k1=1.5e5, k2=2.0e5, k3=2.5e5, t1=20.0, t2_minus_t1=40.0,
        compliance_asymmetry=0.05,
        friction_torque=3.0, dahl_torque=1.5, gap=2e-4, gap_torque=2.0,
        creep_stiffness=2e6, creep_time=8.0,
        viscous_friction=0.5, speed_compliance_1=0.01, speed_compliance_2=0.002,
        torque_offset=0.3, temperature_compliance=0.004, temperature_friction=-0.02,
        angle_offset=jnp.array([1e-4]), te_offset=jnp.array([-2e-5]),
        kin_cos=jnp.array([1e-5, 2e-6, 1e-6]), kin_sin=jnp.array([-5e-6, 1e-6, 3e-7]),
        drift=jnp.array([1e-7, -2e-7, 3e-7]),
    )
    return model, inputs, params


def test_parameters_declared_match_params_used():
    model, inputs, params = full_model_and_data()
    names = [p.name for p in model.parameters()]
    assert sorted(names) == sorted(params)
    sizes = {p.name: p.size for p in model.parameters()}
    for k, v in params.items():
        assert np.size(v) == sizes[k], k


def test_components_sum_to_total():
    model, inputs, params = full_model_and_data()
    for comps in model.components(params, inputs):
        parts = sum(comps[k] for k in m.COMPONENTS)
        np.testing.assert_allclose(parts, comps["total"], rtol=0, atol=1e-15)
        for k in m.COMPONENTS:
            assert np.all(np.isfinite(comps[k]))


def test_predict_is_the_components_total():
    """predict skips the parts that cancel in the total (elastic and geometric at the applied
    torque): the same angle to rounding, for every run kind and every effect switched on."""
    model, inputs, params = full_model_and_data()
    for pred, comps in zip(model.predict(params, inputs), model.components(params, inputs)):
        scale = np.max(np.abs(comps["total"]))
        np.testing.assert_allclose(pred, comps["total"], rtol=0, atol=1e-13 * scale)


def test_te_runs_evaluated_together_equal_each_alone():
    """predict evaluates every TE run of a campaign in one call (their loads, speeds, directions,
    zero groups and temperatures spread over their samples): the same angles as run by run."""
    model, inputs, params = full_model_and_data()
    model = dataclasses.replace(model, drift=False, te_zero_groups=2,
                                run_kinds=model.run_kinds + ("transmission_error",))
    phi = np.linspace(0, 3 * np.pi, 150)
    inputs = inputs + [m.te_input(phi, 40.0, 2.0, -1, zero_group=1, temperature_delta_K=-5.0)]
    params = {k: v for k, v in params.items() if k != "drift"} | {"te_offset": jnp.array([-2e-5, 3e-5])}
    together = model.predict(params, inputs)
    alone = [model.te_components(params, d, i)["total"] if k == "transmission_error" else None
             for i, (k, d) in enumerate(zip(model.run_kinds, inputs))]
    assert [len(t) for t in together] == [len(d.time_s) for d in inputs]
    for t, a in zip(together, alone):
        if a is not None:
            np.testing.assert_allclose(t, a, rtol=0, atol=1e-15 * float(np.max(np.abs(a))))


@pytest.mark.parametrize("name", [
    "k1", "k2", "k3", "t1", "t2_minus_t1", "compliance_asymmetry", "friction_torque",
    "dahl_torque", "gap", "gap_torque", "creep_stiffness", "creep_time", "viscous_friction",
    "speed_compliance_1", "speed_compliance_2", "torque_offset", "angle_offset", "te_offset",
    "kin_cos", "kin_sin", "drift", "temperature_compliance", "temperature_friction",
])
def test_gradient_matches_finite_difference(name):
    model, inputs, params = full_model_and_data()
    rng = np.random.default_rng(0)
    weights = [jnp.asarray(rng.normal(size=np.shape(x.output_angle_rad if isinstance(x, m.TEInput) else x.time_s))) for x in inputs]

    def objective(p):
        # a smooth scalar of every run's prediction, in arcsec so magnitudes are O(1)
        preds = model.predict(p, inputs)
        return sum(jnp.sum(w * y) for w, y in zip(weights, preds)) * 206264.8

    grad = jax.grad(objective)(params)[name]
    value = np.atleast_1d(np.asarray(params[name], float))
    for i in range(value.size):
        h = 1e-6 * max(abs(value[i]), 1e-3 if name != "torque_offset" else 1.0)
        if name in ("kin_cos", "kin_sin", "drift", "angle_offset", "te_offset"):
            h = 1e-9

        def shifted(delta):
            v = value.copy()
            v[i] += delta
            q = dict(params)
            q[name] = jnp.asarray(v) if np.ndim(params[name]) else v[0]
            return float(objective(q))

        fd = (shifted(h) - shifted(-h)) / (2 * h)
        g = float(np.atleast_1d(grad)[i])
        assert g == pytest.approx(fd, rel=1e-5, abs=1e-6 * max(1.0, abs(fd))), (name, i)


@pytest.mark.parametrize("n", [1, 7, 1000, 4097])
def test_associative_scan_equals_serial(n):
    rng = np.random.default_rng(n)
    a = jnp.asarray(rng.uniform(0.0, 1.0, n))
    b = jnp.asarray(rng.normal(size=n))
    x_assoc = m.affine_scan(a, b, 0.3, "associative")
    x_serial = m.affine_scan(a, b, 0.3, "serial")
    np.testing.assert_allclose(x_assoc, x_serial, rtol=0, atol=1e-12)


def test_model_scan_methods_agree():
    model, inputs, params = full_model_and_data()
    assoc = [m_ for m_ in model.__class__(**{**model.__dict__, "scan": "associative"}).predict(params, inputs)]
    serial = model.__class__(**{**model.__dict__, "scan": "serial"}).predict(params, inputs)
    for x, y in zip(assoc, serial):
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-12)


def test_auto_scan_is_serial_on_cpu():
    if jax.default_backend() == "cpu":
        assert m.resolve_scan_method("auto") == "serial"
    with pytest.raises(ValueError, match="scan method"):
        m.resolve_scan_method("parallel")


def loop_area(theta, tau):
    """∮ τ dθ by the trapezoid rule over the given samples."""
    return float(np.sum(0.5 * (tau[1:] + tau[:-1]) * np.diff(theta)))


def hysteresis_prediction(params, model=None, rate=10.0, samples_per_step=400):
    model = model or m.CampaignModel(run_kinds=("hysteresis",))
    t, tau = five_step(rate_Nm_per_s=rate, samples_per_step=samples_per_step)
    comps = model.components(params, [m.hysteresis_input(t, tau)])[0]
    return t, tau, comps


def test_zero_friction_gives_zero_loop_area():
    _, tau, c = hysteresis_prediction(base_params(friction_torque=1e-12))
    # the closed part of the loop: from the end of step 1 to the end of step 5
    i = len(tau) // 5
    assert abs(loop_area(np.asarray(c["total"])[i:], tau[i:])) < 1e-9


def test_friction_gives_positive_loop_area():
    _, tau, c = hysteresis_prediction(base_params())
    i = len(tau) // 5
    assert loop_area(np.asarray(c["total"])[i:], tau[i:]) > 0


def test_loop_width_at_zero_torque_is_two_tf_over_k():
    """Linear spring, no gap: once friction has saturated the loop is 2·T_f/K wide at τ = 0."""
    model = m.CampaignModel(run_kinds=("hysteresis",), backlash=m.NoBacklash())
    p = base_params(friction_torque=4.0, dahl_torque=0.5)
    _, tau, c = hysteresis_prediction(p, model=model, samples_per_step=2000)
    theta = np.asarray(c["total"])
    n = len(tau) // 5
    down = np.interp(0.0, tau[2 * n:n:-1], theta[2 * n:n:-1])  # step 2 ends at τ = 0
    up = np.interp(0.0, tau[3 * n:4 * n + 1], theta[3 * n:4 * n + 1])  # step 4 ends at τ = 0
    assert down - up == pytest.approx(2 * 4.0 / 2.0e5, rel=1e-6)


def test_preloaded_gap_is_the_smooth_gap_without_preload_and_closed_within_it():
    """A preloaded gap (split-pinwheel designs): with T_p → 0 it is the smooth gap; a cycle
    whose mesh torque stays within ±T_p sees no gap at all, a cycle beyond it crosses all of β,
    half at each of ±T_p."""
    params = dict(gap=2e-3, gap_torque=0.3, gap_preload_torque=1e-9)
    tau = jnp.linspace(-20.0, 20.0, 401)
    np.testing.assert_allclose(m.PreloadedBacklash()(params, tau), m.SmoothBacklash()(params, tau), rtol=0, atol=1e-15)
    params["gap_preload_torque"] = 6.0
    theta = np.asarray(m.PreloadedBacklash()(params, tau))
    small = np.abs(tau) <= 4.0  # a ±4 N·m play ramp inside the preload
    assert np.ptp(theta[small]) < 1e-5 * params["gap"]
    assert theta[-1] - theta[0] == pytest.approx(params["gap"], rel=1e-9)
    half = np.asarray(m.PreloadedBacklash()(params, jnp.array([-6.0, 6.0])))
    np.testing.assert_allclose(half, [-0.25 * params["gap"], 0.25 * params["gap"]], rtol=1e-9)


def test_residual_play_is_the_preloaded_gap_plus_a_small_centred_one():
    """A preloaded gap with a residual play: w → 0 is the preloaded gap; a ±4 N·m cycle inside
    the preload crosses the residual share w·β alone, in a jump of width ~τ₀ at zero torque; a
    cycle beyond it crosses all of β."""
    params = dict(gap=2e-3, gap_torque=0.3, gap_preload_torque=6.0, gap_residual_share=1e-12, gap_residual_torque=0.05)
    tau = jnp.linspace(-20.0, 20.0, 4001)
    np.testing.assert_allclose(m.ResidualPlayBacklash()(params, tau), m.PreloadedBacklash()(params, tau), rtol=0, atol=1e-14)
    params["gap_residual_share"] = 0.25
    theta = np.asarray(m.ResidualPlayBacklash()(params, tau))
    small = np.abs(np.asarray(tau)) <= 4.0
    assert np.ptp(theta[small]) == pytest.approx(0.25 * params["gap"], rel=1e-4)
    near_zero = np.abs(np.asarray(tau)) <= 0.2  # four τ₀: the residual play is crossed there
    assert np.ptp(theta[near_zero]) > 0.99 * 0.25 * params["gap"]
    assert theta[-1] - theta[0] == pytest.approx(params["gap"], rel=1e-9)
    assert np.all(np.diff(theta) >= -1e-15)  # increasing, to rounding where it saturates


def test_gap_preload_switch():
    """``gap_preload`` gives the preloaded gap to loops, and stops with one line on a campaign
    without a loop or with a value that is not a switch."""
    model = m.model_with_effects(("hysteresis",), {"gap_preload": True}, 20.0, fitted=True)
    assert isinstance(model.backlash, m.PreloadedBacklash)
    assert "gap_preload_torque" in [p.name for p in model.parameters()]
    with pytest.raises(InputError, match=r"gap_preload: needs a hysteresis run"):
        m.model_with_effects(("transmission_error",), {"gap_preload": True}, 20.0, fitted=True)
    model = m.model_with_effects(("hysteresis",), {"gap_preload": {"residual_play": True}}, 20.0, fitted=True)
    assert isinstance(model.backlash, m.ResidualPlayBacklash)
    assert {"gap_residual_share", "gap_residual_torque"} <= {p.name for p in model.parameters()}
    for bad in ("yes", {"residual": True}, {"residual_play": 1}):
        with pytest.raises(InputError, match=r"gap_preload: expected true, false or \{residual_play = true\}"):
            m.model_with_effects(("hysteresis",), {"gap_preload": bad}, 20.0)
    with pytest.raises(InputError, match=r"gap_steps: needs a hysteresis run and cannot be combined with gap_preload"):
        m.model_with_effects(("hysteresis",), {"gap_preload": {"residual_play": True}, "gap_steps": {"span_Nm": 4.0}}, 20.0)


def test_stepped_gap():
    """A gap taken up in steps: it spans the whole gap like the smooth gap, one step carrying
    every share is a smooth gap moved to that step's torque, and a step's share is the twist
    taken up across it."""
    b = m.SteppedBacklash(n_steps=3, span_Nm=4.0)
    tau = jnp.linspace(-30.0, 30.0, 601)
    params = dict(gap=2e-3, gap_torque=0.3, gap_step_logits=jnp.array([0.5, -1.0]))
    theta = np.asarray(b(params, tau))
    assert theta[-1] - theta[0] == pytest.approx(params["gap"], rel=1e-9)
    assert np.all(np.diff(theta) >= -1e-15)  # increasing, to rounding where it saturates
    # the steps at −4, 0, +4 N·m: the twist across each is its share of the gap
    shares = np.asarray(b.shares(params))
    across = np.diff(np.asarray(b(params, jnp.array([-30.0, -2.0, 2.0, 30.0]))))
    np.testing.assert_allclose(across, shares * params["gap"], rtol=1e-4)  # tanh tails 2 N·m from a step
    one = dict(params, gap_step_logits=jnp.array([60.0, 0.0]))  # all of it at 0 N·m
    np.testing.assert_allclose(b(one, tau), m.SmoothBacklash()(params, tau), rtol=0, atol=1e-15)


def test_gap_steps_switch():
    """``gap_steps`` gives the stepped gap to loops; a malformed value, a campaign without a loop
    or a combination with the preloaded gap stops with one line."""
    model = m.model_with_effects(("hysteresis",), {"gap_steps": {"steps": 5, "span_Nm": 3.0}}, 20.0, fitted=True)
    assert isinstance(model.backlash, m.SteppedBacklash)
    assert (model.backlash.n_steps, model.backlash.span_Nm) == (5, 3.0)
    sizes = {p.name: p.size for p in model.parameters()}
    assert sizes["gap_step_logits"] == 4
    # by default an odd count, one step at zero torque: the plain centred gap stays a case of it
    default = m.model_with_effects(("hysteresis",), {"gap_steps": {"span_Nm": 4.0}}, 20.0, fitted=True).backlash
    assert default.n_steps % 2 == 1 and np.min(np.abs(np.asarray(default.centres_Nm()))) == 0.0
    assert m.SteppedBacklash(span_Nm=4.0).n_steps == default.n_steps
    for bad in (True, {}, {"steps": 1, "span_Nm": 4.0}, {"steps": 4, "span_Nm": -1.0}, {"steps": 4, "span_Nm": 4, "width": 2}):
        with pytest.raises(InputError, match=r"\[effects\]\.gap_steps: expected \{steps = N, span_Nm = S\}"):
            m.model_with_effects(("hysteresis",), {"gap_steps": bad}, 20.0)
    with pytest.raises(InputError, match=r"gap_steps: needs a hysteresis run"):
        m.model_with_effects(("transmission_error",), {"gap_steps": {"span_Nm": 4.0}}, 20.0, fitted=True)
    with pytest.raises(InputError, match=r"cannot be combined with gap_preload"):
        m.model_with_effects(("hysteresis",), {"gap_steps": {"span_Nm": 4.0}, "gap_preload": True}, 20.0)


def angle_at_rated(rate, creep_on=True):
    model = m.CampaignModel(run_kinds=("hysteresis",), creep=m.Creep() if creep_on else None)
    p = base_params(creep_stiffness=1.0e6, creep_time=5.0)
    _, _, c = hysteresis_prediction(p, model=model, rate=rate)
    return float(c["total"][-1] - c["offset"][-1])


def test_faster_loading_gives_smaller_angle_with_creep():
    slow, mid, fast = (angle_at_rated(r) for r in (1.0, 5.0, 25.0))
    assert slow > mid > fast
    # without creep the model is rate-independent
    assert angle_at_rated(1.0, False) == pytest.approx(angle_at_rated(25.0, False), rel=1e-12)


def te_at_speed(speed_rpm, viscous):
    model = m.CampaignModel(
        run_kinds=("transmission_error",),
        speed=m.SpeedDependence(viscous=viscous, compliance_order=0),
    )
    p = base_params(te_offset=jnp.zeros(1), viscous_friction=2.0)
    del p["angle_offset"]
    if not viscous:
        del p["viscous_friction"]
    phi = np.linspace(0, 2 * np.pi, 100)
    return float(model.predict(p, [m.te_input(phi, RATED, speed_rpm, +1)])[0].mean())


def test_te_grows_with_speed_when_viscous_friction_is_on():
    te = [te_at_speed(v, True) for v in (1.0, 5.0, 10.0)]
    assert te[0] < te[1] < te[2]
    flat = [te_at_speed(v, False) for v in (1.0, 10.0)]
    assert flat[0] == pytest.approx(flat[1], rel=1e-12)


@pytest.mark.parametrize("direction", [1, -1])
def test_a_te_run_timed_by_its_angle_reads_a_wrapping_angle_as_the_turns_travelled(direction):
    """Three output turns logged modulo one turn (a single-turn encoder), no time column: the
    run is timed by the angle travelled, and each wrap is no turn of its own (it added one
    turn's time per wrap: 6 turns' time for 3 turns)."""
    phi = direction * (0.1 + np.linspace(0.0, 6 * np.pi, 601))
    wrapped = np.mod(phi, 2 * np.pi)
    assert np.sum(np.abs(np.diff(wrapped)) > np.pi) == 3
    plain, logged = m.te_input(phi, RATED, 2.0, direction), m.te_input(wrapped, RATED, 2.0, direction)
    np.testing.assert_allclose(np.asarray(logged.time_s), np.asarray(plain.time_s), rtol=1e-12)
    assert float(plain.time_s[-1]) == pytest.approx(90.0)  # 3 turns at 2 rpm


def test_te_direction_flips_sign_of_twist():
    model = m.CampaignModel(run_kinds=("transmission_error",) * 2)
    p = base_params(te_offset=jnp.zeros(1))
    del p["angle_offset"]
    phi = np.linspace(0, 2 * np.pi, 50)
    fw, bw = model.predict(p, [m.te_input(phi, RATED, 5, +1), m.te_input(phi, RATED, 5, -1)])
    np.testing.assert_allclose(fw, -bw, atol=1e-15)
    assert float(fw[0]) == pytest.approx((RATED + 3.0) / 2.0e5 + 1e-4 * np.tanh(103 / 2.0), rel=1e-12)


def test_temperature_scales_compliance_and_friction_level():
    """A TE run ΔT above the reference twists by exp(α_C·ΔT)·C(τ + exp(α_f·ΔT)·T_f) + gap; at
    ΔT = 0 the model is the one without the term; a loop's width follows the friction level."""
    plain = m.CampaignModel(run_kinds=("transmission_error", "hysteresis"))
    warm = m.CampaignModel(run_kinds=("transmission_error", "hysteresis"), temperature=m.TemperatureDependence())
    p = base_params(te_offset=jnp.zeros(1), temperature_compliance=0.004, temperature_friction=-0.02)
    phi = np.linspace(0, 2 * np.pi, 50)
    t, tau = five_step(samples_per_step=200)
    at_reference = [m.te_input(phi, RATED, 5, +1), m.hysteresis_input(t, tau)]
    for a, b in zip(warm.predict(p, at_reference), plain.predict(p, at_reference)):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
    dT = 20.0
    te, loop = warm.predict(p, [m.te_input(phi, RATED, 5, +1, temperature_delta_K=dT), m.hysteresis_input(t, tau, dT)])
    mesh = RATED + 3.0 * np.exp(-0.02 * dT)
    assert float(te[0]) == pytest.approx(np.exp(0.004 * dT) * mesh / 2.0e5 + 1e-4 * np.tanh(mesh / 2.0), rel=1e-12)
    # loop width at zero torque on the unloading branch (steps 2 and 4), warm against at reference
    cold_loop = plain.predict(p, [m.te_input(phi, RATED, 5, +1), m.hysteresis_input(t, tau)])[1]

    def width(theta):
        down = np.flatnonzero(np.abs(tau) < 1e-9)
        return float(theta[down[1]] - theta[down[2]])

    assert width(np.asarray(loop)) < width(np.asarray(cold_loop))  # less friction when warm


def test_three_segment_slopes():
    c = m.ThreeSegmentCompliance(knee_fraction=0.02)
    p = dict(k1=1e5, k2=2e5, k3=4e5, t1=10.0, t2_minus_t1=40.0)
    tau = jnp.array([2.0, 6.0, 20.0, 40.0, 70.0, 90.0])
    th = np.asarray(c(p, tau))
    assert (th[1] - th[0]) / 4.0 == pytest.approx(1 / 1e5, rel=1e-3)
    assert (th[3] - th[2]) / 20.0 == pytest.approx(1 / 2e5, rel=1e-3)
    assert (th[5] - th[4]) / 20.0 == pytest.approx(1 / 4e5, rel=1e-3)
    np.testing.assert_allclose(c(p, -tau), -th, rtol=1e-12)


def test_power_law_and_asymmetry():
    pl = m.PowerLawCompliance(reference_torque_Nm=20.0)
    p = dict(elastic_rated_twist=2e-3, power_exponent=1.5)
    assert float(pl(p, jnp.array(20.0))) == pytest.approx(2e-3, rel=1e-4)  # θ_r at the reference torque
    assert float(pl(p, jnp.array(50.0))) == pytest.approx(2e-3 * (50.0 / 20.0) ** (1 / 1.5), rel=1e-4)
    with pytest.raises(ValueError, match="reference_torque_Nm"):
        m.PowerLawCompliance(reference_torque_Nm=0.0)
    assert float(pl(p, jnp.array(-50.0))) == pytest.approx(-float(pl(p, jnp.array(50.0))))
    asym = m.AsymmetricCompliance(m.LinearCompliance(), switch_width_Nm=1.0)
    q = dict(stiffness=1e5, compliance_asymmetry=0.1)
    assert float(asym(q, jnp.array(50.0))) == pytest.approx(1.1 * 50 / 1e5, rel=1e-9)
    assert float(asym(q, jnp.array(-50.0))) == pytest.approx(-0.9 * 50 / 1e5, rel=1e-9)


def test_duplicate_time_stamps_are_harmless():
    """Benches quantise time: Δt = 0 must leave creep unchanged, not divide by zero."""
    model = m.CampaignModel(run_kinds=("hysteresis",), creep=m.Creep())
    t, tau = five_step(samples_per_step=100)
    t = np.floor(t / 0.5) * 0.5  # many rows share a stamp
    p = base_params(creep_stiffness=1e6, creep_time=5.0)
    y = model.predict(p, [m.hysteresis_input(t, tau)])[0]
    assert np.all(np.isfinite(y))


def test_unknown_run_kind_rejected():
    with pytest.raises(ValueError, match="unknown run kind"):
        m.CampaignModel(run_kinds=("torque_ramp",))


def test_temperature_effect_values():
    """true, or {friction = false} (compliance only); anything else is one clear line."""
    from torsionfit import InputError

    full = m.model_with_effects(["transmission_error"], {"temperature_dependence": True}, RATED)
    only = m.model_with_effects(["transmission_error"], {"temperature_dependence": {"friction": False}}, RATED)
    assert {p.name for p in full.parameters()} - {p.name for p in only.parameters()} == {"temperature_friction"}
    for bad in ("yes", {"friction": "no"}, {"viscosity": True}):
        with pytest.raises(InputError, match="temperature_dependence: expected true, false or"):
            m.model_with_effects(["transmission_error"], {"temperature_dependence": bad}, RATED)


@pytest.mark.slow
def test_a_fit_with_gap_steps_recovers_where_the_gap_is_taken_up(tmp_path):
    """SYNTHETIC friction bench (tests/benches/friction/base.toml: its 380 N·m loop with play ramps
    to ±30 N·m, 6 N·m Dahl friction) with a 4′ gap taken up mostly at +20 N·m: a fit with the
    steps declared finds the gap and the steps' shares, the truth inside its 95 % intervals."""
    from pathlib import Path

    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, fit_campaign

    effects = {"gap_steps": {"steps": 3, "span_Nm": 20.0}}
    logits = [-3.0, 1.0]  # shares 0.26 / 0.01 / 0.72 at −20 / 0 / +20 N·m
    text = (Path(__file__).parent / "benches" / "friction" / "base.toml").read_text()
    text = text.replace("gap_arcmin = 1.0", "gap_arcmin = 4.0")
    text = text[: text.index("[[runs]]", text.index("[[runs]]") + 1)]  # the full loop alone: a cheaper fit
    text = text.replace("[truth]", "[effects]\ngap_steps = {steps = 3, span_Nm = 20.0}\n[truth]\n"
                        f"gap_step_logits = {logits}", 1)
    bench = tmp_path / "bench.toml"
    bench.write_text(text)
    sim = simulate(load_bench(bench), seed=3)
    fit = fit_campaign(sim.campaign, FitOptions(sampler="laplace", effects=effects, n_starts=1), seed=0)
    gap = np.asarray(fit.metric_values["gap"]) / ANGLE_UNITS["arcmin"]
    lo, hi = np.quantile(gap, [0.025, 0.975])
    assert lo < 4.0 < hi, (lo, hi)
    steps = np.asarray(fit.metric_values["gap_step_logits"])
    for k, truth in enumerate(logits):
        lo, hi = np.quantile(steps[:, k], [0.025, 0.975])
        assert lo < truth < hi, (k, lo, hi)


def test_play_torque_offset_shifts_the_torque_of_the_smallest_cycles_alone():
    """The model with the play ramps' torque zero δ_p equals the model without it driven by the
    torque less δ_p on the marked samples (the state carried on into the large cycles)."""
    t, tau = five_step(samples_per_step=60)
    small = (np.arange(tau.size) < 120).astype(float)
    with_offset = m.CampaignModel(run_kinds=("hysteresis",), play_torque_offset=True)
    plain = m.CampaignModel(run_kinds=("hysteresis",))
    assert [p.name for p in with_offset.parameters()] == [p.name for p in plain.parameters()][:-1] + ["play_torque_offset", "angle_offset"]
    y = with_offset.predict({**base_params(), "play_torque_offset": 2.5}, [m.hysteresis_input(t, tau, small_cycle=small)])[0]
    shifted = plain.predict(base_params(), [m.hysteresis_input(t, tau - 2.5 * small)])[0]
    np.testing.assert_allclose(y, shifted, rtol=0, atol=1e-12)
    unmarked = with_offset.predict({**base_params(), "play_torque_offset": 2.5}, [m.hysteresis_input(t, tau)])[0]
    np.testing.assert_allclose(unmarked, plain.predict(base_params(), [m.hysteresis_input(t, tau)])[0], rtol=0, atol=1e-12)
    assert not np.allclose(y, unmarked)
    with pytest.raises(InputError, match="play_torque_offset"):
        m.model_with_effects(("hysteresis",), {"play_torque_offset": {"on": True}}, 100.0)
    assert m.model_with_effects(("hysteresis",), {"play_torque_offset": True}, 100.0).play_torque_offset
