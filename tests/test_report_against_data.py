"""The model's metrics against the data's own reading of them (report/_against_data.py), on
SYNTHETIC loops built here: a play operator (Coulomb friction) on the torque, a linear spring
and a tanh gap, five ±4 N·m play cycles then three ±40 N·m stiffness cycles per run."""

import math
from pathlib import Path

import numpy as np
import pytest

from torsionfit.accept._decision import INDETERMINATE, decide_unit
from torsionfit.io import Campaign, HysteresisRun, Instrument, Reducer
from torsionfit.report._against_data import TOLERANCE_SE, against_data, data_readings, off_data_note

DEG = math.pi / 180.0
ARCMIN = DEG / 60.0
T_F = 0.6  # N·m, friction of the play operator
GAP, EPS_GAP = 0.5 * DEG, 0.05  # rad, N·m


def _loop(knots, compliance_deg_per_Nm: float = 0.09, fs: float = 50.0, rate: float = 4.0, friction: float = T_F):
    """Time (s), torque (N·m) ramped through ``knots`` at ``rate`` N·m/s, and the angle (rad)."""
    tau = np.concatenate([np.linspace(a, b, max(2, int(abs(b - a) / rate * fs)), endpoint=False)
                          for a, b in zip(knots[:-1], knots[1:])] + [np.zeros(1)])
    mesh, state = np.empty_like(tau), 0.0
    for i, t in enumerate(tau):
        state = min(max(state, t - friction), t + friction)
        mesh[i] = state
    theta = compliance_deg_per_Nm * DEG * mesh + 0.5 * GAP * np.tanh(mesh / EPS_GAP)
    return np.arange(tau.size) / fs, tau, theta


def _record(compliance_deg_per_Nm: float, fs: float = 50.0, rate: float = 4.0):
    knots = [0.0, 4.0] + [-4.0, 4.0] * 5 + [0.0, 40.0, -40.0, 40.0, -40.0, 40.0, -40.0, 0.0]
    return _loop(knots, compliance_deg_per_Nm, fs, rate)


def _campaign(*compliances) -> Campaign:
    runs = []
    for i, c in enumerate(compliances):
        t, tau, theta = _record(c)
        runs.append(HysteresisRun(name=f"run-{i}", time_s=t, torque_Nm=tau, angle_rad=theta))
    return Campaign(Reducer("u"), Instrument(), tuple(runs))


def test_data_readings_are_the_data_only_metrics_in_the_model_metrics_units():
    readings = data_readings(_campaign(0.09))
    play = readings["play"]
    expected = (2 * T_F * 0.09 * DEG + GAP * math.tanh(T_F / EPS_GAP)) / ARCMIN
    assert play["unit"] == "arcmin" and play["value"] == pytest.approx(expected, rel=2e-3)
    assert play["se"] == pytest.approx(0.0, abs=1e-6)  # identical cycles
    k = readings["stiffness_loading"]
    assert k["unit"] == "Nm/arcmin" and k["value"] == pytest.approx(1.0 / (0.09 * 60.0), rel=2e-3)
    assert readings["compliance_loading_pos"]["value"] == pytest.approx(0.09, rel=2e-3)
    assert readings["compliance_loading_neg"]["run"] == "run-0"
    # two runs: the play where the smallest cycles are, the slope where the largest are
    two = data_readings(_campaign(0.08, 0.10))
    assert two["compliance_loading_pos"]["value"] == pytest.approx(0.08, rel=2e-3)
    # no hysteresis cycles to read: nothing
    t = np.linspace(0.0, 10.0, 200)
    flat = Campaign(Reducer("u"), Instrument(), (HysteresisRun(name="ramp", time_s=t, torque_Nm=t, angle_rad=1e-4 * t),))
    assert data_readings(flat) == {}


def _metrics(mean, lo, hi, unit="Nm/arcmin"):
    return {"stiffness_loading": {"mean": mean, "sd": 1.0, "hdi95": [lo, hi], "unit": unit, "description": ""}}


