"""Checks of a TE run's units against its declarations and the campaign's loops (SYNTHETIC data
from the virtual bench, rewritten as a bench with another unit would export them): the TE
column's angle unit (``io/_te_twist.py``), the torque column against ``torque_Nm``, the input
and output columns against ``[reducer] ratio``, and the sample rate that times a run without a
time column against its speed."""

import math
import re
from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.bench import load_bench, simulate, write_te_export
from torsionfit.io import load_campaign
from torsionfit.io._manifest import write_campaign

from test_plausibility import plausibility_warnings

BENCHES = Path(__file__).resolve().parent / "benches"
#: TE forward and backward at a load of at least a quarter of the rating, with loops beside them
WITH_LOOPS = BENCHES / "effects" / "te_temperature.toml"
#: the same without loops
TE_ONLY = BENCHES / "stat_te_only.toml"
EXPORT = BENCHES / "te_export.toml"
#: a printed-reducer-like unit: its gap and friction make up most of the TE's twist at low load
PRINTED = BENCHES / "te_printed.toml"


def _written(tmp_path, bench_file: Path, seed: int = 0) -> Path:
    bench = load_bench(bench_file)
    sim = simulate(bench, seed=seed)
    folder = tmp_path / bench_file.stem
    if bench.te_export is not None:
        return write_te_export(sim, bench, folder)
    return write_campaign(sim.campaign, folder)


def _rewrite_te_files(manifest: Path, header_from: str, header_to: str, column: str | None = None, scale=1.0):
    """In every TE file of ``manifest``'s folder: rename a header, and multiply ``column``."""
    for path in manifest.parent.glob("te-*.csv"):
        lines = path.read_text().splitlines()
        head = next(i for i, line in enumerate(lines) if not line.startswith("#"))
        names = lines[head].split(",")
        rows = [line.split(",") for line in lines[head + 1:]]
        if column is not None:
            k = names.index(column)
            for row in rows:
                row[k] = repr(float(row[k]) * scale)
        lines[head] = lines[head].replace(header_from, header_to)
        path.write_text("\n".join(lines[:head + 1] + [",".join(r) for r in rows]) + "\n")


@pytest.mark.parametrize("bench_file", [WITH_LOOPS, TE_ONLY, EXPORT, PRINTED, BENCHES / "effects" / "te_speed.toml",
                                        BENCHES / "effects" / "te_kinematic.toml",
                                        BENCHES.parent.parent / "examples" / "accept" / "line-bench.toml"])
@pytest.mark.parametrize("seed", [0, 3])
def test_te_campaigns_as_written_read_without_a_word(tmp_path, bench_file, seed):
    assert plausibility_warnings(_written(tmp_path, bench_file, seed)) == []


def test_a_printed_units_te_at_a_quarter_of_its_rating_alone_reads_without_a_word(tmp_path):
    """Without the loop and the rated-load pair, the TE at 5 of 20 N·m twists about 2.5× its
    elastic share (gap and friction over the load): still inside the band, not a unit slip."""
    manifest = _written(tmp_path, PRINTED)
    blocks = manifest.read_text().split("[[runs]]")
    kept = [b for b in blocks[1:] if 'name = "te-5-' in b]
    assert len(kept) == 2
    manifest.write_text("[[runs]]".join([blocks[0]] + kept))
    assert plausibility_warnings(manifest) == []


def _keep_runs(manifest: Path, keep) -> int:
    """Rewrite ``manifest`` with the run blocks whose text ``keep`` accepts; their number."""
    blocks = manifest.read_text().split("[[runs]]")
    kept = [b for b in blocks[1:] if keep(b)]
    manifest.write_text("[[runs]]".join([blocks[0]] + kept))
    return len(kept)


def test_one_direction_per_rezeroed_test_says_the_te_gives_no_twist(tmp_path):
    """The export's bench re-zeroes before every test; with only the forward revolutions kept,
    every zero group holds one load in one direction: the groups' TE zeros absorb the twist and
    a TE-only fit's stiffness is its prior (a fit of it: 398 ± 1100 N·m/arcmin, truth 200). One
    line naming zero_group. Kept both ways, or sharing one zero, the runs read without a word."""
    manifest = _written(tmp_path, EXPORT)
    assert _keep_runs(manifest, lambda b: 'direction = "forward"' in b) == 5
    (message,) = plausibility_warnings(manifest)
    assert "every TE zero group holds runs at one load in one direction" in message
    assert "TE_486rpm_250Nm_40C: 250 N·m forward" in message and "zero_group" in message
    assert "are their priors" in message
    # the same forward runs under one encoder zero: loads apart in one group give the stiffness
    manifest.write_text(re.sub(r'zero_group = "[^"]*"\n', "", manifest.read_text()))
    assert plausibility_warnings(manifest) == []


