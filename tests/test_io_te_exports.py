"""Reading TE bench exports as they are: sign convention, zero groups, no time column, motor
speed, NaN pads, selection before parsing, temperature. The fit of a declared export is in
test_te_exports_e2e.py.

Every export here is SYNTHETIC, written by the tests from the model with known parameters."""

import math
from pathlib import Path

import numpy as np
import pytest

import torsionfit.model as m
from torsionfit import InputError
from torsionfit.io import load_campaign
from torsionfit.metrics._te import te_metrics

ARCMIN = math.pi / 180 / 60
RATIO = 81.0
INPUT_RPM = 486.0  # output 6 rpm
RATE_HZ = 72.0  # 0.5° of output per sample at 6 rpm
TRUTH = dict(stiffness=480.0 / ARCMIN, friction_torque=15.0, dahl_torque=3.0, gap=0.4 * ARCMIN, gap_torque=5.0)
LOADS = (250.0, 500.0, 1000.0)
SHIFTS_ARCMIN = (0.4, -0.3, 0.1)  # each test re-zeroes the encoders
KIN_ARCMIN = 0.15  # kinematic error, order 2, the same in both directions


def _truth_te(loads, shifts, rng, noise_arcmin=0.02):
    """Lag-positive TE (rad) of forward and backward revolutions per load: (φ_fw, te_fw, φ_bw, te_bw)."""
    phi = np.deg2rad(np.arange(0.0, 360.25, 0.5))  # 721 samples, both ends
    inputs, kinds = [], []
    for g, load in enumerate(loads):
        for d, angles in ((1, phi), (-1, phi[::-1])):
            inputs.append(m.te_input(angles, load, INPUT_RPM / RATIO, d, zero_group=g))
            kinds.append("transmission_error")
    model = m.CampaignModel(run_kinds=tuple(kinds), te_zero_groups=len(loads))
    params = {k: np.asarray(v) for k, v in TRUTH.items()}
    params["te_offset"] = np.asarray(shifts) * ARCMIN
    out = []
    for g in range(len(loads)):
        pair = []
        for j in (0, 1):
            inp = inputs[2 * g + j]
            te = np.asarray(model.te_components(params, inp, 2 * g + j)["total"])
            angle = np.asarray(inp.output_angle_rad)
            te = te + KIN_ARCMIN * ARCMIN * np.sin(2 * angle) + rng.normal(0, noise_arcmin * ARCMIN, angle.size)
            pair += [angle, te]
        out.append(pair)
    return out


def _write_export(path: Path, phi_fw, te_fw, phi_bw, te_bw):
    """SYNTHETIC side-by-side export: fw and bw columns, degrees, TE lag-negative, no time
    column, the backward revolution one sample shorter and padded with NaN."""
    phi_bw, te_bw = phi_bw[:-1], te_bw[:-1]
    rows = ["# SYNTHETIC TE export (torsionfit tests)", "Pos_fw;TE_fw;Pos_bw;TE_bw"]
    for i in range(len(phi_fw)):
        bw = (f"{np.rad2deg(phi_bw[i]):.12g};{-np.rad2deg(te_bw[i]):.12g}" if i < len(phi_bw) else "NaN;NaN")
        rows.append(f"{np.rad2deg(phi_fw[i]):.12g};{-np.rad2deg(te_fw[i]):.12g};{bw}")
    path.write_text("\n".join(rows) + "\n")


