"""benchmarks/repeat_reference.py: the earlier ramps' own twist as a predictor of a later ramp.

Branch splitting on a hand-made torque, exact prediction of a SYNTHETIC loop that repeats
itself, an injected ramp-to-ramp walk recovered as its error, and one REAL measured loop
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0; read from
``<repo>/../shared/data/cycloidal-jv``, skipped when absent).
"""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("scipy", reason="the reference scripts need scipy (not a torsionfit dependency)")

_ROOT = Path(__file__).resolve().parents[1]
_BENCH = _ROOT / "benchmarks"
sys.path.insert(0, str(_BENCH))  # repeat_reference imports pi_reference's torque filter
_spec = importlib.util.spec_from_file_location("_bench_repeat_reference", _BENCH / "repeat_reference.py")
rr = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rr)

_DATA = _ROOT.parent / "shared" / "data" / "cycloidal-jv"


def test_branches_split_at_reversals_not_at_ripple():
    # 0 → 10 → −10 → 0 with a 0.5 ripple (below 10 % of the 20 range) on the way up
    up = np.concatenate([np.linspace(0, 5, 20), np.linspace(5, 4.5, 3), np.linspace(4.5, 10, 20)])
    torque = np.concatenate([up, np.linspace(10, -10, 40)[1:], np.linspace(-10, 0, 20)[1:]])
    b = rr.branches(torque)
    assert list(np.unique(b)) == [0, 1, 2]
    assert b[np.argmax(torque)] == 0 and b[np.argmax(torque) + 1] == 1  # the peak ends branch 0
    assert b[np.argmin(torque)] == 1 and b[-1] == 2


def _ramp_programme(n_ramps: int, per_branch: int = 200):
    """SYNTHETIC torque programme: one cycle, then n_ramps more of 0 → +40 → −40 → 0 N·m,
    test_nr 5, 100, 101, …"""
    one = np.concatenate([np.linspace(0, 40, per_branch), np.linspace(40, -40, 2 * per_branch)[1:],
                          np.linspace(-40, 0, per_branch)[1:]])
    # a first cycle numbered like a play ramp (not a large one): every large ramp then starts
    # from the state the cycle before it left, as in the measured files
    torque = np.tile(one, n_ramps + 1)
    nr = np.repeat(np.r_[5, 100 + np.arange(n_ramps)], one.size)
    return torque, nr


def _play(x, r):
    y, out = x[0], np.empty_like(x)
    for i, v in enumerate(x):
        y = min(max(y, v - r), v + r)
        out[i] = y
    return out


def test_a_loop_that_repeats_itself_is_predicted_exactly_and_a_walk_is_its_error():
    torque, nr = _ramp_programme(3)
    # SYNTHETIC stationary hysteresis: compliance + a play operator, the same on every ramp
    angle = 1e-3 * torque + 2e-3 * _play(torque, 8.0)
    loop = {"torque_Nm": torque, "angle_rad": angle, "test_nr": nr}
    pred = rr.held_out_prediction(loop)
    held = nr == 102
    assert np.all(np.isnan(pred[~held]))
    ok = np.isfinite(pred[held])
    assert ok.mean() > 0.99
    # the running-median filter leaves the torque's linear ramps as they are but flattens the
    # peaks (by < 1 N·m here, at a slope of 3e-3 rad/N·m)
    np.testing.assert_allclose(pred[held][ok], angle[held][ok], atol=3e-3)
    interior = held & (np.abs(torque) < 35)
    np.testing.assert_allclose(pred[interior], angle[interior], atol=1e-9)
    # a walk: the last ramp's twist 0.01 rad higher on the + side → the prediction misses by it
    walked = angle + np.where(held & (torque > 0), 0.01, 0.0)
    pred_w = rr.held_out_prediction({**loop, "angle_rad": walked})
    err = (walked - pred_w)[interior]
    np.testing.assert_allclose(err[torque[interior] > 0], 0.01, atol=1e-9)
    np.testing.assert_allclose(err[torque[interior] < 0], 0.0, atol=1e-9)


def test_a_file_without_earlier_large_ramps_is_refused():
    torque, nr = _ramp_programme(1)
    with pytest.raises(ValueError, match="no large ramp"):
        rr.held_out_prediction({"torque_Nm": torque, "angle_rad": torque * 1e-3, "test_nr": nr})


@pytest.mark.skipif(not _DATA.is_dir(), reason=f"measured data not found at {_DATA} (../shared/data is not part of this repository)")
def test_measured_loop_repeats_better_than_it_walks():
    """REAL data (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0): on split
    reassembled-pos6 the earlier ramps predict the last one within a few hundred arcsec on
    every sample they cover: far below the loop's own width."""
    import pi_reference

    loop = pi_reference.read_loop(_DATA / "split-pccf" / "reassembled-pos6.csv.gz")
    pred = rr.held_out_prediction(loop)
    held = loop["test_nr"] == loop["test_nr"].max()
    err = (pred - loop["angle_rad"])[held]
    assert np.mean(np.isfinite(err)) > 0.95
    rmse_arcsec = np.sqrt(np.nanmean(err**2)) / (np.pi / 180 / 3600)
    width_arcsec = np.ptp(loop["angle_rad"][held]) / (np.pi / 180 / 3600)
    assert rmse_arcsec < 0.02 * width_arcsec