def test_one_te_run_beside_loops_reads_without_a_word(tmp_path):
    """Loops and one TE run (for its ripple) is a common layout: the loops carry the twist."""
    manifest = _written(tmp_path, WITH_LOOPS)
    assert _keep_runs(manifest, lambda b: 'kind = "hysteresis"' in b or 'name = "te-40C-fw"' in b) == 2
    assert plausibility_warnings(manifest) == []
    # the TE run alone: nothing else carries the twist
    assert _keep_runs(manifest, lambda b: 'name = "te-40C-fw"' in b) == 1
    (message,) = plausibility_warnings(manifest)
    assert "(shared): " in message and "are their priors" in message


def test_te_in_arcsec_declared_arcmin_beside_loops_stops_naming_arcsec(tmp_path):
    """60× the loops' compliance, and in arcsec the TE agrees with them: two readings, a stop."""
    manifest = _written(tmp_path, WITH_LOOPS)
    _rewrite_te_files(manifest, "te_arcsec", "te_arcmin")
    with pytest.raises(InputError) as caught:
        load_campaign(manifest)
    message = str(caught.value)
    assert "\n" not in message
    assert "column 'te_arcmin' (arcmin)" in message and "te = \"arcsec\"" in message
    assert re.search(r"60(\.\d)?× the hysteresis loops'", message), message


def test_te_scaled_by_no_unit_beside_loops_warns_what_to_check(tmp_path):
    """Ten times the loops' compliance: no unit explains it (a load declared 10× too small
    would), so a warning names the keys, and reading goes on."""
    manifest = _written(tmp_path, WITH_LOOPS)
    _rewrite_te_files(manifest, "te_arcsec", "te_arcsec", column="te_arcsec", scale=10.0)
    (message,) = plausibility_warnings(manifest)
    assert "10× the hysteresis loops'" in message or "9.9" in message or "10.1" in message
    assert "torque_Nm" in message


def test_te_only_in_arcsec_declared_deg_warns_with_the_unit_that_fits(tmp_path):
    """Without loops the twist at the rated torque alone: 3600× too large, a warning."""
    manifest = _written(tmp_path, TE_ONLY)
    _rewrite_te_files(manifest, "te_arcsec", "te_deg")
    (message,) = plausibility_warnings(manifest)
    assert "column 'te_deg' (deg)" in message and "if it held arcsec" in message


def test_export_te_in_deg_declared_arcmin_warns(tmp_path):
    """The export's TE in degrees under [runs.units] te = "arcmin": 60× too small."""
    manifest = _written(tmp_path, EXPORT)
    manifest.write_text(manifest.read_text().replace('te = "deg"', 'te = "arcmin"'))
    messages = plausibility_warnings(manifest)
    assert len(messages) == 1 and "column 'TE_fw' (arcmin)" in messages[0] and "if it held deg" in messages[0]


def test_te_torque_column_in_Nmm_stops_naming_the_unit(tmp_path):
    manifest = _written(tmp_path, WITH_LOOPS)
    _rewrite_te_files(manifest, "torque_Nm", "torque_Nm", column="torque_Nm", scale=1000.0)
    with pytest.raises(InputError, match=r"column 'torque_Nm' \(read in Nm\) holds a load of 3\.8\d*e\+05 N·m .*"
                                         r"torque_Nm = 380.*holding Nmm"):
        load_campaign(manifest)


def test_te_load_declared_ten_times_too_small_stops(tmp_path):
    """The model uses the declared load: a column that contradicts it stops, no unit named."""
    manifest = _written(tmp_path, WITH_LOOPS)
    manifest.write_text(re.sub(r"(?m)^torque_Nm = 380\.0$", "torque_Nm = 38.0", manifest.read_text()))
    with pytest.raises(InputError, match="check the column's unit and the declared torque_Nm"):
        load_campaign(manifest)


def test_te_torque_column_of_the_motor_stops_naming_the_ratio(tmp_path):
    """A bench that logs the motor's torque, the load over the ratio (121): no unit explains it,
    the ratio does."""
    manifest = _written(tmp_path, WITH_LOOPS)
    _rewrite_te_files(manifest, "torque_Nm", "torque_Nm", column="torque_Nm", scale=1.0 / 121.0)
    with pytest.raises(InputError, match=r"the declared load over \[reducer\] ratio = 121 .* input \(motor\) torque"):
        load_campaign(manifest)


