"""benchmarks/pi_reference.py: the Prandtl–Ishlinskii + gap reference fit (NumPy/SciPy, NNLS).

The play operator against a hand-computed sequence, exact recovery of the weights of a SYNTHETIC
PI + tanh curve, and one REAL measured loop (JelmerV/Anti-Backlash-Cycloidal-Actuator,
CC BY-SA 4.0; read from ``<repo>/../shared/data/cycloidal-jv``, skipped when absent).
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("scipy", reason="the PI reference fit needs scipy (not a torsionfit dependency)")

_ROOT = Path(__file__).resolve().parents[1]
_BENCH = _ROOT / "benchmarks"
_spec = importlib.util.spec_from_file_location("_bench_pi_reference", _BENCH / "pi_reference.py")
pi = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = pi  # dataclasses look the module up while the class is created
_spec.loader.exec_module(pi)

_DATA = _ROOT.parent / "shared" / "data" / "cycloidal-jv"


def test_play_operator_hand_computed():
    x = np.array([0.0, 1.0, 3.0, 2.0, 0.0, -1.0, 1.0])
    # r = 1, starting at y0 = x0 = 0: y = clamp(y_prev, x - 1, x + 1)
    #   x=1 -> clamp(0, 0, 2) = 0;  x=3 -> clamp(0, 2, 4) = 2;  x=2 -> clamp(2, 1, 3) = 2
    #   x=0 -> clamp(2, -1, 1) = 1; x=-1 -> clamp(1, -2, 0) = 0; x=1 -> clamp(0, 0, 2) = 0
    np.testing.assert_array_equal(pi.play_operator(x, 1.0), [0, 0, 2, 2, 1, 0, 0])
    # r = 0 is the identity; several thresholds at once give one column each
    out = pi.play_operator(x, [0.0, 1.0, 5.0])
    assert out.shape == (7, 3)
    np.testing.assert_array_equal(out[:, 0], x)
    np.testing.assert_array_equal(out[:, 1], [0, 0, 2, 2, 1, 0, 0])
    np.testing.assert_array_equal(out[:, 2], np.zeros(7))  # r larger than every move: stuck at y0
    # an explicit initial state y0 = 5: x=0 -> clamp(5, -1, 1) = 1; x=1 -> clamp(1, 0, 2) = 1; then as above
    np.testing.assert_array_equal(pi.play_operator(x, 1.0, y0=5.0), [1, 1, 2, 2, 1, 0, 0])
    with pytest.raises(ValueError):
        pi.play_operator(x, -1.0)


def test_nnls_recovers_synthetic_pi_plus_gap():
    """SYNTHETIC data: a torque of growing triangle ramps, angle = known PI + tanh gap + offset."""
    t = np.linspace(0.0, 1.0, 4000)
    torque = 20.0 * t * np.sin(2 * np.pi * 5 * t)  # growing oscillation: minor and major loops
    m = pi.PIReference(median_window=1)  # no filtering: the synthetic torque is noise-free
    X = m.design(torque)
    k = X.shape[1]
    n_play, n_gap = m.n_play, m.n_gap
    w_true = np.zeros(k)
    w_true[0] = 3.0  # linear compliance (r = 0)
    w_true[5] = 1.5  # a +P column
    w_true[n_play + 3] = 0.8  # a -P column: net negative weight, counter-clockwise contribution
    w_true[2 * n_play - 1 + 2] = 40.0  # gap columns
    w_true[2 * n_play - 1 + 3] = 25.0
    w_true[-2] = 7.0  # offset (+ column)
    angle = X @ w_true
    m.fit(torque, angle)
    np.testing.assert_allclose(m.predict(), angle, atol=1e-8 * np.abs(angle).max())
    # the ± pairs are not identifiable individually, the net play weights are
    net = np.zeros(n_play)
    net[0], net[5], net[4] = 3.0, 1.5, -0.8
    np.testing.assert_allclose(m.play_weights, net, atol=1e-8)
    gap = m.weights[2 * n_play - 1 : 2 * n_play - 1 + n_gap]
    np.testing.assert_allclose(gap, [0, 0, 40.0, 25.0, 0, 0], atol=1e-7)
    assert m.weights[-2] - m.weights[-1] == pytest.approx(7.0, abs=1e-8)
    assert np.all(m.weights >= 0)


def test_gap_lag_matches_the_model_lag_and_the_fit_finds_it():
    """SYNTHETIC: the reference's lag is the model's (``first_order_lag``), and a loop whose gap
    columns see a lagged torque is fitted best at that lag, chosen on the fitted rows alone."""
    import jax.numpy as jnp

    from torsionfit.model import first_order_lag

    t = np.linspace(0.0, 20.0, 4001)
    torque = 20.0 * np.sin(2 * np.pi * t / 5.0) + 3.0 * np.sin(2 * np.pi * t / 1.3)
    ours = pi.lag_torque(t, torque, 0.3)
    np.testing.assert_allclose(ours, np.asarray(first_order_lag(jnp.asarray(t), jnp.asarray(torque), 0.3)), atol=1e-9)
    np.testing.assert_array_equal(pi.lag_torque(t, torque, 0.0), torque)
    truth = pi.PIReference(median_window=1, gap_lag_s=0.3)
    fitted_rows = t < 15.0
    X = truth.design(torque, fitted_rows, time_s=t)  # thresholds from the fitted rows, as the fit's
    w = np.zeros(X.shape[1])
    w[0], w[3], w[2 * truth.n_play + 1], w[-2] = 2.0, 1.0, 5.0, 1.0
    angle = X @ w
    fit, lag = pi.PIReference(median_window=1).fit_lagged(t, torque, angle, fitted_rows)
    assert lag == pytest.approx(0.3)
    assert np.sqrt(np.mean((fit.predict() - angle)[~fitted_rows] ** 2)) < 1e-6 * np.abs(angle).max()
    with pytest.raises(ValueError, match="time_s"):
        truth.design(torque)


@pytest.mark.skipif(not _DATA.is_dir(), reason=f"measured data folder {_DATA} is absent (not part of the repository)")
def test_measured_baseline_initial_pos1():
    """REAL measured data (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0)."""
    r = pi.evaluate(_DATA / "baseline-pccf" / "initial-pos1.csv.gz", variants=False)
    # measured 486″ in sample, 518″ out of sample (fit to ramps 100–101); the project's bar 576″ / 624″
    assert 400 < r["in_sample"] < 560
    assert r["oos_large"] < 650
    assert r["last_ramp"] == 102


@pytest.mark.skipif(not _DATA.is_dir(), reason=f"measured data folder {_DATA} is absent (not part of the repository)")
def test_measured_loop_calls_for_negative_play_weights():
    """REAL measured data (CC BY-SA 4.0): the reference's edge over a physical hysteresis model
    is its negative play weights. With weights ≥ 0 (any break-away density: a clockwise loop)
    the same columns fit the large ramps markedly worse (measured 689″ against 486″)."""
    d = pi.read_loop(_DATA / "baseline-pccf" / "initial-pos1.csv.gz")
    large = d["test_nr"] >= 100
    y = d["angle_rad"] - d["angle_rad"].mean()
    signed = pi.PIReference().fit(d["torque_Nm"], y, large)
    physical = pi.PIReference(signed_play=False).fit(d["torque_Nm"], y, large)
    assert np.all(physical.play_weights >= 0)
    assert signed.play_weights.min() < -0.05 * np.abs(signed.play_weights).max()
    rmse = {name: pi.rmse_arcsec(m.predict()[large], y[large]) for name, m in (("signed", signed), ("physical", physical))}
    assert rmse["physical"] > 1.25 * rmse["signed"], rmse


def test_cli_without_data_exits_cleanly(tmp_path, capsys):
    assert pi.main(["--data", str(tmp_path / "missing"), "-o", str(tmp_path / "x.md")]) == 0
    assert "no measured data" in capsys.readouterr().out
    assert not (tmp_path / "x.md").exists()
