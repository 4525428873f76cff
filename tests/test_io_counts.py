"""Angles logged in raw encoder counts (unit ``count``): one count is the declared resolution."""

import gzip
import math

import numpy as np
import pytest

from torsionfit.io import load_campaign
from torsionfit.metrics import campaign_metrics

from conftest import SHARED_DATA
from test_io import ARCMIN, ARCSEC, EXAMPLES, csv_text, hyst_csv, hyst_run, load_error, manifest, te_run

#: the measured loops' POSITION steps: 2^-16 revolution
MEASURED_COUNT_ARCSEC = 1296000.0 / 2**16


def _instrument(**keys) -> str:
    return "[instrument]\n" + "".join(f"{k} = {v}\n" for k, v in keys.items())


def test_a_hysteresis_angle_in_counts_is_the_resolution_times_the_count(write_files):
    counts = np.round(np.linspace(-300.0, 300.0, 401))  # ±5 arcmin at 1″ per count, a count or two a sample
    text = csv_text(("time_s", "torque_Nm", "angle_count"), [np.linspace(0, 8, 401), counts / 3.0, counts])
    path = write_files({"campaign.toml": manifest(hyst_run(), head="", reducer="[reducer]\nrated_torque_Nm = 100.0\n"
                                                  + _instrument(encoder_resolution_arcsec=1.0)),
                        "h.csv": text})
    (run,) = load_campaign(path).runs
    np.testing.assert_allclose(run.angle_rad, counts * ARCSEC)


def test_counts_without_the_resolution_name_the_key(write_files):
    path = write_files({"campaign.toml": manifest(hyst_run()),
                        "h.csv": hyst_csv(header=("time_s", "torque_Nm", "angle_count"))})
    message = load_error(path)
    assert "'angle_count'" in message and "[instrument] encoder_resolution_arcsec" in message


def test_a_te_column_cannot_be_in_counts(write_files):
    out = np.linspace(0.0, 360.0, 73)
    text = csv_text(("output_angle_deg", "te_count"), [out, np.round(30.0 * np.sin(2 * np.radians(out)))])
    path = write_files({"campaign.toml": manifest(te_run(), head="",
                                                  reducer="[reducer]\nrated_torque_Nm = 100.0\nratio = 50.0\n"
                                                  + _instrument(encoder_resolution_arcsec=1.0)),
                        "te.csv": text})
    message = load_error(path)
    assert "'te_count'" in message and "cannot be in encoder counts" in message


def test_te_from_two_encoders_counts_each_in_its_own_resolution(write_files):
    """Output encoder 2^20 counts per turn, motor encoder 2^12: the TE is output − input / ratio
    in angle, whatever the two count sizes."""
    out_res, in_res, ratio = 1296000.0 / 2**20, 1296000.0 / 2**12, 50.0
    out_counts = np.round(np.linspace(0.0, 2**20, 200))
    te_arcsec = 20.0 * np.sin(2 * np.pi * out_counts / 2**20)
    in_counts = ratio * (out_counts * out_res - te_arcsec) / in_res  # motor counts, not whole after the TE
    text = csv_text(("output_angle_count", "input_angle_count"), [out_counts, in_counts])
    reducer = "[reducer]\nrated_torque_Nm = 100.0\nratio = 50.0\n"
    files = {"te.csv": text}
    path = write_files({**files, "campaign.toml": manifest(te_run(), head="", reducer=reducer + _instrument(
        encoder_resolution_arcsec=out_res, input_encoder_resolution_arcsec=in_res))})
    (te,) = load_campaign(path).runs
    np.testing.assert_allclose(te.output_angle_rad, out_counts * out_res * ARCSEC)
    np.testing.assert_allclose(te.te_rad / ARCSEC, te_arcsec, atol=1e-6)
    path = write_files({**files, "campaign.toml": manifest(te_run(), head="", reducer=reducer + _instrument(
        encoder_resolution_arcsec=out_res))})
    message = load_error(path)
    assert "'input_angle_count'" in message and "[instrument] input_encoder_resolution_arcsec" in message