def _manifest(folder: Path, files, *, convention: str | None = "lag_negative", groups=True, extra_run="", instrument=""):
    lines = ["label = \"SYNTHETIC TE bench export\"", "[reducer]", "name = \"rv-synthetic\"",
             f"ratio = {RATIO}", "rated_torque_Nm = 1000.0", "[instrument]", f"sample_rate_Hz = {RATE_HZ}"]
    if convention:
        lines.append(f"te_convention = \"{convention}\"")
    lines.append(instrument)
    for file, load in files:
        for way, tag in (("forward", "fw"), ("backward", "bw")):
            lines += ["[[runs]]", f"name = \"{Path(file).stem}-{tag}\"", "kind = \"transmission_error\"",
                      f"file = \"{file}\"", f"input_speed_rpm = {INPUT_RPM}", f"torque_Nm = {load}",
                      f"direction = \"{way}\"", "temperature_C = 40.0", extra_run]
            if groups:
                lines.append(f"zero_group = \"{Path(file).stem}\"")
            lines += ["[runs.columns]", f"output_angle = \"Pos_{tag}\"", f"te = \"TE_{tag}\"",
                      "[runs.units]", "output_angle = \"deg\"", "te = \"deg\""]
    (folder / "campaign.toml").write_text("\n".join(lines) + "\n")
    return folder / "campaign.toml"


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    folder = tmp_path_factory.mktemp("te_export")
    rng = np.random.default_rng(18)
    files = []
    for load, pair in zip(LOADS, _truth_te(LOADS, SHIFTS_ARCMIN, rng)):
        name = f"test_{int(load)}Nm.csv"
        _write_export(folder / name, *pair)
        files.append((name, load))
    return folder, files


def test_export_read_as_it_is(export):
    folder, files = export
    campaign = load_campaign(_manifest(folder, files))
    fw, bw = campaign.runs[0], campaign.runs[1]
    assert len(fw) == 721 and len(bw) == 720  # the NaN pad row dropped
    assert any("dropped 1 trailing row" in n for n in bw.notes) and not any("dropped" in n for n in fw.notes)
    assert fw.speed_rpm == pytest.approx(INPUT_RPM / RATIO)
    np.testing.assert_allclose(fw.time_s[:3], np.arange(3) / RATE_HZ)
    # lag_negative negated: a forward run under load lies above its backward partner
    assert np.mean(fw.te_rad) > np.mean(bw.te_rad) + 2 * 250.0 / TRUTH["stiffness"]
    assert campaign.te_zero_groups == ("test_250Nm", "test_500Nm", "test_1000Nm")
    assert campaign.te_zero_index(campaign.runs[5]) == 2
    assert fw.nominal_temperature_C == 40.0 and fw.te_convention == "lag_negative"
    # the note reaches the data-only metrics
    assert "dropped 1 trailing row" in te_metrics(bw)["te_mean"]["note"]


def test_undeclared_convention_stops_with_one_line(export):
    folder, files = export
    for groups in (True, False):
        with pytest.raises(InputError, match="te_convention") as err:
            load_campaign(_manifest(folder, files, convention=None, groups=groups))
        assert "\n" not in str(err.value) and "test_250Nm.csv" in str(err.value)


def test_per_run_convention_overrides_instrument(export):
    folder, files = export
    # instrument says lag_positive, every run says lag_negative: reads like the declared export
    path = _manifest(folder, files, convention="lag_positive", extra_run="te_convention = \"lag_negative\"")
    assert all(r.te_convention == "lag_negative" for r in load_campaign(path).runs)
    with pytest.raises(InputError, match="te_convention must be 'lag_positive'"):
        load_campaign(_manifest(folder, files, convention="negative"))


def test_check_quiet_on_noisy_lag_positive_data(tmp_path):
    """Correct data with noise far above the twist differences, kinematic error and no-load
    runs: nothing is clear, nothing fires; and the clear case agrees."""
    rng = np.random.default_rng(1)
    loads = (0.0, 5.0)
    for name, load, pair in zip(("a.csv", "b.csv"), loads, _truth_te(loads, (0.0, 0.0), rng, noise_arcmin=0.5)):
        phi_fw, te_fw, phi_bw, te_bw = pair
        _write_export(tmp_path / name, phi_fw, -te_fw, phi_bw, -te_bw)  # written lag-positive
    files = [("a.csv", 0.0), ("b.csv", 5.0)]
    campaign = load_campaign(_manifest(tmp_path, files, convention="lag_positive", groups=False))
    assert len(campaign.te_runs) == 4