def test_a_model_interval_that_misses_the_datas_reading_is_flagged_with_one_line():
    reading = {"stiffness_loading": {"value": 10.0, "se": 0.2, "unit": "Nm/arcmin", "run": "r"}}
    inside = _metrics(10.5, 10.3, 10.7)  # misses by 0.3 < 2 s.e.: the reading may scatter so far
    assert against_data(inside, reading) == [] and inside["stiffness_loading"]["data"]["within"] is True
    off = _metrics(11.2, 10.5, 11.8)  # misses by 0.5 > 2 s.e.
    assert against_data(off, reading) == ["stiffness_loading"]
    assert off["stiffness_loading"]["data"] == {**reading["stiffness_loading"], "within": False}
    note = off_data_note(off, ["stiffness_loading"])
    assert "\n" not in note and "stiffness_loading 11.2" in note and "10.5–11.8" in note and "10 ± 0.2 Nm/arcmin" in note
    assert 0.5 > TOLERANCE_SE * 0.2
    # one cycle: no standard error, so no judgement (within None), never a flag
    single = {"stiffness_loading": {**reading["stiffness_loading"], "se": None}}
    far = _metrics(20.0, 19.0, 21.0)
    assert against_data(far, single) == [] and far["stiffness_loading"]["data"]["within"] is None
    # a metric the data read in another unit than the model's entry: not compared
    other = _metrics(20.0, 19.0, 21.0, unit="deg/Nm")
    assert against_data(other, reading) == [] and "data" not in other["stiffness_loading"]


def test_a_withheld_decision_is_indeterminate_with_its_reason():
    conform = np.ones((100, 2), bool)  # every draw meets both requirements
    d = decide_unit(conform, ["k_loading", "lost_motion"], 0.95, withheld_reason="the model does not draw stiffness_loading")
    assert d.decision == INDETERMINATE and set(d.requirement_decisions) == {INDETERMINATE}
    assert d.reason.startswith("no decision: the model does not draw stiffness_loading; joint p_c would be 1")
    assert decide_unit(conform, ["k_loading", "lost_motion"], 0.95).decision != INDETERMINATE


def test_the_record_reader_reads_the_datas_angles_as_the_data_only_metrics_do():
    """The model's reading (report/_record.py, JAX, vectorised over draws) applied to the
    data's own angles gives the data-only numbers: same ramps, grids, bins, fit ranges."""
    from torsionfit.metrics import cycle_classes, loading_fit, play_of
    from torsionfit.report._record import record_classes, record_reader

    campaign = _campaign(0.09)
    run = campaign.runs[0]
    theta = run.angle_rad + 2e-5 * np.sin(run.time_s)  # a slow wander: branches differ cycle to cycle
    classes = cycle_classes(run.time_s, run.torque_Nm, theta)
    play = play_of(classes.smallest)
    fit = loading_fit(classes.largest, play)
    reader = record_reader(record_classes(Campaign(Reducer("u"), Instrument(), (
        HysteresisRun(name="r", time_s=run.time_s, torque_Nm=run.torque_Nm, angle_rad=theta),))))
    got = [float(v) for v in reader.read_angles(theta, theta)]
    assert got == pytest.approx([play, fit.compliance_pos, fit.compliance_neg], rel=1e-9)
    # a loop whose loading branch never gets past half the play: NaN (a draw left out), not a number
    flat = np.where(np.abs(run.torque_Nm) > 4.5, 0.0, theta)
    assert np.isnan(float(reader.read_angles(theta, flat)[1]))


MEASURED = Path(__file__).resolve().parents[1] / "examples" / "cycloidal-jv" / "split-pccf-preload2-pos1.toml"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "data" / "cycloidal-jv"