def test_te_run_timed_by_another_rate_stops_naming_sample_rate(tmp_path):
    """The export has no time column: [instrument] sample_rate_Hz times it, and at a tenth of
    the logger's rate the output would turn at 0.6 rpm, not 6."""
    manifest = _written(tmp_path, EXPORT)
    text = manifest.read_text()
    assert "sample_rate_Hz = 72.0" in text
    manifest.write_text(text.replace("sample_rate_Hz = 72.0", "sample_rate_Hz = 7.2"))
    with pytest.raises(InputError, match=r"sample_rate_Hz = 7\.2 .*10× slower than the declared output speed 6 rpm"):
        load_campaign(manifest)


# ----------------------------------------------------------------------------- input / output / ratio


RATIO = 81.0


def _te_from_angles(tmp_path, declared_ratio=RATIO, input_scale=1.0, input_unit="deg", input_sign=1.0) -> Path:
    """A TE run written as two encoder columns (degrees): the output turning once at 6 rpm and
    the input ``RATIO`` times as far, with a small TE of its own (SYNTHETIC)."""
    n = 2000
    output = np.linspace(0.0, 360.0, n, endpoint=False)
    te = 0.01 * np.sin(np.radians(output) * 2) + np.random.default_rng(0).normal(0, 1e-4, n)
    inp = input_sign * RATIO * (output - te) * input_scale
    folder = tmp_path / "angles"
    folder.mkdir()
    (folder / "te.csv").write_text("output_angle_deg,input_angle_x,time_s\n" + "\n".join(
        f"{o!r},{i!r},{t!r}" for o, i, t in zip(output.tolist(), inp.tolist(), (np.arange(n) * 10.0 / n).tolist())) + "\n")
    (folder / "campaign.toml").write_text(
        f'label = "SYNTHETIC"\n[reducer]\nname = "r"\nratio = {declared_ratio}\n'
        '[[runs]]\nname = "te"\nkind = "transmission_error"\nfile = "te.csv"\nspeed_rpm = 6.0\ntorque_Nm = 0.0\n'
        f'direction = "forward"\n[runs.columns]\noutput_angle = "output_angle_deg"\ninput_angle = "input_angle_x"\n'
        f'time = "time_s"\n[runs.units]\noutput_angle = "deg"\ninput_angle = "{input_unit}"\n')
    return folder / "campaign.toml"


def test_input_and_output_at_the_ratio_read_cleanly(tmp_path):
    campaign = load_campaign(_te_from_angles(tmp_path))
    te = campaign.runs[0].te_rad
    assert np.ptp(te) < math.radians(0.05)


def test_a_ratio_a_tooth_off_stops_with_the_drift(tmp_path):
    with pytest.raises(InputError, match=r"turn 81(\.\d*)?:1 over the run, where \[reducer\] ratio = 80; .*drift 27\d\.\d arcmin "
                                         r"per output revolution; check \[reducer\] ratio"):
        load_campaign(_te_from_angles(tmp_path, declared_ratio=80.0))


def test_an_input_in_arcmin_declared_deg_stops_naming_arcmin(tmp_path):
    with pytest.raises(InputError, match="column 'input_angle_x' holding arcmin would turn them at the ratio"):
        load_campaign(_te_from_angles(tmp_path, input_scale=60.0))


def test_an_input_turning_the_other_way_stops_saying_so(tmp_path):
    with pytest.raises(InputError, match="the input turns against the output"):
        load_campaign(_te_from_angles(tmp_path, input_sign=-1.0))


# ----------------------------------------------------------------------------- the guide's examples


def test_the_guides_te_examples_are_what_the_commands_print(tmp_path, capsys, monkeypatch):
    """docs/guide/checks.md shows the two TE stops of the line bench's copy: re-made here."""
    from torsionfit.cli import main

    guide = (Path(__file__).resolve().parents[1] / "docs" / "guide" / "checks.md").read_text()
    monkeypatch.chdir(tmp_path)
    bench = Path(__file__).resolve().parents[1] / "examples" / "accept" / "line-bench.toml"
    assert main(["simulate", str(bench), "-o", "copy", "-q"]) == 0
    capsys.readouterr()
    manifest = Path("copy") / "campaign.toml"
    shown = []
    for header, scale in (("te_arcmin", 1.0), ("te_arcsec", 1000.0)):
        folder = tmp_path / "copy"
        saved = {p: p.read_text() for p in folder.glob("te-*.csv")}
        _rewrite_te_files(folder / "campaign.toml", "te_arcsec", header, column="torque_Nm", scale=scale)
        assert main(["metrics", str(manifest)]) == 2
        (line,) = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
        shown.append(line)
        for p, text in saved.items():
            p.write_text(text)
    for line in shown:
        assert line in guide, line
