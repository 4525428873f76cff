"""scripts/measured_held_out_error.py: the held-out error split at the gap crossings (SYNTHETIC
records here; the measured predictions are never in the repository)."""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("_held_out_error", ROOT / "scripts" / "measured_held_out_error.py")
he = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(he)


def _ramp_record(cross_data_Nm=2.0, cross_model_Nm=2.0, gap_rad=0.05, n=1200):
    """SYNTHETIC held-out ramp 0 → +20 → −20 → 0 N·m: twist = compliance·τ ± gap/2, the gap
    crossed in a tanh 0.1 N·m wide at +c on rising and −c on falling branches."""
    t = np.linspace(0.0, 1.0, n)
    tau = np.interp(t, [0, 0.25, 0.75, 1.0], [0.0, 20.0, -20.0, 0.0])
    rising = np.gradient(tau) > 0

    def twist(c):
        side = np.where(rising, np.tanh((tau - c) / 0.1), np.tanh((tau + c) / 0.1))
        return 0.001 * tau + 0.5 * gap_rad * side

    y, pred = twist(cross_data_Nm), twist(cross_model_Nm)
    return {"time_s": t, "torque_Nm": tau, "angle_rad": y, "test_nr": np.full(n, 102),
            "prediction_rad": pred[None, :]}


def test_the_crossing_is_found_where_the_twist_jumps():
    rec = _ramp_record(cross_data_Nm=2.0, cross_model_Nm=3.5)
    r = he.anatomy(rec)
    assert r["crossing_branches"] == 2  # 0 → +20 and +20 → −20; −20 → 0 never reaches the + crossing
    assert r["crossing_data_falling_Nm"] == pytest.approx(-2.0, abs=0.3)
    assert r["crossing_model_falling_Nm"] == pytest.approx(-3.5, abs=0.3)
    assert r["crossing_data_rising_Nm"] == pytest.approx(2.0, abs=0.3)
    assert r["jump_data_deg"] == pytest.approx(np.rad2deg(0.05), rel=0.1)
    # the error lies between the two crossings: at the crossings most of it, elsewhere none
    assert r["share_squared_error"] > 0.99
    assert r["rmse_elsewhere_arcsec"] < 1.0
    assert 0 < r["share_samples"] < 0.2


def test_a_model_that_crosses_with_the_data_leaves_no_error_at_the_crossing():
    r = he.anatomy(_ramp_record(cross_data_Nm=2.0, cross_model_Nm=2.0))
    assert r["rmse_held_out_arcsec"] < 1e-6
    assert np.isnan(r["share_squared_error"])  # no error to share, not a division by zero


def test_the_reference_is_scored_in_the_same_windows():
    rec = _ramp_record(cross_data_Nm=2.0, cross_model_Nm=3.5)
    late = _ramp_record(cross_data_Nm=4.0)["angle_rad"]  # a reference crossing later still
    r = he.anatomy(rec, reference_rad=late)
    assert r["reference_rmse_crossing_arcsec"] > r["rmse_crossing_arcsec"] > 0
    assert r["reference_rmse_elsewhere_arcsec"] < 1.0


def test_a_branch_without_a_jump_is_not_a_crossing():
    rec = _ramp_record(gap_rad=0.0)
    assert np.isnan(he.crossing(rec["torque_Nm"][:300], rec["angle_rad"][:300], 1)[0])
    assert he.anatomy(rec)["crossing_branches"] == 0