@pytest.mark.skipif(not SHARED.is_dir(), reason=f"measured data absent: {SHARED}")
def test_on_a_measured_loop_the_reader_and_the_readings_are_the_data_only_metrics():
    """REAL measured loop (JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0, read from
    ../shared/data): the reader applied to the file's angles gives the data-only play and
    loading compliances, and each reading has a standard error from its cycles (5 play
    ramps, 2–3 large branches per side), a small fraction of the value."""
    from torsionfit.io import decimate, load_campaign
    from torsionfit.metrics import cycle_classes, loading_fit, play_of
    from torsionfit.report._record import record_classes, record_reader

    campaign = decimate(load_campaign(MEASURED), 16)
    run = campaign.runs[0]
    classes = cycle_classes(run.time_s, run.torque_Nm, run.angle_rad)
    play = play_of(classes.smallest)
    fit = loading_fit(classes.largest, play)
    reader = record_reader(record_classes(campaign))
    theta = np.asarray(run.angle_rad)
    got = [float(v) for v in reader.read_angles(theta, theta)]
    assert got == pytest.approx([play, fit.compliance_pos, fit.compliance_neg], rel=1e-6)
    readings = data_readings(campaign)
    assert readings["play"]["value"] == pytest.approx(play / ARCMIN, rel=1e-9)
    for name, r in readings.items():
        assert r["run"] == "preload2-pos1" and 0 < r["se"] < 0.05 * r["value"], (name, r)


LOADING = ("stiffness_loading", "compliance_loading_pos", "compliance_loading_neg")


@pytest.mark.parametrize("knots, left_out", [
    ([0.0, 4.0, -4.0, 0.0, 40.0, -40.0, 40.0, -40.0, 40.0, -40.0, 0.0], ("play",)),
    ([0.0, 4.0, -4.0, 4.0, -4.0, 4.0, -4.0, 0.0, 40.0, -40.0, 0.0], LOADING),
], ids=["one-play-ramp", "one-stiffness-ramp"])
def test_ramps_that_form_no_loop_leave_their_metrics_out_of_the_fit_with_the_reason(knots, left_out):
    """SYNTHETIC: one ±4 N·m play ramp (0 → + → − → 0) before three ±40 N·m cycles, or play
    cycles before one ±40 N·m ramp. The single ramp has no increasing branch across zero: no
    play (no loading slope) from the data or the model — before, both read the other cycles'
    width (slope) as the play (the stiffness ramps') — named in the fit's metrics_not_computed;
    the other class metrics are reported and checked against the data's."""
    from torsionfit.report import FitOptions, fit_campaign, fit_json
    from torsionfit.report._record import record_classes

    t, tau, theta = _loop(knots, fs=12.5)
    theta += np.random.default_rng(1).normal(0.0, 2e-5, theta.size)
    campaign = Campaign(Reducer("u", rated_torque_Nm=40.0), Instrument(), (
        HysteresisRun(name="r", time_s=t, torque_Nm=tau, angle_rad=theta),))
    classes = record_classes(campaign)
    assert "run in one direction only" in (classes.play_note if left_out == ("play",) else classes.loading_note)
    readings = data_readings(campaign)
    assert not set(left_out) & set(readings) and len(readings) == 4 - len(left_out)
    with pytest.warns(UserWarning, match=f"metrics not computed: {left_out[0]}: hysteresis run 'r'"):
        fit = fit_campaign(campaign, FitOptions(sampler="laplace", progress=False, laplace_draws=100, metric_draws=20), seed=0)
    doc = fit_json(fit)
    assert set(doc["diagnostics"]["metrics_not_computed"]) == set(left_out)
    assert not set(left_out) & set(doc["metrics"])
    for name in readings:  # what the data read, the model reports and is checked against
        assert doc["metrics"][name]["data"]["within"] is not None
    if left_out == ("play",):
        assert "no play:" in doc["metrics"]["stiffness_loading"]["description"]
        assert doc["metrics"]["compliance_loading_pos"]["mean"] == pytest.approx(0.09, rel=0.05)


