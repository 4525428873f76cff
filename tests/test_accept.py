"""Acceptance decisions (DESIGN §4): spec files, units, the decision rule, the CLI, and the
guarded-acceptance promise on SYNTHETIC bench units with known truth.

Every unit here is SYNTHETIC: ``tests/benches/stat_rv_white.toml`` (one hysteresis loop of 381
samples and TE runs of 181 samples forward at 380 N·m and backward at 190 N·m, 1″ angle noise,
1″ encoder steps, 1.5 N·m torque noise), with its truth varied per unit. Fits use the Laplace
approximation (2 MAP starts, 300 draws for the metrics and decisions) — seconds per unit instead
of minutes — and every unit has the same run shapes, so the fit compiles once for the file.
The truth of a unit is judged by the same rule as the posterior draws
(``requirement_quantities`` of the true parameters). Seeds are fixed in advance.
"""

import dataclasses
import json
import warnings
from pathlib import Path
from types import SimpleNamespace

import jax.numpy as jnp
import numpy as np
import pytest

from torsionfit import InputError
from torsionfit.accept import (
    ACCEPT,
    ERROR,
    EXIT_CODE,
    INDETERMINATE,
    REJECT,
    accept_campaign,
    batch_exit_code,
    bind_requirements,
    bind_to_campaign,
    conformance,
    decide,
    decide_unit,
    extrapolation,
    load_spec,
    measured_region,
    parse_spec,
    requirement_quantities,
)
from torsionfit.bench import load_bench, simulate
from torsionfit.cli import main
from torsionfit.io import write_campaign
from torsionfit.report import FitOptions, MetricSpec
from torsionfit.units import convert, quantity_of

BENCH = Path(__file__).parent / "benches" / "stat_rv_white.toml"
OPTIONS = FitOptions(sampler="laplace", n_starts=2, laplace_draws=600, metric_draws=300, progress=False)
REGION = {"torque_Nm": [300.0, 380.0], "speed_rpm": [1.0, 10.0]}
#: the three requirements of the bench tests: (metric, bound, unit)
REQUIREMENTS = (("stiffness_elastic", "min", "Nm/arcmin"), ("lost_motion", "max", "arcmin"), ("kd", "min", "Nm/arcmin"))

DESIGN_SPEC = """
p_accept = 0.95                 # guarded acceptance threshold on p_c
[[requirement]]
metric = "stiffness_elastic"    # any metric name of fit.json
min = 80.0
unit = "Nm/arcmin"
[[requirement]]
metric = "lost_motion"
max = 1.5
unit = "arcmin"
[[requirement]]
metric = "kd"                   # dynamic stiffness over an operating region (TE campaigns)
min = 85.0
unit = "Nm/arcmin"
torque_Nm = [95.0, 380.0]
speed_rpm = [1.0, 20.0]
"""


# --- helpers -----------------------------------------------------------------------------------
def bench_spec(limits, p_accept: float = 0.95):
    """The three bench requirements with ``limits`` (metric units), as a parsed spec."""
    entries = []
    for (metric, bound, unit), limit in zip(REQUIREMENTS, limits):
        entry = {"metric": metric, bound: float(limit), "unit": unit}
        if metric == "kd":
            entry.update(REGION)
        entries.append(entry)
    return parse_spec({"p_accept": p_accept, "requirement": entries}, "SYNTHETIC test spec")


def truth_quantities(sim) -> np.ndarray:
    """The three requirement quantities of a simulated unit's true parameters."""
    bound, derived = bind_to_campaign(bench_spec([1.0, 1.0, 1.0]), sim.campaign, OPTIONS)
    truth = {k: jnp.asarray(v)[None] for k, v in sim.truth.items()}
    return requirement_quantities(bound, derived, truth)[0]


def shifted_limits(q, factor_outside):
    """Limits ``factor_outside`` (relative) beyond the quantities ``q``: > 0 puts the truth out of
    spec, < 0 inside, 0 exactly on the limit."""
    signs = np.array([1.0 if bound == "min" else -1.0 for _, bound, _ in REQUIREMENTS])
    return q * (1 + signs * np.asarray(factor_outside, float))


def decide_sim(sim, limits, seed):
    return accept_campaign(sim.campaign, bench_spec(limits), OPTIONS, seed=seed, envelope=False)


@pytest.fixture(scope="module")
def bench():
    return load_bench(BENCH)


def metric_catalogue():
    return [MetricSpec("stiffness_elastic", "Nm/arcmin", ""), MetricSpec("lost_motion", "arcmin", ""),
            MetricSpec("dissipated_energy", "J", ""), MetricSpec("kd_mean[te-1]", "Nm/arcmin", "")]


