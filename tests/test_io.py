"""Campaign files (DESIGN §5.1): manifest + CSV runs, one-line errors, round trip, examples."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.io import (
    Campaign,
    HysteresisRun,
    Instrument,
    Reducer,
    TransmissionErrorRun,
    load_campaign,
    write_campaign,
)

ARCMIN = math.pi / (180 * 60)
ARCSEC = ARCMIN / 60
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "cycloidal-jv"

REDUCER = """
[reducer]
name = "unit-1"
rated_torque_Nm = 100.0
ratio = 50.0
"""


# ----------------------------------------------------------------------------- builders


def csv_text(header, columns, label="# SYNTHETIC test data") -> str:
    """CSV text: an optional comment line, a header and the columns' values."""
    rows = [",".join(repr(float(v)) for v in row) for row in zip(*columns)]
    return "\n".join(([label] if label else []) + [",".join(header)] + rows) + "\n"


def hyst_csv(n=40, peak=100.0, header=("time_s", "torque_Nm", "angle_arcmin")) -> str:
    """One sine load cycle to ±peak over 8 s; angle = torque / 20 (in the header's unit)."""
    t = np.linspace(0.0, 8.0, n)
    torque = peak * np.sin(2 * np.pi * t / 8.0)
    return csv_text(header, [t, torque, torque / 20.0])


def te_csv(n=73, turns=1.0, header=("output_angle_deg", "te_arcsec")) -> str:
    """Output angle over ``turns`` revolutions (degrees) and a twice-per-turn TE (arcsec)."""
    out = np.linspace(0.0, 360.0 * turns, n)
    return csv_text(header, [out, 30.0 * np.sin(2 * np.radians(out))])


def toml_pairs(**keys) -> str:
    return "".join(
        f"{k} = {v!r}\n".replace("'", '"') if isinstance(v, str) else f"{k} = {v}\n"
        for k, v in keys.items()
    )


def hyst_run(name="h1", file="h.csv", tail="", **keys) -> str:
    return "\n[[runs]]\n" + toml_pairs(name=name, kind="hysteresis", file=file, **keys) + tail


def te_run(name="te1", file="te.csv", tail="", **keys) -> str:
    keys = {"speed_rpm": 5.0, "torque_Nm": 100.0, "direction": "forward", **keys}
    pairs = toml_pairs(name=name, kind="transmission_error", file=file, **keys)
    return "\n[[runs]]\n" + pairs + tail


def manifest(*runs, reducer=REDUCER, head="") -> str:
    return head + reducer + "".join(runs)


def load_error(path) -> str:
    """The message of the InputError that loading ``path`` raises; checks it is one line."""
    with pytest.raises(InputError) as info:
        load_campaign(path)
    message = str(info.value)
    assert "\n" not in message and message.strip() == message
    return message


# ----------------------------------------------------------------------------- reading


def test_load_hysteresis_and_te_in_si(write_files):
    path = write_files(
        {
            "campaign.toml": manifest(
                hyst_run(loading_rate_Nm_per_s=25.0),
                te_run(direction="backward", speed_rpm=2.5, torque_Nm=50.0),
                head='label = "SYNTHETIC: made for a test"\n',
                reducer=REDUCER
                + "max_speed_rpm = 70.0\n[instrument]\nencoder_resolution_arcsec = 1.0\n",
            ),
            "h.csv": hyst_csv(),
            "te.csv": te_csv(),
        }
    )
    campaign = load_campaign(path)
    assert isinstance(campaign, Campaign)
    assert campaign.notes == "SYNTHETIC: made for a test"
    assert campaign.path == path.resolve()
    assert campaign.reducer == Reducer("unit-1", 100.0, ratio=50.0, max_speed_rpm=70.0)
    assert campaign.instrument.encoder_resolution_arcsec == 1.0
    assert campaign.instrument.torque_full_scale_Nm is None
    (h,) = campaign.hysteresis_runs
    (te,) = campaign.te_runs
    assert isinstance(h, HysteresisRun) and isinstance(te, TransmissionErrorRun)
    assert len(h) == 40 and h.loading_rate_Nm_per_s == 25.0 and h.peak_torque_Nm is None
    np.testing.assert_allclose(h.angle_rad, h.torque_Nm / 20.0 * ARCMIN)
    assert h.time_s[-1] == 8.0 and h.temperature_C is None
    assert (te.direction, te.speed_rpm, te.torque_Nm) == (-1, 2.5, 50.0)
    assert te.output_angle_rad[-1] == pytest.approx(2 * math.pi)
    np.testing.assert_allclose(te.te_rad, 30.0 * np.sin(2 * te.output_angle_rad) * ARCSEC)
    assert te.time_s is None and te.torque_series_Nm is None
    assert h.source.endswith("h.csv")