def test_ramps_that_form_no_loop_give_no_record_readings_of_what_they_would_hold():
    """SYNTHETIC: one stiffness ramp after the play cycles gives the play alone; one play ramp
    and one stiffness ramp around ±20 N·m cycles give neither (no record), and the model's
    metrics leave them out with the reason (the specs and values the fit reports agree)."""
    from torsionfit.report._derived import derived_metrics_for
    from torsionfit.report._pipeline import campaign_model
    from torsionfit.report._record import record_classes

    def campaign(knots):
        t, tau, theta = _loop(knots)
        return Campaign(Reducer("u", rated_torque_Nm=40.0), Instrument(), (
            HysteresisRun(name="r", time_s=t, torque_Nm=tau, angle_rad=theta),))

    one_large = campaign([0.0, 4.0, -4.0, 4.0, -4.0, 0.0, 40.0, -40.0, 0.0])
    classes = record_classes(one_large)
    assert classes.play_note is None and "its largest ramps" in classes.loading_note
    assert set(data_readings(one_large)) == {"play"}
    derived = derived_metrics_for(one_large, campaign_model(one_large))
    names = [s.name for s in derived.specs]
    assert "play" in names and "stiffness_loading" not in names
    assert set(derived.not_read_notes()) == {"stiffness_loading", "compliance_loading_pos", "compliance_loading_neg"}
    neither = campaign([0.0, 4.0, -4.0, 0.0, 20.0, -20.0, 20.0, -20.0, 0.0, 40.0, -40.0, 0.0])
    assert record_classes(neither) is None and data_readings(neither) == {}


def test_a_metric_read_on_no_draw_is_left_out_with_its_reason_and_the_others_are_reported():
    """SYNTHETIC: only ±4 N·m cycles whose friction (2.5 N·m) holds the twist past half their
    peak: the loading slope has no range beyond the play, for the data and for the model alike.
    The fit reports every other metric and names the loading metrics with the data's reason
    (it once dropped every draw and stopped on an empty interval)."""
    from torsionfit.report import FitOptions, fit_campaign, fit_json, summary_table

    t, tau, theta = _loop([0.0, 4.0] + [-4.0, 4.0] * 4 + [0.0], friction=2.5)
    theta += np.random.default_rng(0).normal(0.0, 2e-6, theta.size)
    campaign = Campaign(Reducer("u", rated_torque_Nm=4.0), Instrument(), (
        HysteresisRun(name="small", time_s=t, torque_Nm=tau, angle_rad=theta),))
    with pytest.warns(UserWarning, match="metrics not computed: stiffness_loading"):
        fit = fit_campaign(campaign, FitOptions(sampler="laplace", progress=False, laplace_draws=200, metric_draws=40), seed=0)
    doc = fit_json(fit)
    left_out = doc["diagnostics"]["metrics_not_computed"]
    assert set(left_out) == {"stiffness_loading", "compliance_loading_pos", "compliance_loading_neg"}, left_out
    assert all("on any of 40 draws" in n and "the data-only reading fails as well" in n for n in left_out.values())
    assert "play" in doc["metrics"] and not set(left_out) & set(doc["metrics"])
    assert all(np.isfinite(e["mean"]) for e in doc["metrics"].values())
    assert "not computed: stiffness_loading:" in summary_table(doc)
    # acceptance reads its requirements' draws by column: the right ones with metrics left out,
    # and a requirement on a metric not computed stops with one line
    from torsionfit._errors import InputError
    from torsionfit.accept import accept_campaign, parse_spec

    spec = parse_spec({"requirement": [{"metric": "play", "max": 1e4, "unit": "arcmin", "name": "P"},
                                       {"metric": "backlash", "max": 1e4, "unit": "arcmin", "name": "B"}]}, "test spec")
    unit = accept_campaign(campaign, spec, fit.options, envelope=False, fit=fit)
    names = [m.name for m in fit.metric_specs]
    for b, q in zip(unit.bound, unit.quantities.T):
        assert np.array_equal(q, fit.metric_draws[:, names.index(b.requirement.metric)])
    loading = parse_spec({"requirement": [{"metric": "stiffness_loading", "min": 0.01, "unit": "Nm/arcmin"}]}, "test spec")
    with pytest.raises(InputError, match=r"stiffness_loading is not computed for this unit \(its definition reads no value"):
        accept_campaign(campaign, loading, fit.options, envelope=False, fit=fit)
