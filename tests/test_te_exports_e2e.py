"""TE bench exports end to end: the virtual bench writes the layout a real TE rig exports
(``tests/benches/te_export.toml``: forward and backward side by side, degrees, lag-negative, a
logger clock and no time column, motor rpm in the file name, NaN pad, encoders re-zeroed before
every test, kinematic error at orders 1, 2, 39), and metrics, fit and diagnose read it as a user
would. Every file here is SYNTHETIC."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.bench import load_bench, simulate, write_te_export
from torsionfit.io import load_campaign
from torsionfit.metrics import campaign_metrics
from torsionfit.report import derived_metrics_for

BENCH = Path(__file__).parent / "benches" / "te_export.toml"
K = 200.0  # N·m/arcmin, the bench's stiffness
ARCMIN = math.pi / 180 / 60
SHIFTS_ARCMIN = (0.0, 0.4, -0.3, 0.25, -0.15)  # the bench's zero shift per test


def _bench(tmp_path, *, shifts=True, no_load=True, kinematic=True):
    """te_export.toml, optionally without zero shifts, no-load test or kinematic error."""
    text = BENCH.read_text()
    if not shifts:
        text = re.sub(r"zero_shift_arcmin = \[.*\]", "zero_shift_arcmin = [0.0, 0.0, 0.0, 0.0, 0.0]", text)
    if not no_load:
        text = re.sub(r"zero_shift_arcmin = \[.*\]", "zero_shift_arcmin = []", text)
        text = re.sub(r'\[\[runs\]\]\nname = "noload-(fw|bw)"\n(.*\n){5}', "", text)
    if not kinematic:
        text = re.sub(r"\[effects\]\nkinematic_error = .*\n", "", text)
        text = re.sub(r"kin_(cos|sin)_arcsec = .*\n", "", text)
    path = tmp_path / "bench.toml"
    path.write_text(text)
    return load_bench(path)


@pytest.fixture(scope="module")
def export(tmp_path_factory):
    """(bench, simulation, manifest) of the declared export of te_export.toml."""
    folder = tmp_path_factory.mktemp("te_export")
    bench = load_bench(BENCH)
    sim = simulate(bench)
    return bench, sim, write_te_export(sim, bench, folder / "declared")


def test_bench_writes_the_export_layout(export):
    bench, sim, manifest = export
    folder = manifest.parent
    files = sorted(p.name for p in folder.glob("*.csv"))
    assert files == ["TE_486rpm_0Nm_40C.csv", "TE_486rpm_1000Nm_25C.csv", "TE_486rpm_1000Nm_40C.csv",
                     "TE_486rpm_250Nm_40C.csv", "TE_486rpm_500Nm_40C.csv"]  # motor rpm = 6 rpm × 81
    lines = (folder / "TE_486rpm_500Nm_40C.csv").read_text().splitlines()
    assert lines[0].startswith("# SYNTHETIC") and lines[1] == "Pos_fw;TE_fw;Pos_bw;TE_bw"  # no time column
    rows = np.array([[float(v) for v in line.split(";")] for line in lines[2:]])
    assert np.isnan(rows[-1, 2:]).all() and np.isfinite(rows[:-1]).all()  # the backward side padded
    assert np.ptp(rows[:, 0]) == pytest.approx(360.0, abs=1.0)  # degrees
    # lag-negative: under load the forward TE lies below the backward TE in the file
    assert np.mean(rows[:, 1]) < np.nanmean(rows[:, 3]) - 2 * 500.0 / K / 60
    text = manifest.read_text()
    assert 'te_convention = "lag_negative"' in text and "sample_rate_Hz = 72.0" in text
    assert "kinematic" not in text and "zero_shift" not in text  # the truth is not written
    campaign = load_campaign(manifest)
    assert len(campaign.te_zero_groups) == 5 and len(campaign.runs) == 10
    # read back = simulated, lag-positive, in SI (up to the text's rounding)
    for read, made in zip(campaign.runs, sim.campaign.runs):
        assert read.zero_group == made.zero_group and read.direction == made.direction
        np.testing.assert_allclose(read.te_rad, made.te_rad, atol=1e-15)
        np.testing.assert_allclose(read.time_s, made.time_s, rtol=1e-12)
        assert read.nominal_temperature_C == made.nominal_temperature_C
    assert any("dropped 1 trailing row" in n for n in campaign.runs[1].notes)


def test_undeclared_export_stops_with_one_line(export, tmp_path):
    bench, sim, _ = export
    manifest = write_te_export(sim, bench, tmp_path / "undeclared", declare=False)
    with pytest.raises(InputError, match="te_convention") as err:
        load_campaign(manifest)
    assert "\n" not in str(err.value) and "TE_486rpm_500Nm_40C.csv" in str(err.value)


def _agreement(campaign, model, truth):
    """{run: {name: (data, model)}} for kd, kt and te_kinematic_180 of every loaded run."""
    data = {r["name"]: r["metrics"] for r in campaign_metrics(campaign)["runs"]}
    derived = derived_metrics_for(campaign, model)
    values = dict(zip((s.name for s in derived.specs), np.asarray(derived.evaluate(truth))))
    out = {}
    for spec_name, value in values.items():
        if "[" not in spec_name:
            continue
        metric, run = spec_name[:-1].split("[")
        name = {"kd_mean": "kd"}.get(metric, metric)
        out.setdefault(run, {})[name] = (data[run][name]["value"], float(value))
    return out, data


@pytest.mark.parametrize("no_load", [True, False], ids=["no-load reference", "encoders' zero"])
def test_data_and_model_read_kd_kt_the_same_way(tmp_path, no_load):
    """The data-only K_d, K_t and kinematic part of each loaded run equal the model's, read
    from the noise-free truth, in both directions — with a no-load reference (kinematic error
    removed: K_d ≈ K_t ≈ the stiffness both ways) and without (the kinematic part included in
    K_d as the paper does, the same part on both sides). No-load runs have no stiffness."""
    bench = _bench(tmp_path, shifts=False, no_load=no_load)
    sim = simulate(bench)
    campaign = load_campaign(write_te_export(sim, bench, tmp_path / "export"))
    out, data = _agreement(campaign, sim.model, sim.truth)
    assert len(out) == 8  # the loaded runs only
    for run, metrics in data.items():
        if "_0Nm_" in run:
            assert "kd" not in metrics and "kt" not in metrics
    for run, m in out.items():
        load = float(re.search(r"_(\d+)Nm_", run).group(1))
        # the ±2° window holds ~11 samples of 0.49″ noise in the run and in its reference:
        # ~0.3″ standard error; 0.02′ (1.2″) is four of them, against the twist T/K
        tol = 0.02 * K / load
        assert m["kt"][0] == pytest.approx(m["kt"][1], rel=0.003), run
        assert m["kd"][0] == pytest.approx(m["kd"][1], rel=tol), run
        assert m["te_kinematic_180"][0] == pytest.approx(m["te_kinematic_180"][1], abs=0.02), run  # arcmin
        if no_load:
            assert m["kd"][1] == pytest.approx(K, rel=0.003) and m["kt"][1] == pytest.approx(K, rel=0.003)
        else:
            # without a reference K_d carries the kinematic part: 1/K_d − 1/K_t = kinematic / T
            kin = m["te_kinematic_180"][1]
            assert abs(kin) > 0.3
            way = 1 if run.endswith("-fw") else -1
            assert load / m["kd"][1] - load / m["kt"][1] == pytest.approx(way * kin, abs=1e-6)


def test_reference_in_another_zero_group_is_named(export):
    """A bench that re-zeroes per test: the data-only K_d against a no-load test of another zero
    says so (the fit separates the zeros; the data alone cannot)."""
    _, _, manifest = export
    data = {r["name"]: r["metrics"] for r in campaign_metrics(load_campaign(manifest))["runs"]}
    note = data["TE_486rpm_500Nm_40C-fw"]["kd"]["note"]
    assert "another zero group" in note and "TE_486rpm_0Nm_40C" in note


def test_fit_json_runs_name_the_temperatures(export):
    """fit.json's runs and temperatures_C, from the campaign the fit read (the slow fit test
    checks them in a written fit.json)."""
    from torsionfit.report._pipeline import _runs_json

    _, _, manifest = export
    campaign = load_campaign(manifest)
    doc = json.loads(json.dumps(_runs_json(campaign, temperature_term=False)))
    assert doc["temperatures_C"] == [25.0, 40.0] and doc["reference_temperature_C"] is None
    # with the temperature term on, metrics are at the median of the distinct temperatures
    assert _runs_json(campaign, temperature_term=True)["reference_temperature_C"] == 32.5
    assert doc["runs"]["TE_486rpm_1000Nm_25C-bw"] == {
        "kind": "transmission_error", "temperature_C": 25.0, "torque_Nm": 1000.0, "speed_rpm": 6.0,
        "direction": "backward", "zero_group": "TE_486rpm_1000Nm_25C",
        "reading": list(next(r for r in campaign.runs if r.name == "TE_486rpm_1000Nm_25C-bw").notes)}
    assert any("TE negated on reading" in n for n in doc["runs"]["TE_486rpm_1000Nm_25C-bw"]["reading"])


@pytest.fixture(scope="module")
def declared_fit(export):
    """The declared export fitted with the kinematic harmonics (Laplace; the default sampler's
    run of this campaign is in docs/benchmarks.md)."""
    from torsionfit.report import FitOptions, fit_campaign

    _, _, manifest = export
    return fit_campaign(load_campaign(manifest), FitOptions(
        sampler="laplace", n_starts=2, laplace_draws=2000, metric_draws=400, progress=False,
        effects={"kinematic_error": [1, 2, 39]}), seed=1)


@pytest.mark.slow
def test_declared_export_fit_recovers_the_stiffness(export, declared_fit):
    """The declared export, fitted with the kinematic harmonics: stiffness within 3 % of the
    truth and inside the 95 % HDI, the MAP converged; each test's zero comes back; K_d of the
    model (against the no-load reference) is the truth's in both directions; fit.json names
    the runs' temperatures (25 and 40 °C, fitted together: no temperature term)."""
    from torsionfit.report import fit_json, summary_table

    _, sim, manifest = export
    campaign = load_campaign(manifest)
    derived = derived_metrics_for(campaign, sim.model)
    truth = dict(zip((s.name for s in derived.specs), np.asarray(derived.evaluate(sim.truth))))
    fit = declared_fit
    doc = json.loads(json.dumps(fit_json(fit)))
    assert doc["diagnostics"]["converged"], doc["diagnostics"]
    assert doc["temperatures_C"] == [25.0, 40.0] and doc["runs"]["TE_486rpm_1000Nm_25C-fw"]["temperature_C"] == 25.0
    assert not any("_0Nm_" in name for name in doc["metrics"])  # no K_d of a no-load run
    k = doc["metrics"]["stiffness_elastic"]
    assert k["mean"] == pytest.approx(K, rel=0.03)
    assert k["hdi95"][0] <= K <= k["hdi95"][1], k
    # TE runs never reverse: the friction's pre-sliding torque is the prior's, and fit.json says so
    # (the stiffness, seen through the loads within each test, is not)
    prior = doc["diagnostics"]["prior_dominated"]
    assert "dahl_torque" in prior and "stiffness" not in prior, prior
    assert "dahl_torque" in doc["diagnostics"]["prior_dominated_note"]
    shown = summary_table(doc)  # the screen says it beside the line that says the MAP converged
    assert "sampler laplace: MAP converged" in shown and "\nprior: " in shown and "dahl_torque" in shown
    offsets = np.asarray(fit.map_result.values["te_offset"]) / ARCMIN
    np.testing.assert_allclose(offsets - offsets[0], np.asarray(SHIFTS_ARCMIN) - SHIFTS_ARCMIN[0], atol=0.05)
    for way in ("fw", "bw"):  # the truth's K_d against no load (the gap's pre-load makes it ≠ K)
        name = f"kd_mean[TE_486rpm_1000Nm_40C-{way}]"
        kd, true_kd = doc["metrics"][name], truth[name]
        assert true_kd == pytest.approx(K, rel=0.003)
        assert kd["mean"] == pytest.approx(true_kd, rel=0.03) and kd["hdi95"][0] <= true_kd <= kd["hdi95"][1], kd


