"""scripts/measured_play_edges.py: what the play ramps give back after each peak, per side
(SYNTHETIC records here; the measured predictions are never in the repository)."""

import importlib.util
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("_play_edges", ROOT / "scripts" / "measured_play_edges.py")
pe = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(pe)


def _play_ramps(compliance_plus, compliance_minus, cycles=5, per_half=40):
    """SYNTHETIC ±4 N·m triangle (play ramps), twist = c± · τ on either side of zero torque."""
    corners = np.tile([4.0, -4.0], cycles)
    tau = np.concatenate([np.linspace(a, b, per_half, endpoint=False) for a, b in zip(np.r_[0.0, corners[:-1]], corners)])
    return tau, np.where(tau > 0, compliance_plus, compliance_minus) * tau


def test_the_give_back_of_each_side_is_its_own_compliance_times_the_peaks_torque():
    tau, twist = _play_ramps(0.10, 0.04)
    drop, rise, peak_to_peak, n = pe.give_back_deg(tau, twist)
    assert n >= 8
    # both read from the peak region's end (the smoothed torque at 85 % of the peak) to zero torque
    assert abs(drop / rise - 2.5) < 0.05
    assert 0.3 < drop < 0.4 and abs(peak_to_peak - (drop + rise)) < 0.05 * peak_to_peak


def test_a_model_giving_back_less_after_the_peak_reads_a_wider_play(tmp_path):
    """The table's sum: the model's play minus the data's is its peak-to-peak twist minus the
    data's plus (data − model) of what each side gives back."""
    tau, data = _play_ramps(0.10, 0.04)
    _, model = _play_ramps(0.05, 0.04)
    np.savez(tmp_path / "unit.npz", torque_Nm=tau, angle_rad=np.radians(data), test_nr=np.zeros(len(tau)),
             prediction_rad=np.radians(model)[None, :])
    row = pe.loop_row(tmp_path / "unit.npz")
    # the zero-torque reading averages three samples, one of them on the other side of zero
    assert row["data"][0] > 1.9 * row["model"][0] and abs(row["data"][1] - row["model"][1]) < 0.01
    text = pe.markdown([row])
    assert "outside the model's 5–95 % range on one side or both on 1 of 1 loops" in text


def test_a_folder_without_predictions_is_one_line(tmp_path, capsys):
    assert pe.main([str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--save-predictions" in err