# --- spec files --------------------------------------------------------------------------------
def test_design_spec_parses(tmp_path):
    path = tmp_path / "spec.toml"
    path.write_text(DESIGN_SPEC)
    spec = load_spec(path)
    assert spec.p_accept == 0.95 and spec.path == path
    assert [(r.metric, r.bound, r.limit, r.unit) for r in spec.requirements] == [
        ("stiffness_elastic", "min", 80.0, "Nm/arcmin"), ("lost_motion", "max", 1.5, "arcmin"), ("kd", "min", 85.0, "Nm/arcmin")]
    kd = spec.requirements[2]
    assert kd.is_kd and kd.torque_range_Nm == (95.0, 380.0) and kd.speed_range_rpm == (1.0, 20.0)
    assert len({r.name for r in spec.requirements}) == 3


def test_default_p_accept_and_names():
    spec = parse_spec({"requirement": [{"metric": "backlash", "max": 60, "unit": "arcsec", "name": "B"},
                                       {"metric": "backlash", "min": 10, "unit": "arcsec"}]})
    assert spec.p_accept == 0.95
    assert [r.name for r in spec.requirements] == ["B", "backlash >= 10 arcsec"]


GOOD = {"metric": "lost_motion", "max": 1.5, "unit": "arcmin"}
KD_GOOD = {"metric": "kd", "min": 85.0, "unit": "Nm/arcmin", **REGION}

SPEC_ERRORS = [
    ({"p_acept": 0.9, "requirement": [GOOD]}, r"unknown key 'p_acept' in the top level \(did you mean 'p_accept'\?\)"),
    ({"p_accept": "high", "requirement": [GOOD]}, "p_accept must be a finite number"),
    ({"p_accept": True, "requirement": [GOOD]}, "p_accept must be a finite number"),
    ({"p_accept": 0.5, "requirement": [GOOD]}, r"p_accept must be in \(0.5, 1\)"),
    ({"p_accept": 1.0, "requirement": [GOOD]}, r"p_accept must be in \(0.5, 1\)"),
    ({"p_accept": 0.3, "requirement": [GOOD]}, r"p_accept must be in \(0.5, 1\)"),
    ({}, "no requirements"),
    ({"requirement": []}, "no requirements"),
    ({"requirement": GOOD}, r"array of tables, written as \[\[requirement\]\]"),
    ({"requirement": [{"max": 1.5, "unit": "arcmin"}]}, r"requirement\[0\]: missing required key 'metric'"),
    ({"requirement": [{**GOOD, "maxx": 2}]}, r"requirement\[0\] \(metric 'lost_motion'\): unknown key 'maxx'"),
    ({"requirement": [{**GOOD, "torque_Nm": [1.0, 2.0]}]}, r"unknown key 'torque_Nm' .*belong to metric = 'kd'"),
    ({"requirement": [GOOD, {**GOOD, "min": 0.5}]}, r"requirement\[1\] .*exactly one of min or max, got both"),
    ({"requirement": [{"metric": "lost_motion", "unit": "arcmin"}]}, "exactly one of min or max, got neither"),
    ({"requirement": [{**GOOD, "max": "1.5"}]}, "max must be a finite number, got '1.5'"),
    ({"requirement": [{**GOOD, "max": float("nan")}]}, "max must be a finite number"),
    ({"requirement": [{"metric": "lost_motion", "max": 1.5}]}, "missing required key 'unit'"),
    ({"requirement": [{**GOOD, "unit": "arcmins"}]}, r"requirement\[0\] .*unknown unit 'arcmins'"),
    ({"requirement": [{**KD_GOOD, "unit": "arcmin"}]}, "unit 'arcmin' is a unit of angle, but 'Nm/arcmin'"),
    ({"requirement": [{**KD_GOOD, "max": 90.0}]}, "unknown key 'max' in a kd requirement"),
    ({"requirement": [{k: v for k, v in KD_GOOD.items() if k != "torque_Nm"}]}, "missing required key 'torque_Nm'"),
    ({"requirement": [{k: v for k, v in KD_GOOD.items() if k != "speed_rpm"}]}, "missing required key 'speed_rpm'"),
    ({"requirement": [{**KD_GOOD, "torque_Nm": [380.0, 95.0]}]}, r"torque_Nm must be \[lo, hi\] with > 0 lo <= hi"),
    ({"requirement": [{**KD_GOOD, "torque_Nm": [0.0, 95.0]}]}, r"torque_Nm must be \[lo, hi\]"),
    ({"requirement": [{**KD_GOOD, "speed_rpm": [1.0, 2.0, 3.0]}]}, r"speed_rpm must be \[lo, hi\] with >= 0"),
    ({"requirement": [{**KD_GOOD, "speed_rpm": [-1.0, 2.0]}]}, r"speed_rpm must be \[lo, hi\]"),
    ({"requirement": [{**KD_GOOD, "speed_rpm": "1-20"}]}, r"speed_rpm must be \[lo, hi\]"),
    ({"requirement": [{**GOOD, "name": "a"}, {**GOOD, "max": 2.0, "name": "a"}]}, "name 'a' is already used by"),
    ({"requirement": [{**GOOD, "name": 3}]}, "name must be a non-empty string"),
    ({"label": 5, "requirement": [GOOD]}, "label must be a non-empty string"),
]