@pytest.mark.slow
def test_accept_decides_the_declared_export(export, declared_fit, tmp_path, capsys):
    """accept on the declared export: a spec below the truth (K = 200 N·m/arcmin, and K_d over
    250–1000 N·m at 6 rpm) is accepted, one above it rejected, from the fitted posterior; the
    command on the undeclared export stops (exit 2) with the one-line te_convention error."""
    from torsionfit.accept import accept_campaign, parse_spec
    from torsionfit.cli import main

    def spec(limit):
        return parse_spec({"p_accept": 0.95, "requirement": [
            {"metric": "stiffness_elastic", "min": limit, "unit": "Nm/arcmin"},
            {"metric": "kd", "min": limit, "unit": "Nm/arcmin", "torque_Nm": [250.0, 1000.0], "speed_rpm": [6.0, 6.0]},
        ]}, "spec")

    fit = declared_fit
    for limit, decision in ((0.95 * K, "accept"), (1.05 * K, "reject")):
        result = accept_campaign(fit.campaign, spec(limit), fit.options, fit=fit)
        assert result.decision.decision == decision, result.decision.reason
        assert result.decision.requirement_decisions == (decision, decision)
    bench, sim, _ = export
    undeclared = write_te_export(sim, bench, tmp_path / "undeclared", declare=False)
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text('p_accept = 0.95\n[[requirement]]\nmetric = "stiffness_elastic"\nmin = 190.0\nunit = "Nm/arcmin"\n')
    assert main(["accept", str(undeclared), "--spec", str(spec_file), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "te_convention" in err and err.startswith("torsionfit accept: error:"), err


@pytest.mark.slow
@pytest.mark.extended
def test_diagnose_adds_the_kinematic_error_and_closes_to_the_noise(export):
    """Undeclared kinematic error in the declared export: diagnose adds it (orders 1, 2, 39
    among those it keeps) and the residual comes down to the noise (0.4″ on a 1″ encoder)."""
    from torsionfit.diagnose import DiagnoseOptions, diagnose

    _, _, manifest = export
    d = diagnose(load_campaign(manifest), DiagnoseOptions(), seed=3)
    added = [s.effect for s in d.steps]
    assert added == ["kinematic_error"], (added, d.final.rmse_arcsec)
    assert {1, 2, 39} <= set(d.final.effects["kinematic_error"])
    noise = math.sqrt(0.4**2 + 1 / 12)
    assert d.final.rmse_arcsec <= 1.1 * noise < 0.2 * d.base.rmse_arcsec
    assert not d.unexplained


def test_simulate_command_writes_the_export_layout(tmp_path, capsys):
    from torsionfit.cli import main

    assert main(["simulate", str(BENCH), "-o", str(tmp_path / "export")]) == 0
    assert "bench-export layout" in capsys.readouterr().out
    campaign = load_campaign(tmp_path / "export" / "campaign.toml")  # declared: reads back
    assert campaign.te_runs and not campaign.hysteresis_runs
    assert len(campaign.te_zero_groups) > 1  # one zero per test, as the export re-zeroes


def test_readme_manifest_example_reads_a_bench_export(export, tmp_path):
    """The README's TE-export manifest, completed with its backward run as its comment says,
    reads a test file the bench wrote in that layout, into the runs the bench's own manifest
    declares for that file (inline tables or [runs.columns]: the same manifest)."""
    import tomllib

    readme = (Path(__file__).parents[1] / "README.md").read_text()
    section = readme[readme.index("## TE bench exports"):]
    block = re.search(r"```toml\n(.*?)```", section, re.S).group(1)
    example = tomllib.loads(block)
    fw = example["runs"][0]
    assert fw["direction"] == "forward" and fw["columns"] == {"output_angle": "Pos_fw", "te": "TE_fw"}
    _, _, manifest = export
    written = tomllib.loads(manifest.read_text())
    ours = next(r for r in written["runs"] if r["direction"] == "forward" and r["torque_Nm"] == 1000.0
                and r["temperature_C"] == 40.0)
    assert set(fw) == set(ours), "the README example declares what the bench's manifest declares"
    # point the example at the bench's file (its logger rate, its ratio) and add the backward run
    name = Path(ours["file"]).stem
    fw |= {"name": f"{name}-fw", "file": str(manifest.parent / ours["file"]), "zero_group": name,
           "torque_Nm": ours["torque_Nm"], "input_speed_rpm": ours["input_speed_rpm"]}
    bw = fw | {"name": f"{name}-bw", "direction": "backward", "columns": {"output_angle": "Pos_bw", "te": "TE_bw"}}
    lines = block.split("[[runs]]")[0].replace("4000.0", str(written["instrument"]["sample_rate_Hz"]))
    lines = lines.replace("ratio = 81.0", f"ratio = {written['reducer']['ratio']}")
    def value(v):
        return "{ " + ", ".join(f"{k} = {json.dumps(x)}" for k, x in v.items()) + " }" if isinstance(v, dict) else json.dumps(v)

    for run in (fw, bw):
        lines += "\n[[runs]]\n" + "".join(f"{k} = {value(v)}\n" for k, v in run.items())
    path = tmp_path / "campaign.toml"
    path.write_text(lines)
    campaign = load_campaign(path)
    assert [r.direction for r in campaign.runs] == [1, -1]  # forward, backward
    assert len(campaign.te_zero_groups) == 1
    np.testing.assert_allclose(campaign.runs[0].speed_rpm, ours["input_speed_rpm"] / written["reducer"]["ratio"])