def test_folder_path_reads_campaign_toml(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": hyst_csv()})
    assert load_campaign(path.parent).runs[0].name == "h1"


def test_te_from_input_angle_and_ratio_with_optional_columns(write_files):
    out = np.linspace(0.0, 360.0, 50)
    te_true = 20.0 * np.sin(np.radians(out))  # arcsec
    input_deg = 50.0 * (out - te_true / 3600.0)
    text = csv_text(
        ("output_angle_deg", "input_angle_deg", "time_ms", "torque_kNm", "temperature_C"),
        [out, input_deg, np.arange(50) * 100.0, np.full(50, 0.1), np.full(50, 25.0)],
    )
    path = write_files({"campaign.toml": manifest(te_run()), "te.csv": text})
    (te,) = load_campaign(path).runs
    np.testing.assert_allclose(te.te_rad / ARCSEC, te_true, atol=1e-6)
    np.testing.assert_allclose(te.time_s[-1], 4.9)
    np.testing.assert_allclose(te.torque_series_Nm, 100.0)
    np.testing.assert_allclose(te.temperature_C, 25.0)


def test_mapped_columns_units_select_and_gzip(write_files):
    """A raw bench export read as it is: own column names, rev angles, rows selected."""
    n = 30
    t = np.repeat(np.arange(n // 3) * 0.5, 3)  # quantised time, as on real benches
    torque = 100.0 * np.sin(np.linspace(0, 2 * np.pi, n))
    test_nr = np.r_[np.zeros(10), np.full(n - 10, 100.0)]
    text = csv_text(
        ("TIME", "POSITION", "TORQUE", "test_nr"), [t, torque / 3600.0, torque, test_nr]
    )
    tail = (
        '[runs.columns]\ntime = "TIME"\ntorque = "TORQUE"\nangle = "POSITION"\n'
        '[runs.units]\nangle = "rev"\n[runs.select]\ntest_nr = [100, 101]\n'
    )
    path = write_files(
        {
            "campaign.toml": manifest(hyst_run(file="raw/bench.csv.gz", tail=tail)),
            "raw/bench.csv.gz": text,
        }
    )
    (h,) = load_campaign(path).runs
    assert len(h) == n - 10
    np.testing.assert_allclose(h.angle_rad, torque[10:] / 3600.0 * 2 * math.pi)
    np.testing.assert_array_equal(h.time_s, t[10:])


def test_mapped_column_without_unit_is_si_and_range_select(write_files):
    t = np.linspace(0, 1, 40)
    torque = 100.0 * np.sin(2 * np.pi * t)
    text = csv_text(("t", "tau", "phi", "step"), [t, torque, torque * 1e-5, np.arange(40.0)])
    tail = (
        '[runs.columns]\ntime = "t"\ntorque = "tau"\nangle = "phi"\n'
        "[runs.select]\nstep = {min = 5, max = 34}\n"
    )
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": text})
    (h,) = load_campaign(path).runs
    assert len(h) == 30
    np.testing.assert_allclose(h.angle_rad, torque[5:35] * 1e-5)  # rad, no conversion


def test_select_on_text_values(write_files):
    t = np.linspace(0, 1, 24)
    torque = 100.0 * np.sin(2 * np.pi * t)
    lines = ["time_s,torque_Nm,angle_rad,phase"] + [
        f"{a!r},{b!r},{b * 1e-5!r},{'ramp' if i < 20 else 'hold'}"
        for i, (a, b) in enumerate(zip(t.tolist(), torque.tolist()))
    ]
    tail = '[runs.select]\nphase = ["ramp"]\n'
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": "\n".join(lines)})
    assert len(load_campaign(path).runs[0]) == 20


def test_duplicate_time_stamps_are_kept(write_files):
    """Benches quantise time: several rows share one stamp. Every row stays, time as given."""
    t = np.repeat(np.arange(10) * 0.0156, 4)
    torque = 100.0 * np.sin(np.linspace(0, 2 * np.pi, 40))
    path = write_files(
        {
            "campaign.toml": manifest(hyst_run()),
            "h.csv": csv_text(("time_s", "torque_Nm", "angle_arcmin"), [t, torque, torque / 20]),
        }
    )
    (h,) = load_campaign(path).runs
    assert len(h) == 40
    np.testing.assert_array_equal(h.time_s, t)
    assert np.all(np.diff(h.time_s) >= 0) and np.sum(np.diff(h.time_s) == 0) == 30


def test_comments_blank_lines_and_semicolons(write_files):
    body = hyst_csv().replace(",", ";").splitlines()
    text = "# label line\n\n" + "\n".join(body[1:3] + ["# a comment in the middle", ""] + body[3:])
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": text})
    assert len(load_campaign(path).runs[0]) == 40


def test_reducer_name_defaults_to_manifest_stem(write_files):
    reducer = "[reducer]\nrated_torque_Nm = 100.0\n"
    files = {"campaign.toml": manifest(hyst_run(), reducer=reducer), "h.csv": hyst_csv()}
    path = write_files(files)
    assert load_campaign(path).reducer.name == "campaign"


def test_peak_torque_allows_a_partial_load_run(write_files):
    path = write_files(
        {"campaign.toml": manifest(hyst_run(peak_torque_Nm=30.0)), "h.csv": hyst_csv(peak=30.0)}
    )
    assert load_campaign(path).runs[0].peak_torque_Nm == 30.0


def test_peak_torque_from_the_data_declares_a_partial_load_run_without_a_guess(write_files, tmp_path):
    """``peak_torque_Nm = "data"``: play ramps far below the rated torque load, their loop
    metrics at the loop's own peak, with a note that the torque unit went unchecked; a written
    manifest keeps the declaration."""
    from torsionfit.metrics import campaign_metrics

    t = np.linspace(0.0, 24.0, 600)
    torque = 30.0 * np.sin(2 * np.pi * t / 8.0)  # three cycles to ±30 N·m of a 100 N·m reducer
    angle = torque / 20.0 + 2.0 * np.sign(np.cos(2 * np.pi * t / 8.0))  # arcmin: a loop 4 arcmin wide
    csv = csv_text(("time_s", "torque_Nm", "angle_arcmin"), [t, torque, angle])
    path = write_files({"campaign.toml": manifest(hyst_run(peak_torque_Nm="data")), "h.csv": csv})
    campaign = load_campaign(path)
    run = campaign.runs[0]
    assert run.peak_from_data and run.peak_torque_Nm is None
    assert any('peak_torque_Nm = "data": a partial-load run' in n and "not checked" in n for n in run.notes)
    metrics = campaign_metrics(campaign)["runs"][0]["metrics"]
    assert "stiffness_rated" in metrics and "loop's own peak" in json.dumps(metrics), metrics
    written = write_campaign(campaign, tmp_path / "out")
    assert load_campaign(written).runs[0].peak_from_data
    # without it the rated torque is the nominal load the run must reach, and the line says how to declare it
    message = load_error(write_files({"campaign.toml": manifest(hyst_run()), "h.csv": csv}))
    assert 'or "data" for the peak its cycles reach' in message


@pytest.mark.parametrize("value, expected", [
    ('"dta"', 'peak_torque_Nm must be a number > 0 (N·m) or "data"'),
    ("-3.0", "peak_torque_Nm must be > 0"),
])
def test_peak_torque_is_a_positive_number_or_data(write_files, value, expected):
    text = manifest(hyst_run()).rstrip() + f"\npeak_torque_Nm = {value}\n"
    assert expected in load_error(write_files({"campaign.toml": text, "h.csv": hyst_csv(peak=30.0)}))


def test_peak_torque_from_the_data_needs_torque_of_both_signs(write_files):
    one_signed = csv_text(("time_s", "torque_Nm", "angle_arcmin"),
                          [np.linspace(0, 8, 40), np.linspace(1, 30, 40), np.linspace(1, 30, 40) / 20])
    message = load_error(write_files({"campaign.toml": manifest(hyst_run(peak_torque_Nm="data")), "h.csv": one_signed}))
    assert "does not change sign" in message and "'torque_Nm'" in message


# ----------------------------------------------------------------------------- bad input


def test_missing_manifest(tmp_path):
    message = load_error(tmp_path / "nope.toml")
    assert "nope.toml" in message and "not found" in message


def test_toml_syntax_error(write_files):
    path = write_files({"campaign.toml": "[reducer]\nrated_torque_Nm 100\n"})
    message = load_error(path)
    assert "campaign.toml" in message and "TOML syntax error" in message and "line 2" in message


def test_missing_run_file(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run(file="gone.csv"))})
    message = load_error(path)
    assert "runs[0] 'h1' file gone.csv" in message and "not found" in message


def test_missing_column(write_files):
    text = csv_text(("output_angle_deg", "foo"), [np.linspace(0, 360, 20), np.zeros(20)])
    path = write_files({"campaign.toml": manifest(te_run(name="te-5rpm")), "te.csv": text})
    message = load_error(path)
    assert "runs[0] 'te-5rpm' file te.csv" in message
    assert "te_<unit>" in message and "input_angle_<unit>" in message
    assert "columns are output_angle_deg, foo" in message


def test_missing_mapped_column(write_files):
    tail = '[runs.columns]\nangle = "POSITION"\n'
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": hyst_csv()})
    message = load_error(path)
    assert "column 'POSITION'" in message and "not found" in message and "h.csv" in message


def test_unknown_unit_in_column_suffix(write_files):
    path = write_files(
        {
            "campaign.toml": manifest(hyst_run()),
            "h.csv": hyst_csv(header=("time_s", "torque_Nm", "angle_mrad")),
        }
    )
    message = load_error(path)
    assert "h.csv" in message and "'angle_mrad'" in message
    assert "unknown angle unit 'mrad'" in message
    assert "arcmin" in message  # lists what is accepted


def test_unknown_unit_in_runs_units(write_files):
    tail = '[runs.columns]\nangle = "angle_arcmin"\n[runs.units]\nangle = "grad"\n'
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": hyst_csv()})
    message = load_error(path)
    assert "[runs.units] angle" in message and "unknown angle unit 'grad'" in message


def test_units_without_mapped_column(write_files):
    tail = '[runs.units]\nangle = "deg"\n'
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": hyst_csv()})
    message = load_error(path)
    assert "[runs.units] angle" in message and "[runs.columns]" in message


@pytest.mark.parametrize("bad", ["nan", "inf", "-Infinity"])
def test_non_finite_value_names_the_line(write_files, bad):
    lines = hyst_csv().splitlines()
    lines[7] = lines[7].split(",")[0] + f",{bad}," + lines[7].split(",")[2]  # data row 6, line 8
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": "\n".join(lines)})
    message = load_error(path)
    assert "h.csv" in message and "'torque_Nm'" in message and "line 8" in message
    assert "finite" in message


@pytest.mark.parametrize("bad, shown", [("abc", "'abc'"), ("", "empty cell")])
def test_text_in_numeric_column_names_the_line(write_files, bad, shown):
    lines = hyst_csv().splitlines()
    cells = lines[12].split(",")
    lines[12] = ",".join(cells[:2] + [bad])
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": "\n".join(lines)})
    message = load_error(path)
    assert "'angle_arcmin'" in message and "line 13" in message and shown in message


def test_time_going_backwards_names_the_line(write_files):
    lines = hyst_csv().splitlines()
    cells = lines[20].split(",")
    lines[20] = ",".join(["0.5"] + cells[1:])  # line 21 steps back to t = 0.5 s
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": "\n".join(lines)})
    message = load_error(path)
    assert "'time_s'" in message and "backwards" in message and "line 21" in message


def test_too_few_samples(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": hyst_csv(n=9)})
    message = load_error(path)
    assert "h.csv" in message and "9 data row" in message and "at least 10" in message


def test_too_few_samples_after_selection(write_files):
    t = np.linspace(0, 1, 30)
    torque = 100 * np.sin(2 * np.pi * t)
    text = csv_text(("time_s", "torque_Nm", "angle_rad", "k"), [t, torque, torque, np.arange(30.0)])
    tail = "[runs.select]\nk = {max = 4}\n"
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": text})
    message = load_error(path)
    assert "5 data row(s) after [runs.select]" in message


def test_header_only_file(write_files):
    path = write_files(
        {"campaign.toml": manifest(hyst_run()), "h.csv": "# label\ntime_s,torque_Nm,angle_arcmin\n"}
    )
    message = load_error(path)
    assert "h.csv" in message and "no data rows" in message


def test_empty_file(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": "# only a comment\n"})
    assert "empty" in load_error(path)


def test_row_with_wrong_field_count(write_files):
    lines = hyst_csv().splitlines()
    lines[5] += ",7"
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": "\n".join(lines)})
    message = load_error(path)
    assert "line 6 has 4 fields" in message and "has 3" in message


def test_unknown_run_kind(write_files):
    text = manifest('\n[[runs]]\nname = "x"\nkind = "hysterisis"\nfile = "h.csv"\n')
    message = load_error(write_files({"campaign.toml": text, "h.csv": hyst_csv()}))
    assert "runs[0] 'x'" in message and "unknown kind 'hysterisis'" in message


def test_rated_torque_is_optional(write_files):
    # Data-only metrics read their torque scale from the data; without a nominal load the
    # io layer has no peak to check the run against.
    files = {
        "campaign.toml": manifest(hyst_run(), reducer='[reducer]\nname = "u"\n'),
        "h.csv": hyst_csv(peak=3.0),
    }
    campaign = load_campaign(write_files(files))
    assert campaign.reducer.rated_torque_Nm is None
    assert float(np.max(np.abs(campaign.runs[0].torque_Nm))) == pytest.approx(3.0, rel=0.01)


def test_missing_rated_torque_at_the_fit_entry_point(write_files):
    from torsionfit.fit import check_fittable

    files = {"campaign.toml": manifest(hyst_run(), reducer='[reducer]\nname = "u"\n'), "h.csv": hyst_csv()}
    campaign = load_campaign(write_files(files))
    with pytest.raises(InputError) as info:
        check_fittable(campaign)
    message = str(info.value)
    assert "\n" not in message and "[reducer].rated_torque_Nm" in message and "missing" in message


def test_rated_torque_missing_round_trips(tmp_path):
    t = np.linspace(0.0, 8.0, 40)
    tau = 5.0 * np.sin(2 * np.pi * t / 8.0)
    run = HysteresisRun(name="h", time_s=t, torque_Nm=tau, angle_rad=tau / 2000.0)
    original = Campaign(Reducer("u"), Instrument(), (run,))
    loaded = load_campaign(write_campaign(original, tmp_path / "c"))
    assert loaded.reducer == original.reducer and loaded.reducer.rated_torque_Nm is None


@pytest.mark.parametrize("value", ["0.0", "-5", '"100"'])
def test_bad_rated_torque(write_files, value):
    reducer = f"[reducer]\nrated_torque_Nm = {value}\n"
    files = {"campaign.toml": manifest(hyst_run(), reducer=reducer), "h.csv": hyst_csv()}
    path = write_files(files)
    message = load_error(path)
    assert "[reducer]" in message and "rated_torque_Nm must be" in message


def test_missing_reducer_table(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run(), reducer=""), "h.csv": hyst_csv()})
    assert "missing [reducer] table" in load_error(path)


def test_bad_direction(write_files):
    path = write_files({"campaign.toml": manifest(te_run(direction="fwd")), "te.csv": te_csv()})
    message = load_error(path)
    assert "runs[0] 'te1'" in message and "direction" in message and "'fwd'" in message


def test_negative_speed(write_files):
    path = write_files({"campaign.toml": manifest(te_run(speed_rpm=-5.0)), "te.csv": te_csv()})
    assert "speed_rpm must be >= 0" in load_error(path)


def test_te_shorter_than_one_revolution(write_files):
    path = write_files({"campaign.toml": manifest(te_run()), "te.csv": te_csv(turns=0.75)})
    message = load_error(path)
    assert "te.csv" in message and "'output_angle_deg'" in message and "270" in message
    assert "revolution" in message


def test_te_one_revolution_without_end_point_is_enough(write_files):
    out = np.arange(72) * 5.0  # 0 … 355°: one turn sampled at 72 equal steps
    text = csv_text(("output_angle_deg", "te_arcsec"), [out, np.zeros(72)])
    path = write_files({"campaign.toml": manifest(te_run()), "te.csv": text})
    assert len(load_campaign(path).runs[0]) == 72


def test_campaign_without_runs(write_files):
    message = load_error(write_files({"campaign.toml": manifest()}))
    assert "campaign.toml" in message and "no runs" in message and "[[runs]]" in message


def test_hysteresis_never_reaching_the_nominal_load(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": hyst_csv(peak=80.0)})
    message = load_error(path)
    assert "h.csv" in message and "'torque_Nm'" in message and "0.9" in message
    assert "|torque| = 79.9" in message and "100 N·m (rated_torque_Nm)" in message


@pytest.mark.parametrize(
    "text, key, where",
    [
        ('labl = "x"\n' + REDUCER + hyst_run(), "labl", "top level"),
        (REDUCER.replace("ratio", "ratoi") + hyst_run(), "ratoi", "[reducer]"),
        (REDUCER + "[instrument]\nencoder_res = 1.0\n" + hyst_run(), "encoder_res", "[instrument]"),
        (REDUCER + hyst_run(loading_rate=1.0), "loading_rate", "runs[0] 'h1'"),
        (REDUCER + hyst_run(speed_rpm=5.0), "speed_rpm", "hysteresis run"),
        (REDUCER + hyst_run(tail='[runs.columns]\nangel = "A"\n'), "angel", "[runs.columns]"),
        (REDUCER + hyst_run(tail="[runs.select]\nk = {low = 3}\n"), "low", "[runs.select] k"),
    ],
)
def test_unknown_manifest_key(write_files, text, key, where):
    message = load_error(write_files({"campaign.toml": text, "h.csv": hyst_csv()}))
    assert f"unknown key {key!r}" in message and where in message and "campaign.toml" in message


def test_unknown_key_suggests_the_right_one(write_files):
    text = REDUCER.replace("rated_torque_Nm", "rated_torqe_Nm") + hyst_run()
    message = load_error(write_files({"campaign.toml": text, "h.csv": hyst_csv()}))
    assert "did you mean 'rated_torque_Nm'" in message


def test_select_column_missing(write_files):
    tail = "[runs.select]\ntest_nr = [100]\n"
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": hyst_csv()})
    message = load_error(path)
    assert "h.csv" in message and "'test_nr'" in message and "[runs.select]" in message
    assert "not found" in message


def test_select_keeping_no_rows(write_files):
    t = np.linspace(0, 1, 30)
    torque = 100 * np.sin(2 * np.pi * t)
    header = ("time_s", "torque_Nm", "angle_rad", "test_nr")
    text = csv_text(header, [t, torque, torque, np.full(30, 3.0)])
    tail = "[runs.select]\ntest_nr = [100, 101]\n"
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": text})
    message = load_error(path)
    assert "test_nr in [100, 101] matches no row" in message and "holds 3" in message


def test_bad_select_rule(write_files):
    tail = '[runs.select]\ntest_nr = [1, "a"]\n'
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": hyst_csv()})
    assert "[runs.select] test_nr" in load_error(path)


def test_input_angle_without_ratio(write_files):
    reducer = "[reducer]\nrated_torque_Nm = 100.0\n"
    angle = np.linspace(0, 360, 20)
    text = csv_text(("output_angle_deg", "input_angle_deg"), [angle, angle])
    path = write_files({"campaign.toml": manifest(te_run(), reducer=reducer), "te.csv": text})
    message = load_error(path)
    assert "'input_angle_deg'" in message and "[reducer] ratio" in message and "te.csv" in message


def test_duplicate_run_names(write_files):
    path = write_files(
        {"campaign.toml": manifest(hyst_run(), hyst_run(file="h2.csv")), "h.csv": hyst_csv()}
    )
    message = load_error(path)
    assert "runs[1] name 'h1' is already used by runs[0]" in message


def test_ambiguous_suffixed_columns(write_files):
    text = hyst_csv().replace("angle_arcmin", "angle_arcmin,angle_deg", 1)
    text = "\n".join(line + ",0" if i > 1 else line for i, line in enumerate(text.splitlines()))
    path = write_files({"campaign.toml": manifest(hyst_run()), "h.csv": text})
    message = load_error(path)
    assert "angle_arcmin, angle_deg" in message and "[runs.columns]" in message


def test_duplicated_column_name(write_files):
    text = hyst_csv().replace("angle_arcmin", "torque_Nm", 1)  # header: time_s, torque_Nm × 2
    run = hyst_run(tail='[runs.columns]\nangle = "time_s"\n')
    path = write_files({"campaign.toml": manifest(run), "h.csv": text})
    assert "'torque_Nm' appears more than once" in load_error(path)


def test_bad_gzip_file(write_files, tmp_path):
    path = write_files({"campaign.toml": manifest(hyst_run(file="h.csv.gz"))})
    (tmp_path / "h.csv.gz").write_text("not gzip")
    assert "cannot read" in load_error(path)


# ----------------------------------------------------------------------------- writing


def _campaign_for_writing() -> Campaign:
    t = np.repeat(np.arange(25) * 8.0, 2)  # the sine ramps at about its declared 1 N·m/s
    torque = 50.0 * np.sin(np.linspace(0, 2 * np.pi, 50)) + 1e-7
    out = np.linspace(0, 4 * math.pi, 90)
    return Campaign(
        Reducer("unit \"7\"", 380.0, ratio=121.0, max_speed_rpm=70.0),
        Instrument(torque_full_scale_Nm=1500.0, torque_accuracy_pct_fs=0.1),
        (
            HysteresisRun(
                "hyst 1", t, torque, torque / 2.0e5, loading_rate_Nm_per_s=1.0, peak_torque_Nm=50.0
            ),
            TransmissionErrorRun(
                "te/5rpm",
                out,
                1e-5 * np.sin(2 * out),
                torque_Nm=380.0,
                speed_rpm=5.0,
                direction=-1,
                time_s=np.linspace(0, 24, 90),
                torque_series_Nm=np.full(90, 379.5),
            ),
        ),
        notes="old notes",
    )


def test_round_trip(tmp_path):
    original = _campaign_for_writing()
    path = write_campaign(original, tmp_path / "out", label="SYNTHETIC: round trip")
    assert path == tmp_path / "out" / "campaign.toml"
    loaded = load_campaign(path)
    assert loaded.reducer == original.reducer and loaded.instrument == original.instrument
    assert loaded.notes == "SYNTHETIC: round trip"
    (h0, te0), (h1, te1) = original.runs, loaded.runs
    assert (h1.name, h1.loading_rate_Nm_per_s, h1.peak_torque_Nm) == ("hyst 1", 1.0, 50.0)
    np.testing.assert_array_equal(h1.time_s, h0.time_s)
    np.testing.assert_array_equal(h1.torque_Nm, h0.torque_Nm)
    np.testing.assert_allclose(h1.angle_rad, h0.angle_rad, rtol=1e-14, atol=0)
    assert (te1.name, te1.direction, te1.speed_rpm, te1.torque_Nm) == ("te/5rpm", -1, 5.0, 380.0)
    np.testing.assert_allclose(te1.output_angle_rad, te0.output_angle_rad, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(te1.te_rad, te0.te_rad, rtol=1e-14, atol=1e-20)
    np.testing.assert_array_equal(te1.time_s, te0.time_s)
    np.testing.assert_array_equal(te1.torque_series_Nm, te0.torque_series_Nm)
    assert te1.temperature_C is None


def test_written_files_carry_the_label_and_unit_columns(tmp_path):
    path = write_campaign(_campaign_for_writing(), tmp_path, bench_file=tmp_path / "bench.toml")
    text = path.read_text()
    assert 'label = "old notes"' in text and "bench.toml" in text  # label defaults to the notes
    files = sorted(p.name for p in tmp_path.glob("*.csv"))
    assert files == ["hyst_1.csv", "te_5rpm.csv"]
    hyst = (tmp_path / "hyst_1.csv").read_text().splitlines()
    te = (tmp_path / "te_5rpm.csv").read_text().splitlines()
    assert hyst[:2] == ["# old notes", "time_s,torque_Nm,angle_arcmin"]
    assert te[:2] == ["# old notes", "output_angle_deg,te_arcsec,time_s,torque_Nm"]


# ----------------------------------------------------------------------------- examples

_REQUIRED_EXAMPLES = [
    "baseline-pccf-initial-pos1",
    "baseline-pccf-initial-pos5",
    "baseline-pccf-initial-pos6",
    "baseline-pccf-runin-pos1",
    "split-pccf-initial-pos1",
    "split-pccf-preload3-pos1",
]


def test_required_examples_exist_and_credit_the_source():
    for stem in _REQUIRED_EXAMPLES:
        assert (EXAMPLES / f"{stem}.toml").is_file(), stem
    for path in EXAMPLES.glob("*.toml"):
        text = path.read_text(encoding="utf-8")
        assert "CC BY-SA 4.0" in text and "JelmerV/Anti-Backlash-Cycloidal-Actuator" in text
        assert 'file = "../../../shared/data/cycloidal-jv/' in text  # read in place, never copied
    assert not list(EXAMPLES.glob("*.csv*"))


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_example_loads_real_loops(shared_data, path):
    campaign = load_campaign(path)
    assert "REAL MEASURED DATA" in campaign.notes and "CC BY-SA 4.0" in campaign.notes
    assert campaign.reducer.rated_torque_Nm == 20.0
    assert campaign.instrument.encoder_resolution_arcsec == pytest.approx(19.78, abs=0.01)
    (run,) = campaign.runs
    assert isinstance(run, HysteresisRun) and run.source.startswith(str(shared_data.resolve()))
    assert 30_000 < len(run) < 40_000  # the whole file: play ramps + three stiffness ramps at ~430 rows/s
    assert np.all(np.diff(run.time_s) >= 0) and 75 < np.ptp(run.time_s) < 90
    assert run.torque_Nm.min() < -20 and run.torque_Nm.max() > 20  # ramps reach ±25..40 N·m
    assert 4 < np.degrees(np.ptp(run.angle_rad)) < 12  # twist of a few degrees
    steps = np.diff(np.unique(run.angle_rad))
    assert np.degrees(steps.min()) * 3600 == pytest.approx(19.775390625, rel=1e-6)


@pytest.mark.parametrize("command", ["fit", "diagnose", "accept"])
def test_model_entry_points_name_the_missing_rated_torque(write_files, capsys, command):
    from torsionfit.cli import main

    files = {
        "campaign.toml": manifest(hyst_run(), reducer='[reducer]\nname = "u"\n'),
        "h.csv": hyst_csv(),
        "spec.toml": '[[requirement]]\nmetric = "backlash"\nmax = 5.0\nunit = "arcmin"\n',
    }
    path = write_files(files)
    extra = ["--spec", str(path.parent / "spec.toml")] if command == "accept" else []
    code = main([command, str(path), "-o", str(path.parent / "out"), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2 and "\n" not in err and "[reducer].rated_torque_Nm" in err, err


# --- conditioning rows ---------------------------------------------------------------------------
def _numbered_cycles(n=30):
    """Three sine cycles to ±100 N·m, test_nr 1, 2, 3 (SYNTHETIC)."""
    t = np.linspace(0.0, 3.0, 3 * n, endpoint=False)
    torque = 100 * np.sin(2 * np.pi * t)
    header = ("time_s", "torque_Nm", "angle_rad", "test_nr")
    return csv_text(header, [t, torque, torque / 1e5, np.floor(t) + 1.0])


def test_conditioning_rows_are_read_kept_and_carried(write_files, tmp_path):
    """[runs.condition] marks rows (after [runs.select]); decimation carries the mark (a block
    with a conditioning row is one) and write_campaign writes it back."""
    from torsionfit.io import decimate, write_campaign

    tail = "[runs.select]\ntest_nr = [2, 3]\n[runs.condition]\ntest_nr = [2]\n"
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": _numbered_cycles()})
    run = load_campaign(path).runs[0]
    assert len(run) == 60 and run.conditioning.tolist() == [True] * 30 + [False] * 30
    assert any("30 conditioning row(s)" in note for note in run.notes)
    blocks = decimate(load_campaign(path), 4).runs[0].conditioning
    assert blocks.tolist() == [True] * 8 + [False] * 7  # block 7 holds rows 28–31: two conditioning
    again = load_campaign(write_campaign(load_campaign(path), tmp_path / "w")).runs[0]
    assert again.conditioning.tolist() == run.conditioning.tolist()


@pytest.mark.parametrize("rule, words", [("test_nr = [7]", "[runs.condition] test_nr in [7] matches no row"),
                                          ("test_nr = [1, 2, 3]", "[runs.condition] matches every row")])
def test_conditioning_rules_that_leave_nothing_to_fit_or_match_nothing_stop(write_files, rule, words):
    tail = f"[runs.condition]\n{rule}\n"
    path = write_files({"campaign.toml": manifest(hyst_run(tail=tail)), "h.csv": _numbered_cycles()})
    message = load_error(path)
    assert words in message and "h.csv" in message


def test_a_te_run_has_no_conditioning_rows(write_files):
    tail = "[runs.condition]\ntest_nr = [1]\n"
    message = load_error(write_files({"campaign.toml": manifest(te_run(tail=tail)), "te.csv": te_csv()}))
    assert "unknown key 'condition'" in message