def test_a_folder_without_predictions_stops_with_one_line(tmp_path, capsys):
    assert he.main([str(tmp_path), "--no-reference"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(tmp_path) in err[0] and "--save-predictions" in err[0]


def test_a_file_missing_a_key_is_named(tmp_path, capsys):
    rec = _ramp_record()
    del rec["prediction_rad"]
    np.savez(tmp_path / "unit.npz", **rec)
    assert he.main([str(tmp_path), "--no-reference"]) == 2
    err = capsys.readouterr().err.strip()
    assert "unit.npz" in err and "prediction_rad" in err


def test_the_table_is_written(tmp_path):
    np.savez(tmp_path / "synthetic-unit.npz", **_ramp_record(cross_model_Nm=3.0))
    out = tmp_path / "t.md"
    assert he.main([str(tmp_path), "--no-reference", "-o", str(out)]) == 0
    text = out.read_text()
    assert "| synthetic-unit |" in text and "squared error at the crossing" in text


def _asymmetric_ramps(data=(2.0, -1.0), model=(1.5, -1.5), n=1200):
    """SYNTHETIC file of two large ramps (test_nr 100, 101), each 0 → +20 → −20 → 0 N·m; the gap
    crossed at ``data`` (rising, falling torque) in the data and at ``model`` in the prediction."""
    t = np.linspace(0.0, 1.0, n)
    tau = np.interp(t, [0, 0.25, 0.75, 1.0], [0.0, 20.0, -20.0, 0.0])
    rising = np.gradient(tau) > 0

    def twist(rise, fall):
        side = np.where(rising, np.tanh((tau - rise) / 0.1), np.tanh((tau - fall) / 0.1))
        return 0.001 * tau + 0.025 * side

    y, pred = np.tile(twist(*data), 2), np.tile(twist(*model), 2)
    return {"time_s": np.concatenate([t, t + 1.0]), "torque_Nm": np.tile(tau, 2), "angle_rad": y,
            "test_nr": np.repeat([100, 101], n), "prediction_rad": pred[None, :]}


def test_the_crossings_of_every_large_ramp_give_their_centre_and_the_models_offset():
    c = he.ramp_crossings(_asymmetric_ramps())
    assert c["data_rising_Nm"] == pytest.approx([2.0, 2.0], abs=0.3)
    assert c["data_falling_Nm"] == pytest.approx([-1.0, -1.0], abs=0.3)
    assert c["centre_data_Nm"] == pytest.approx(0.5, abs=0.15)
    assert c["centre_model_Nm"] == pytest.approx(0.0, abs=0.15)
    # the fitted ramp (100; 101 is the held-out one): |1.5 − 2.0| and |−1.5 + 1.0|
    assert c["fitted_offset_model_minus_data_Nm"] == pytest.approx(0.5, abs=0.2)
    same = he.ramp_crossings(_asymmetric_ramps(model=(2.0, -1.0)))
    assert same["fitted_offset_model_minus_data_Nm"] == pytest.approx(0.0, abs=0.1)


def test_the_play_and_the_large_ramps_are_crossed_about_centres_of_their_own():
    """class_crossings: a file of a ±4 N·m play ramp (test_nr 0) crossed about +0.5 N·m and two
    large ramps crossed about −0.5 N·m gives each class its centre, in the data and the model
    (which here crosses both about zero); the table names the shift."""
    play = _ramp_record()
    n = play["torque_Nm"].size
    play["torque_Nm"] = play["torque_Nm"] / 5.0  # ±4 N·m
    rising = np.gradient(play["torque_Nm"]) > 0
    tau = play["torque_Nm"]

    def twist(rise, fall):
        return 0.001 * tau + 0.025 * np.where(rising, np.tanh((tau - rise) / 0.05), np.tanh((tau - fall) / 0.05))

    large = _asymmetric_ramps(data=(1.0, -2.0), model=(1.5, -1.5))
    saved = {
        "time_s": np.concatenate([play["time_s"] - 1.0, large["time_s"]]),
        "torque_Nm": np.concatenate([tau, large["torque_Nm"]]),
        "angle_rad": np.concatenate([twist(2.0, -1.0), large["angle_rad"]]),
        "test_nr": np.concatenate([np.zeros(n, int), large["test_nr"]]),
        "prediction_rad": np.concatenate([twist(1.5, -1.5), large["prediction_rad"][0]])[None, :],
    }
    c = he.class_crossings(saved)
    assert c["play_data"]["centre_Nm"] == pytest.approx(0.5, abs=0.15)
    assert c["large_data"]["centre_Nm"] == pytest.approx(-0.5, abs=0.15)
    assert c["play_model"]["centre_Nm"] == pytest.approx(0.0, abs=0.15)
    assert c["large_model"]["centre_Nm"] == pytest.approx(0.0, abs=0.15)
    text = he.markdown({"synthetic-unit": {**he.anatomy(saved), "classes": c}})
    assert "moves from the play ramps to the large ramps by more than 0.5 N·m on 1" in text


def _interval_record(move):
    """SYNTHETIC held-out ramp whose data are the model's prediction plus ``move`` (rad, per
    sample): 200 draws shifted by 1e-4 rad (sd) and a noise sd of 1e-4 rad, the data scattered
    by both (√2 · 1e-4 rad), so that the interval is calibrated where ``move`` is 0."""
    rec = _ramp_record(cross_data_Nm=2.0, cross_model_Nm=2.0)
    rng = np.random.default_rng(1)
    model = rec["angle_rad"]
    rec["prediction_rad"] = model[None] + 1e-4 * rng.standard_normal((200, 1))
    rec["noise_marginal_rad"] = np.float64(1e-4)
    rec["angle_rad"] = model + move + np.sqrt(2) * 1e-4 * rng.standard_normal(model.size)
    return rec


def test_a_ramp_moved_as_a_whole_is_covered_once_its_offsets_are_removed():
    n = _ramp_record()["angle_rad"].size
    o = he.offsets(_interval_record(np.full(n, 1e-3)))  # 10 predictive sds off, every branch alike
    assert o["coverage90"] < 0.05
    assert 0.8 <= o["coverage90_offsets_removed"] <= 0.95
    assert o["offset_share_squared_error"] > 0.95
    assert o["offset_rms_arcsec"] == pytest.approx(1e-3 * he.ARCSEC, rel=0.05)


def test_a_ramp_whose_shape_moved_is_not_covered_with_its_offsets_removed():
    tau = _ramp_record()["torque_Nm"]
    o = he.offsets(_interval_record(1e-4 * tau))  # a compliance change: the error grows with |τ|
    assert o["coverage90"] < 0.5
    assert o["coverage90_offsets_removed"] < 0.5
    assert o["offset_share_squared_error"] < 0.5