def test_counts_read_with_a_wrong_resolution_ask_for_it(write_files):
    """A count declared 100× too small makes a stiff reducer 100× stiffer than any: the warning
    asks about the resolution, not about an angle unit the column cannot hold."""
    torque = 100.0 * np.sin(np.linspace(0, 2 * np.pi, 40))
    counts = np.round(torque / 100.0 * 300.0)  # ±5 arcmin at ±100 N·m in 1″ counts
    text = csv_text(("time_s", "torque_Nm", "angle_count"), [np.linspace(0, 8, 40), torque, counts])
    path = write_files({"campaign.toml": manifest(hyst_run(), head="", reducer="[reducer]\nrated_torque_Nm = 100.0\n"
                                                  + _instrument(encoder_resolution_arcsec=0.01)),
                        "h.csv": text})
    with pytest.warns(UserWarning, match=r"encoder_resolution_arcsec, the angle of one count") as record:
        load_campaign(path)
    assert not any("if the column held" in str(w.message) for w in record)


def test_counts_that_step_far_coarser_than_the_resolution_ask_for_it(write_files):
    """A 2^16-count encoder's counts declared at a 2^22-count resolution (64× finer): every change
    is a multiple of 64 of the declared counts, and the warning asks about the resolution."""
    counts = np.round(np.linspace(-300.0, 300.0, 401)) * 64.0
    text = csv_text(("time_s", "torque_Nm", "angle_count"), [np.linspace(0, 8, 401), counts / 192.0, counts])
    reducer = "[reducer]\nrated_torque_Nm = 100.0\n" + _instrument(encoder_resolution_arcsec=1296000.0 / 2**22)
    path = write_files({"campaign.toml": manifest(hyst_run(), head="", reducer=reducer), "h.csv": text})
    with pytest.warns(UserWarning, match=r"64× the \[instrument\] encoder_resolution_arcsec") as record:
        load_campaign(path)
    (step,) = [str(w.message) for w in record if "moves in steps" in str(w.message)]
    assert "is the resolution (the angle of one count) right?" in step and "angle unit" not in step


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="measured data ../shared/data is absent")
def test_a_measured_loop_logged_in_counts_of_a_wrapping_encoder_reads_as_in_revolutions(tmp_path):
    """REAL split preload3-pos1, POSITION (rev, 2^-16 steps) written as a single-turn absolute
    encoder logs it, counts modulo 2^16: read in counts at 19.78″ each and unwrapped, its angle
    moves as the revolutions do and its play and loading slope are the same."""
    source = SHARED_DATA / "cycloidal-jv" / "split-pccf" / "preload3-pos1.csv.gz"
    lines = gzip.open(source, "rt").read().splitlines()
    k = lines[0].split(",").index("POSITION")
    rows = [line.split(",") for line in lines[1:]]
    revs = np.array([float(r[k]) for r in rows])
    counts = np.round(revs * 2**16)
    assert np.allclose(counts, revs * 2**16, atol=1e-6)  # whole counts: the file's steps
    for row, c in zip(rows, (counts - counts.min() + 2**16 - 300) % 2**16):  # crosses the wrap
        row[k] = str(int(c))
    (tmp_path / "counts.csv").write_text("\n".join([lines[0]] + [",".join(r) for r in rows]) + "\n")
    text = (EXAMPLES / "split-pccf-preload3-pos1.toml").read_text()
    text = text.replace("../../../shared/data/cycloidal-jv/split-pccf/preload3-pos1.csv.gz", "counts.csv")
    assert 'angle = "rev"' in text
    (tmp_path / "counts.toml").write_text(text.replace('angle = "rev"', 'angle = "count"'))
    counted = load_campaign(tmp_path / "counts.toml")
    original = load_campaign(EXAMPLES / "split-pccf-preload3-pos1.toml")
    moved = counted.runs[0].angle_rad - original.runs[0].angle_rad
    np.testing.assert_allclose(moved, moved[0], atol=1e-9)  # one offset: the counts' zero
    assert abs(moved[0]) < 2 * math.pi and MEASURED_COUNT_ARCSEC * ARCSEC == pytest.approx(2 * math.pi / 2**16)
    a, b = campaign_metrics(counted)["runs"][0], campaign_metrics(original)["runs"][0]
    for name in ("play", "stiffness_loading"):
        assert a["metrics"][name]["value"] == pytest.approx(b["metrics"][name]["value"], rel=1e-9), name
    assert any("'POSITION' wraps at a full turn" in n for n in a["reading"])
