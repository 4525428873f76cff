"""The damped gap crossing (``gap_lag``): the gap follows the mesh torque through a first-order
lag. The lag recurrence (exact on piecewise-linear input, the identity at no lag, held stamps)
and what it does to a loop: the gap is crossed late, the peaks are not."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit._errors import InputError
from torsionfit.model import first_order_lag, model_with_effects
from torsionfit.model._inputs import hysteresis_input


def _reference(time_s, x, lag, substeps=2000):
    """T·dy/dt = x − y by fine midpoint steps on the linearly interpolated input."""
    y = [x[0]]
    for n in range(1, len(time_s)):
        t = np.linspace(time_s[n - 1], time_s[n], substeps + 1)
        xs = np.interp(t, time_s[n - 1:n + 1], x[n - 1:n + 1])
        v = y[-1]
        for k in range(substeps):
            h = t[k + 1] - t[k]
            xm = 0.5 * (xs[k] + xs[k + 1])
            v = v + h * (xm - (v + 0.5 * h * (xm - v) / lag)) / lag
        y.append(v)
    return np.array(y)


def test_lag_matches_the_ode_on_piecewise_linear_input():
    t = np.array([0.0, 0.3, 0.5, 1.4, 1.5, 2.9, 3.0])
    x = np.array([0.0, 3.0, 5.0, -2.0, -1.0, 4.0, 4.0])
    got = first_order_lag(jnp.asarray(t), jnp.asarray(x), 0.4)
    np.testing.assert_allclose(np.asarray(got), _reference(t, x, 0.4), atol=1e-5)


def test_lag_on_a_ramp_is_the_ramp_delayed_by_the_lag():
    t = np.linspace(0.0, 20.0, 401)
    got = np.asarray(first_order_lag(jnp.asarray(t), jnp.asarray(2.0 * t), 0.5))
    # y = a(t − T) + a·T·e^(−t/T): the delay after the start-up transient
    np.testing.assert_allclose(got, 2.0 * (t - 0.5) + 1.0 * np.exp(-t / 0.5), atol=1e-9)


def test_no_lag_is_the_identity_and_its_derivative_is_minus_the_rate():
    t = jnp.linspace(0.0, 10.0, 101)
    x = jnp.sin(t)
    tiny = 1e-7
    np.testing.assert_allclose(np.asarray(first_order_lag(t, x, tiny)), np.asarray(x), atol=1e-6)
    d = jax.jacfwd(lambda T: first_order_lag(t, x, T))(tiny)
    assert np.all(np.isfinite(np.asarray(d)))
    # first order: −dx/dt of the linearly interpolated input (backward differences)
    np.testing.assert_allclose(np.asarray(d)[1:], -np.diff(np.asarray(x)) / 0.1, atol=1e-4)


def test_duplicate_stamps_hold():
    got = np.asarray(first_order_lag(jnp.array([0.0, 1.0, 1.0, 2.0]), jnp.array([0.0, 1.0, 5.0, 5.0]), 0.5))
    assert got[2] == pytest.approx(got[1])
    assert np.all(np.isfinite(got))


def test_model_switch_and_its_checks():
    model = model_with_effects(["hysteresis"], {"gap_lag": True}, 100.0)
    assert "gap_lag_time" in [p.name for p in model.parameters()]
    te = model_with_effects(["transmission_error"], {"gap_lag": True}, 100.0)
    assert "gap_lag_time" not in [p.name for p in te.parameters()]  # a constant load crosses no gap
    with pytest.raises(InputError, match=r"\[effects\].gap_lag: expected true or false"):
        model_with_effects(["hysteresis"], {"gap_lag": "yes"}, 100.0)


def test_damped_gap_is_crossed_late_and_the_peaks_are_not():
    t = np.linspace(0.0, 40.0, 4001)
    tau = 50.0 * np.sin(2 * np.pi * t / 20.0)
    data = hysteresis_input(t, tau)
    params = {"stiffness": 1000.0, "friction_torque": 1.0, "dahl_torque": 1.0, "gap": 0.02, "gap_torque": 1.0,
              "angle_offset": jnp.zeros(1)}
    base = model_with_effects(["hysteresis"], {}, 100.0)
    damped = model_with_effects(["hysteresis"], {"gap_lag": True}, 100.0)
    lagged = {**params, "gap_lag_time": 0.5}
    y0 = np.asarray(base.predict(params, [data])[0])
    y1 = np.asarray(damped.predict(lagged, [data])[0])
    second = t > 20.0
    # the peak of the twist stays where it was: the loaded flanks follow the torque at once
    assert abs(t[second][np.argmax(y1[second])] - t[second][np.argmax(y0[second])]) <= 0.02
    # the gap (mid twist) is crossed later, by about the lag, on the falling branch
    mid = 0.5 * (y0.max() + y0.min())
    fall = (t > 25.0) & (t < 35.0)  # from the peak at 25 s through the gap at 30 s
    cross0 = t[fall][np.argmax(y0[fall] < mid)]
    cross1 = t[fall][np.argmax(y1[fall] < mid)]
    assert 0.3 < cross1 - cross0 < 0.7
    # components: the delay is booked as the rate-dependent part and the parts still sum up
    comps = damped.components(lagged, [data])[0]
    np.testing.assert_allclose(np.asarray(comps["total"]), y1, atol=1e-12)
    assert np.max(np.abs(np.asarray(comps["creep"]))) > 0.1 * params["gap"]