def test_same_direction_load_order_checked(tmp_path):
    """Forward runs only, one zero: mean TE falling with load contradicts lag_positive."""
    rng = np.random.default_rng(2)
    pairs = _truth_te(LOADS, (0.0, 0.0, 0.0), rng)
    rows = ["# SYNTHETIC", "angle_deg,te_arcmin"]
    for load, (phi, te, _, _) in zip(LOADS, pairs):
        text = "\n".join(f"{np.rad2deg(a):.12g},{-t / ARCMIN:.12g}" for a, t in zip(phi, te))
        (tmp_path / f"f{int(load)}.csv").write_text("# SYNTHETIC\noutput_angle_deg,te_arcmin\n" + text + "\n")
    runs = "".join(
        f"[[runs]]\nname = \"f{int(l)}\"\nkind = \"transmission_error\"\nfile = \"f{int(l)}.csv\"\n"
        f"speed_rpm = 6.0\ntorque_Nm = {l}\ndirection = \"forward\"\n" for l in LOADS)
    head = "[reducer]\nname = \"x\"\n"
    (tmp_path / "campaign.toml").write_text(head + runs)
    with pytest.raises(InputError, match="te_convention.*f250.csv"):
        load_campaign(tmp_path)
    (tmp_path / "campaign.toml").write_text(head + "[instrument]\nte_convention = \"lag_negative\"\n" + runs)
    campaign = load_campaign(tmp_path)
    assert campaign.runs[0].time_s is None  # no time column, no sample rate: timed by speed in the model


def _small_te(tmp_path, rows, name="t.csv", keys="speed_rpm = 6.0", select="", reducer=""):
    (tmp_path / name).write_text("# SYNTHETIC\n" + "\n".join(rows) + "\n")
    (tmp_path / "campaign.toml").write_text(
        f"[reducer]\nname = \"x\"\n{reducer}\n[[runs]]\nname = \"r\"\nkind = \"transmission_error\"\n"
        f"file = \"{name}\"\n{keys}\ntorque_Nm = 10.0\ndirection = \"forward\"\n{select}")
    return tmp_path / "campaign.toml"


def _rows(n=73, inside_nan=None, pad=0):
    out = ["output_angle_deg,te_arcmin,test_nr"]
    for i in range(n):
        te = "NaN" if i == inside_nan else "0.5"
        out.append(f"{i * 5.0},{te},1")
    out += ["NaN,NaN,1"] * pad
    return out


def test_nan_inside_data_is_an_error_naming_file_column_line(tmp_path):
    with pytest.raises(InputError, match=r"t\.csv.*column 'te_arcmin' line 13: expected a finite number"):
        load_campaign(_small_te(tmp_path, _rows(inside_nan=10)))
    assert len(load_campaign(_small_te(tmp_path, _rows(pad=2))).runs[0]) == 73


def test_select_filters_before_numbers_are_checked(tmp_path):
    rows = _rows() + ["NaN,NaN,NaN"] + ["999,junk,2"]
    select = "[runs.select]\ntest_nr = [1]\n"
    run = load_campaign(_small_te(tmp_path, rows, select=select)).runs[0]
    assert len(run) == 73 and run.notes == ()


def test_speed_keys(tmp_path):
    with pytest.raises(InputError, match="input_speed_rpm needs \\[reducer\\] ratio"):
        load_campaign(_small_te(tmp_path, _rows(), keys="input_speed_rpm = 600.0"))
    with pytest.raises(InputError, match="give one of speed_rpm .* got both"):
        load_campaign(_small_te(tmp_path, _rows(), keys="input_speed_rpm = 600.0\nspeed_rpm = 6.0", reducer="ratio = 100.0"))
    with pytest.raises(InputError, match="got neither"):
        load_campaign(_small_te(tmp_path, _rows(), keys=""))
    run = load_campaign(_small_te(tmp_path, _rows(), keys="input_speed_rpm = 600.0", reducer="ratio = 100.0")).runs[0]
    assert run.speed_rpm == 6.0