@pytest.mark.parametrize("doc, match", SPEC_ERRORS)
def test_spec_errors_are_one_line_naming_file_and_key(doc, match):
    with pytest.raises(InputError, match=match) as err:
        parse_spec(doc, "line.toml")
    text = str(err.value)
    assert text.startswith("line.toml: ") and "\n" not in text, text


def test_spec_file_errors(tmp_path):
    with pytest.raises(InputError, match="spec file not found"):
        load_spec(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("p_accept = \n")
    with pytest.raises(InputError, match=f"{bad}: TOML syntax error"):
        load_spec(bad)


BIND_ERRORS = [
    ({"metric": "lost_motoin", "max": 1.0, "unit": "arcmin"}, True, "unknown metric 'lost_motoin'; this campaign's metrics are stiffness_elastic"),
    ({"metric": "kd_mean[te-2]", "min": 1.0, "unit": "Nm/arcmin"}, True, r"unknown metric 'kd_mean\[te-2\]'"),
    ({"metric": "lost_motion", "max": 1.0, "unit": "Nm/arcmin"}, True, "unit 'Nm/arcmin' is a unit of stiffness, but 'arcmin' .* angle"),
    ({"metric": "dissipated_energy", "max": 1.0, "unit": "Nm"}, True, "unit 'Nm' is a unit of torque, but 'J'"),
    (KD_GOOD, False, "K_d over an operating region needs TE runs"),
]


@pytest.mark.parametrize("entry, has_te, match", BIND_ERRORS)
def test_binding_to_a_campaign_checks_metric_and_unit(entry, has_te, match):
    spec = parse_spec({"requirement": [entry]}, "s.toml")
    with pytest.raises(InputError, match=match) as err:
        bind_requirements(spec, metric_catalogue(), has_te)
    assert str(err.value).startswith("s.toml: requirement[0]"), str(err.value)


def test_binding_converts_limits_to_the_metric_unit():
    spec = parse_spec({"requirement": [
        {"metric": "lost_motion", "max": 90.0, "unit": "arcsec"},
        {"metric": "stiffness_elastic", "min": 1.0, "unit": "Nm/deg"},
        {"metric": "dissipated_energy", "max": 20.0, "unit": "mJ"},
        {"metric": "kd_mean[te-1]", "min": 80.0, "unit": "Nm/arcmin"},
        {"metric": "kd", "min": 6000.0, "unit": "Nm/deg", **REGION}]})
    bound = bind_requirements(spec, metric_catalogue(), True)
    assert [b.column for b in bound] == [1, 0, 2, 3, None]
    assert [b.metric_unit for b in bound] == ["arcmin", "Nm/arcmin", "J", "Nm/arcmin", "Nm/arcmin"]
    np.testing.assert_allclose([b.limit_in_metric_unit for b in bound], [1.5, 1 / 60, 0.02, 80.0, 100.0], rtol=1e-12)


# --- units -------------------------------------------------------------------------------------
def test_unit_conversion():
    assert convert(90.0, "arcsec", "arcmin") == pytest.approx(1.5)
    assert convert(6000.0, "Nm/deg", "Nm/arcmin") == pytest.approx(100.0)
    assert convert(1.0, "kNm", "Nm") == pytest.approx(1000.0)
    assert convert(1.0, "rev", "deg") == pytest.approx(360.0)
    assert convert(0.1, "Nm/arcmin", "Nm/arcmin") == 0.1  # exact, no round trip through SI
    assert quantity_of("Nm/arcsec") == "stiffness" and quantity_of("mJ") == "energy"
    with pytest.raises(InputError, match="here: unknown unit 'N m'"):
        convert(1.0, "N m", "Nm", "here")
    with pytest.raises(InputError, match="here: unit 'deg' is a unit of angle, but 'Nm' .* torque"):
        convert(1.0, "deg", "Nm", "here")


# --- decision rule -----------------------------------------------------------------------------
@pytest.mark.parametrize("p, p_accept, expected", [
    (0.95, 0.95, ACCEPT), (0.05, 0.95, REJECT), (0.9, 0.9, ACCEPT), (0.1, 0.9, REJECT),
    (1900 / 2000, 0.95, ACCEPT), (100 / 2000, 0.95, REJECT), (1899 / 2000, 0.95, INDETERMINATE),
    (101 / 2000, 0.95, INDETERMINATE), (0.5, 0.95, INDETERMINATE), (1.0, 0.99, ACCEPT), (0.0, 0.99, REJECT),
    (0.98, 0.99, INDETERMINATE), (0.6, 0.6, ACCEPT), (0.4, 0.6, REJECT), (0.5, 0.6, INDETERMINATE),
])
def test_decide_thresholds_are_inclusive_and_exact(p, p_accept, expected):
    assert decide(p, p_accept) == expected


def _conform(columns) -> np.ndarray:
    return np.stack([np.asarray(c, bool) for c in columns], axis=1)


def test_joint_probability_comes_from_the_same_draws():
    """Two requirements met on the same 96 of 100 draws: joint p_c = 0.96 (accept), where the
    product of the marginals, 0.9216, would not accept; met on different draws, the joint p_c
    is lower than the product."""
    same = np.arange(100) < 96
    d = decide_unit(_conform([same, same]), ["a", "b"], 0.95)
    assert d.p_conform == pytest.approx(0.96) and d.decision == ACCEPT
    assert d.requirement_p_conform == pytest.approx((0.96, 0.96))
    assert d.consumer_risk == pytest.approx(0.04) and d.producer_risk is None
    apart = _conform([np.arange(100) >= 4, np.arange(100) < 96])
    d = decide_unit(apart, ["a", "b"], 0.95)
    assert d.p_conform == pytest.approx(0.92) and d.decision == INDETERMINATE
    assert d.requirement_decisions == (ACCEPT, ACCEPT)
    assert d.consumer_risk is None and d.producer_risk is None


def test_reject_reports_producer_risk_and_the_failing_requirement():
    d = decide_unit(_conform([np.ones(200), np.arange(200) < 6]), ["stiff", "lost"], 0.95)
    assert d.decision == REJECT and d.p_conform == pytest.approx(0.03)
    assert d.producer_risk == pytest.approx(0.03) and d.consumer_risk is None
    assert d.requirement_decisions == (ACCEPT, REJECT)
    assert "failing: lost" in d.reason and "stiff (p_c" not in d.reason


def test_no_decision_without_convergence():
    d = decide_unit(_conform([np.ones(50)]), ["a"], 0.95, converged=False, not_converged_reason="R-hat 1.3")
    assert d.decision == INDETERMINATE and d.requirement_decisions == (INDETERMINATE,)
    assert d.p_conform == 1.0 and d.consumer_risk is None and d.producer_risk is None
    assert "not converged" in d.reason and "R-hat 1.3" in d.reason
    d = decide_unit(_conform([np.zeros(50)]), ["a"], 0.95, converged=False)
    assert d.decision == INDETERMINATE and "converged: false" in d.reason


def test_conformance_limits_are_inclusive():
    spec = parse_spec({"requirement": [{"metric": "stiffness_elastic", "min": 100.0, "unit": "Nm/arcmin"},
                                       {"metric": "lost_motion", "max": 1.0, "unit": "arcmin"}]})
    bound = bind_requirements(spec, metric_catalogue(), True)
    q = np.array([[100.0, 1.0], [99.99, 1.0], [100.0, 1.01], [120.0, 0.5]])
    assert conformance(bound, q).tolist() == [[True, True], [False, True], [True, False], [True, True]]


def test_batch_exit_code():
    row = lambda d: {"decision": d}  # noqa: E731
    assert batch_exit_code([row(ACCEPT), row(ACCEPT)]) == 0
    assert batch_exit_code([row(ACCEPT), row(REJECT)]) == 3
    assert batch_exit_code([row(REJECT), row(INDETERMINATE), row(ACCEPT)]) == 4
    assert batch_exit_code([row(INDETERMINATE), row(ERROR)]) == 2
    assert EXIT_CODE == {ACCEPT: 0, REJECT: 3, INDETERMINATE: 4}


# --- CLI without fitting -----------------------------------------------------------------------
def test_accept_help_documents_exit_codes(capsys):
    with pytest.raises(SystemExit):
        main(["accept", "--help"])
    out = capsys.readouterr().out
    assert "0 accept, 3 reject, 4 indeterminate" in out and "--spec" in out and "--sampler" in out


@pytest.fixture(scope="module")
def unit_folder(tmp_path_factory, bench):
    """One SYNTHETIC unit written as campaign files."""
    folder = tmp_path_factory.mktemp("unit")
    write_campaign(simulate(bench, seed=5).campaign, folder, label=bench.label)
    return folder


@pytest.mark.parametrize("spec_text, fragment", [
    ("p_accept = 2.0\n[[requirement]]\nmetric = 'lost_motion'\nmax = 1.0\nunit = 'arcmin'\n", "p_accept must be in"),
    ("[[requirement]]\nmetric = 'lost_motoin'\nmax = 1.0\nunit = 'arcmin'\n", "unknown metric 'lost_motoin'"),
    ("[[requirement]]\nmetric = 'lost_motion'\nmax = 1.0\nunit = 'Nm'\n", "unit 'Nm' is a unit of torque"),
])
def test_accept_bad_spec_is_exit_2_before_any_fit(tmp_path, unit_folder, spec_text, fragment, capsys):
    (tmp_path / "spec.toml").write_text(spec_text)
    code = main(["accept", str(unit_folder / "campaign.toml"), "--spec", str(tmp_path / "spec.toml"),
                 "-o", str(tmp_path / "out"), "--sampler", "laplace"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and fragment in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "out" / "accept.json").exists()


def test_accept_missing_campaign_is_exit_2(tmp_path, capsys):
    (tmp_path / "spec.toml").write_text(DESIGN_SPEC)
    code = main(["accept", str(tmp_path / "none.toml"), "--spec", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "o")])
    assert code == 2 and "campaign manifest not found" in capsys.readouterr().err


# --- bench units: far inside, far outside, on the limit ----------------------------------------
@pytest.mark.slow
def test_unit_far_inside_is_accepted(bench):
    sim = simulate(bench, seed=21)
    q = truth_quantities(sim)
    result = decide_sim(sim, shifted_limits(q, [-0.1, -0.1, -0.1]), seed=21)
    d = result.decision
    print(f"\n[far inside] truth {q.round(4)}, p_c {d.requirement_p_conform}, joint {d.p_conform}")
    assert d.decision == ACCEPT and d.requirement_decisions == (ACCEPT,) * 3
    assert d.p_conform == 1.0 and d.consumer_risk == pytest.approx(1 / d.n_draws) and d.risk_is_bound


@pytest.mark.slow
def test_unit_far_outside_is_rejected(bench):
    sim = simulate(bench, seed=22)
    q = truth_quantities(sim)
    all_out = decide_sim(sim, shifted_limits(q, [0.1, 0.1, 0.1]), seed=22).decision
    assert all_out.decision == REJECT and all_out.requirement_decisions == (REJECT,) * 3 and all_out.p_conform == 0.0
    lost_out = decide_sim(sim, shifted_limits(q, [-0.1, 0.1, -0.1]), seed=22).decision
    print(f"\n[far outside] all three: {all_out.reason}\n[far outside] lost motion only: {lost_out.reason}")
    assert lost_out.decision == REJECT and lost_out.requirement_decisions == (ACCEPT, REJECT, ACCEPT)
    assert lost_out.producer_risk == pytest.approx(1 / lost_out.n_draws) and lost_out.risk_is_bound
    assert "failing: lost_motion" in lost_out.reason


#: units with the truth exactly on one limit (each requirement in turn), the others 10 % inside
ON_LIMIT_SEEDS = range(40, 70)
#: with calibrated posteriors p_c is uniform on (0, 1) for a truth on the limit, so each unit is
#: indeterminate with probability 0.9: ≥ 21 of 30 fails by chance with probability 0.15 %
ON_LIMIT_MIN_INDETERMINATE = 21


@pytest.mark.slow
def test_truth_on_the_limit_is_indeterminate(bench):
    decisions, p = [], []
    for i, seed in enumerate(ON_LIMIT_SEEDS):
        sim = simulate(bench, seed=seed)
        shift = [-0.1, -0.1, -0.1]
        shift[i % 3] = 0.0
        d = decide_sim(sim, shifted_limits(truth_quantities(sim), shift), seed=seed).decision
        decisions.append(d.decision)
        p.append(d.requirement_p_conform[i % 3])
    n = decisions.count(INDETERMINATE)
    message = (f"{n} of {len(decisions)} indeterminate ({decisions.count(ACCEPT)} accept, {decisions.count(REJECT)} "
               f"reject); p_c of the requirement on its limit: {np.round(p, 3).tolist()}")
    print("\n[on the limit] " + message)
    assert n >= ON_LIMIT_MIN_INDETERMINATE, message


@pytest.mark.slow
def test_unconverged_chain_gives_indeterminate(bench):
    """emcee stopped long before 50 autocorrelation times: the unit is far inside the spec, yet
    the answer is indeterminate with the sampler's reason, never accept."""
    sim = simulate(bench, seed=23)
    spec = bench_spec(shifted_limits(truth_quantities(sim), [-0.1, -0.1, -0.1]))
    options = dataclasses.replace(OPTIONS, sampler="emcee", max_steps=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the sampler warns that it did not converge
        result = accept_campaign(sim.campaign, spec, options, seed=23, envelope=False)
    d = result.decision
    assert result.fit.diagnostics["converged"] is False
    assert d.decision == INDETERMINATE and d.requirement_decisions == (INDETERMINATE,) * 3
    assert "not converged" in d.reason and result.fit.diagnostics["reason"] in d.reason


# --- the guarded-acceptance promise ------------------------------------------------------------
POPULATION_UNITS = 200
POPULATION_RNG_SEED = 2025
POPULATION_SEEDS = range(1000, 1000 + POPULATION_UNITS)
#: relative sd of each true parameter across the population (the posterior sd of stiffness is
#: ≈ 0.09 %, of lost motion ≈ 0.8 %: the population spreads over a few posterior sd)
POPULATION_SPREAD = {"stiffness": 0.0015, "gap": 0.01, "friction_torque": 0.05, "dahl_torque": 0.05, "gap_torque": 0.05}
#: limits at these quantiles of the population's true values (min requirements at the low end,
#: max at the high end), so that a real fraction of units is near or over each limit
POPULATION_LIMIT_QUANTILE = 0.15


@pytest.mark.slow
@pytest.mark.runtime_bound
def test_guarded_acceptance_over_200_units_near_the_limits(bench):
    """200 SYNTHETIC units, truth varied around the limits (seeded), each decided with p_accept
    = 0.95 on stiffness_elastic ≥, lost_motion ≤ and K_d ≥ over 300–380 N·m × 1–10 rpm: of the
    accepted units, at most 5 % may have their truth out of spec (the promise of guarded
    acceptance). Short runs and the Laplace approximation (see the module docstring) keep it
    to about two minutes. For contrast, the rule "accept when the posterior mean is in spec" is
    evaluated on the same units and printed."""
    rng = np.random.default_rng(POPULATION_RNG_SEED)
    sims = []
    for seed in POPULATION_SEEDS:
        truth = {k: float(v) * (1 + POPULATION_SPREAD.get(k, 0.0) * rng.standard_normal()) for k, v in bench.truth.items()}
        sims.append(simulate(dataclasses.replace(bench, truth=truth), seed=seed))
    truth_q = np.array([truth_quantities(sim) for sim in sims])
    lo, hi = np.quantile(truth_q, [POPULATION_LIMIT_QUANTILE, 1 - POPULATION_LIMIT_QUANTILE], axis=0)
    limits = [lo[i] if bound == "min" else hi[i] for i, (_, bound, _) in enumerate(REQUIREMENTS)]
    spec = bench_spec(limits)

    decisions, truth_in, mean_in, converged = [], [], [], 0
    for i, (seed, sim) in enumerate(zip(POPULATION_SEEDS, sims)):
        result = accept_campaign(sim.campaign, spec, OPTIONS, seed=seed, envelope=False)
        decisions.append(result.decision.decision)
        converged += bool(result.fit.diagnostics["converged"])
        truth_in.append(conformance(result.bound, truth_q[i:i + 1])[0].all())
        mean_in.append(conformance(result.bound, result.quantities.mean(axis=0, keepdims=True))[0].all())
    decisions, truth_in, mean_in = np.array(decisions), np.array(truth_in), np.array(mean_in)
    accepted = decisions == ACCEPT
    false_accept = int(np.sum(accepted & ~truth_in))
    fraction = false_accept / max(1, accepted.sum())
    naive_false = int(np.sum(mean_in & ~truth_in))
    naive_fraction = naive_false / max(1, mean_in.sum())
    message = (
        f"{len(sims)} units, limits {np.round(limits, 4).tolist()}; truth out of spec {int((~truth_in).sum())}; "
        f"accepted {int(accepted.sum())}, rejected {int((decisions == REJECT).sum())}, indeterminate "
        f"{int((decisions == INDETERMINATE).sum())}; accepted with truth out of spec {false_accept} "
        f"({100 * fraction:.2f} %, promise ≤ 5 %); rejected with truth in spec "
        f"{int(np.sum((decisions == REJECT) & truth_in))}; posterior-mean rule: accepted {int(mean_in.sum())}, "
        f"of them truth out of spec {naive_false} ({100 * naive_fraction:.2f} %); converged {converged}/{len(sims)}")
    print("\n[guarded acceptance] " + message)
    assert fraction <= 1 - spec.p_accept, message
    # the population is a real test: units near and over the limits, enough of them accepted,
    # and deciding from the posterior mean alone would break the promise on these very units
    assert 0.2 <= (~truth_in).mean() <= 0.8, message
    assert accepted.sum() >= 30, message
    assert naive_fraction > 1 - spec.p_accept, message


# --- the command -------------------------------------------------------------------------------
def _write_spec(path: Path, limits) -> Path:
    lines = ['label = "SYNTHETIC test spec"', "p_accept = 0.95"]
    for (metric, bound, unit), limit in zip(REQUIREMENTS, limits):
        lines += ["[[requirement]]", f'metric = "{metric}"', f"{bound} = {float(limit)!r}", f'unit = "{unit}"']
        if metric == "kd":
            lines += [f"torque_Nm = {REGION['torque_Nm']}", f"speed_rpm = {REGION['speed_rpm']}"]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.slow
def test_accept_command_exit_codes_and_accept_json(tmp_path, bench, unit_folder, capsys):
    """One unit through ``torsionfit accept``: far inside → exit 0, far outside → 3, limit at the
    posterior mean → 4; accept.json carries the §5.2 keys, the envelope and the SYNTHETIC label."""
    q = truth_quantities(simulate(bench, seed=5))
    manifest = str(unit_folder / "campaign.toml")
    run = lambda spec, out: main(["accept", manifest, "--spec", str(spec), "-o", str(out),  # noqa: E731
                                  "--sampler", "laplace", "--seed", "5"])
    assert run(_write_spec(tmp_path / "in.toml", shifted_limits(q, [-0.1] * 3)), tmp_path / "in") == 0
    doc = json.loads((tmp_path / "in" / "accept.json").read_text())
    assert doc["decision"] == "accept" and doc["reason"] and "SYNTHETIC" in doc["label"]
    for r in doc["requirements"]:
        assert {"name", "p_conform", "decision", "limit", "unit"} <= set(r)
    # far inside: no draw fails, so the risk is the bound 1/N, not 0
    assert doc["consumer_risk"] == pytest.approx(max(1 - doc["p_conform"], 1 / doc["n_draws"]))
    assert doc["risk_is_upper_bound"] == (doc["p_conform"] == 1.0) and doc["producer_risk"] is None
    assert doc["provenance"]["seed"] == 5 and doc["provenance"]["torsionfit_version"]
    assert doc["provenance"]["command"].startswith("torsionfit accept ") and "--seed 5" in doc["provenance"]["command"]
    (env,) = doc["envelope"]
    prob = np.array(env["probability"])
    assert prob.shape == (len(env["speed_rpm"]), len(env["torque_Nm"])) and np.all((prob >= 0) & (prob <= 1))
    in_region = np.array(env["torque_Nm"]) >= REGION["torque_Nm"][0]
    assert np.all(prob[:, in_region] == 1.0)  # the unit is far inside: K_d ≥ K_req everywhere there
    assert (tmp_path / "in" / "figures" / "envelope-0.png").is_file()

    assert run(_write_spec(tmp_path / "out.toml", shifted_limits(q, [0.1] * 3)), tmp_path / "out") == 3
    assert json.loads((tmp_path / "out" / "accept.json").read_text())["decision"] == "reject"

    posterior_mean = [r["posterior"]["mean"] for r in doc["requirements"]]
    limits = shifted_limits(q, [-0.1] * 3)
    limits[0] = posterior_mean[0]  # stiffness exactly at its posterior mean: p_c ≈ 0.5
    assert run(_write_spec(tmp_path / "mid.toml", limits), tmp_path / "mid") == 4
    mid = json.loads((tmp_path / "mid" / "accept.json").read_text())
    assert mid["decision"] == "indeterminate" and 0.2 < mid["requirements"][0]["p_conform"] < 0.8
    assert "ACCEPT" in capsys.readouterr().out


@pytest.mark.slow
def test_accept_over_a_folder_writes_one_row_per_unit(tmp_path, bench, capsys):
    """Two good units and one with a broken run file: the broken one is an error row, the batch
    goes on, the table is CSV and JSON, the exit code says a unit is in error."""
    folder = tmp_path / "line"
    for name, seed in (("unit-a", 31), ("unit-b", 32), ("unit-c", 33)):
        write_campaign(simulate(bench, seed=seed).campaign, folder / name, label=bench.label)
    broken = sorted((folder / "unit-b").glob("*.csv*"))[0]
    broken.write_text("time_s,torque_Nm\n0,1\n")
    q = truth_quantities(simulate(bench, seed=31))
    spec = _write_spec(tmp_path / "spec.toml", shifted_limits(q, [-0.1] * 3))
    code = main(["accept", str(folder), "--spec", str(spec), "-o", str(tmp_path / "out"), "--sampler", "laplace"])
    assert code == 2
    table = json.loads((tmp_path / "out" / "accept_batch.json").read_text())
    assert table["provenance"]["seed"] == 0 and table["provenance"]["command"].startswith("torsionfit accept ")
    rows = table["units"]
    assert [r["unit"] for r in rows] == ["unit-a", "unit-b", "unit-c"]
    assert [r["decision"] for r in rows] == ["accept", "error", "accept"]
    assert broken.name in rows[1]["reason"] and "\n" not in rows[1]["reason"]
    csv_lines = (tmp_path / "out" / "accept_batch.csv").read_text().splitlines()
    assert len(csv_lines) == 4 and csv_lines[0].startswith("unit,decision,p_conform")
    assert (tmp_path / "out" / "unit-c" / "accept.json").is_file()
    assert "3 units: 2 accept" in capsys.readouterr().out


# --- risks from finite draws, extrapolated decisions -------------------------------------------
def test_a_risk_no_draw_shows_is_a_bound_not_zero():
    """4000 draws all in spec: the consumer's risk is < 1/4000 (the draws cannot resolve less),
    never "0"; all out of spec: the producer's risk likewise; a risk the draws do show is as is."""
    d = decide_unit(_conform([np.ones(4000)]), ["a"], 0.95)
    assert d.decision == ACCEPT and d.consumer_risk == pytest.approx(1 / 4000) and d.risk_is_bound
    assert "consumer's risk < 0.00025 (no draw of 4000 fails)" in d.reason
    d = decide_unit(_conform([np.zeros(4000)]), ["a"], 0.95)
    assert d.decision == REJECT and d.producer_risk == pytest.approx(1 / 4000) and d.risk_is_bound
    assert "producer's risk < 0.00025" in d.reason
    d = decide_unit(_conform([np.arange(100) < 97]), ["a"], 0.95)
    assert d.consumer_risk == pytest.approx(0.03) and not d.risk_is_bound and "consumer's risk 0.03" in d.reason


def _te_campaign(conditions):
    """A stand-in campaign: TE runs at (torque N·m, speed rpm)."""
    runs = tuple(SimpleNamespace(torque_Nm=t, speed_rpm=v) for t, v in conditions)
    return SimpleNamespace(te_runs=runs)


def _kd_requirement(torque, speed):
    spec = parse_spec({"requirement": [{"metric": "kd", "min": 80.0, "unit": "Nm/arcmin",
                                        "torque_Nm": torque, "speed_rpm": speed}]})
    return spec.requirements[0]


def test_a_kd_region_beyond_the_measured_conditions_is_named():
    campaign = _te_campaign([(0.0, 5.0), (100.0, 1.0), (380.0, 1.0), (100.0, 20.0), (380.0, 20.0)])
    assert measured_region(campaign) == ((100.0, 380.0), (1.0, 20.0))  # the no-load run is the reference
    assert extrapolation(_kd_requirement([100.0, 380.0], [1.0, 20.0]), campaign) is None
    line = extrapolation(_kd_requirement([95.0, 380.0], [0.0, 30.0]), campaign)
    assert "extrapolates" in line and "\n" not in line
    assert "torque 95–380 N·m asked, measured 100–380 N·m" in line
    assert "speed 0–30 rpm asked, measured 1–20 rpm" in line
    only_speed = extrapolation(_kd_requirement([150.0, 300.0], [1.0, 25.0]), campaign)
    assert "speed" in only_speed and "torque" not in only_speed
    stiffness = parse_spec({"requirement": [{"metric": "stiffness_rated", "min": 1.0, "unit": "Nm/arcmin"}]})
    assert extrapolation(stiffness.requirements[0], campaign) is None  # not over a region
