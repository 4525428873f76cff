"""Closing the loop (DESIGN §3) on SYNTHETIC campaigns with an undeclared effect in them.

Each campaign comes from the virtual bench ``tests/benches/effects/base.toml`` (two hysteresis
loops at 2 and 10 N·m/s, two TE runs at 2 and 10 rpm, 1″ angle noise on a 1″ encoder; for speed
dependence ``one_load.toml``, the same runs with both TE runs forward at one load) with one
effect switched on in the bench's ``[effects]``/``[truth]``. The campaign is written with
``write_campaign`` and read back with ``load_campaign``: the manifest never names the effect, so
``diagnose`` sees only the data. It must find the effect (the first one it adds is the true one;
another one may follow only when it is physically entangled with the truth, see ``ENTANGLED``)
and bring the residual down to the noise.

Honesty: the effect's parameters are drawn from a seeded generator within a plausible range
(every test its own seeds, for the parameters and for the noise); the seeds were fixed before
looking at the results. ``TORSIONFIT_DIAGNOSE_SEED=<n>`` shifts every seed, to rerun the file on
other draws.

TE-only campaigns: ``te_kinematic.toml`` (six runs, 3600 samples per revolution, noise below
the encoder step) and ``te_speed.toml`` (ten runs at two loads and 2–12 rpm, for kinematic error
and speed dependence together). Every campaign is made by a ``*_case`` function returning a
:class:`Case`; ``scripts/diagnose_zoo.py`` runs the same functions and tabulates the results.

Cost: every campaign has the shape of ``base.toml`` (same run kinds, same run lengths), so the
base model compiles once per process and each extension once (~20 s per new model shape on an
idle two-core machine, ~3 s per fit once compiled); the file runs eight diagnoses in about five
minutes there (most of it compiling). Cases whose catalog entry another test already finds are
left to the zoo (``ZOO_ONLY``; the three-segment compliance is found behind jumps, its base fit in the suite and its
trail with ``TORSIONFIT_DIAGNOSE_ZOO_CASES=1``); the rate and speed dependences, the torque offset and the
warm-up drift run only with ``TORSIONFIT_DIAGNOSE_ZOO_CASES=1`` (``ZOO_FOR_TIME``: the suite's
time budget), and so does the TE campaign with two effects found in turn.
"""

import json
import os
import re
import zlib
from dataclasses import dataclass, replace
from pathlib import Path
import tomllib

import numpy as np
import pytest

from torsionfit.bench import EFFECTS, load_bench, simulate
from torsionfit.diagnose import DiagnoseOptions, diagnose, summary_text, write_diagnosis
from torsionfit.io import load_campaign, write_campaign

pytestmark = pytest.mark.slow

BENCHES = Path(__file__).parent / "benches" / "effects"
BASE = BENCHES / "base.toml"
ONE_LOAD = BENCHES / "one_load.toml"  # base.toml with both TE runs forward at 380 N·m

SEED_SHIFT = int(os.environ.get("TORSIONFIT_DIAGNOSE_SEED", "0"))

K = 108.0  # N·m/arcmin, base.toml's stiffness
RATED = 380.0  # N·m
#: the residual RMSE a correct model leaves: 1″ angle noise and the 1″ encoder's quantisation
NOISE_RMSE = float(np.sqrt(1.0 + 1.0 / 12.0))
#: a fit "at the noise" may exceed it by 20 % (model error of a smooth-knee compliance, TE runs'
#: input-encoder quantisation, a finite fit)
AT_NOISE = 1.2 * NOISE_RMSE

#: effects another one may bring along: the same observable, explained two ways
ENTANGLED = {
    "stiffness_nonlinearity": {"asymmetry"},  # both reshape the compliance curve
    "asymmetry": {"stiffness_nonlinearity"},
    "rate_dependence": set(),
    "kinematic_error": set(),
    "speed_dependence": set(),
    "thermal_drift": set(),
    "torque_offset": set(),
}


def _seed(*parts) -> int:
    return zlib.crc32("/".join(map(str, parts)).encode()) + SEED_SHIFT


# --- bench files -----------------------------------------------------------------------------
def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float, np.floating, np.integer)):
        return repr(float(v)) if isinstance(v, (float, np.floating)) else str(int(v))
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"no TOML for {v!r}")


def _bench_file(path: Path, effects: dict, truth: dict, drop_truth=(), base: Path = BASE, top: dict | None = None) -> Path:
    """``base`` with ``effects`` switched on and ``truth`` added to (``drop_truth`` removed from)
    its ``[truth]``, top-level keys replaced by ``top``, written to ``path``."""
    doc = tomllib.loads(base.read_text()) | (top or {})
    doc["truth"] = {k: v for k, v in doc["truth"].items() if k not in drop_truth} | truth
    doc["effects"] = effects
    lines = [f"{k} = {_toml_value(v)}" for k, v in doc.items() if not isinstance(v, (dict, list))]
    for k, v in doc.items():
        if isinstance(v, dict):
            lines += [f"[{k}]"] + [f"{kk} = {_toml_value(vv)}" for kk, vv in v.items()]
    for run in doc["runs"]:
        lines += ["[[runs]]"] + [f"{kk} = {_toml_value(vv)}" for kk, vv in run.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def _undeclared_campaign(tmp_path: Path, effects: dict, truth: dict, seed: int, drop_truth=(), base=BASE, top=None):
    """Simulate the bench, write the campaign, check that nothing written names an effect, read
    it back. Returns (campaign as read back, bench)."""
    bench = load_bench(_bench_file(tmp_path / "bench.toml", effects, truth, drop_truth, base, top))
    assert set(bench.effects) == set(effects)  # switched on in the bench …
    sim = simulate(bench, seed=seed)
    out = tmp_path / "campaign"
    manifest = write_campaign(sim.campaign, out)  # no bench_file: the bench's name is not written
    text = manifest.read_text()
    for word in (*EFFECTS, "[effects]", "[truth]", "creep", "ripple", "drift"):
        assert word not in text, f"the manifest names {word!r}"  # … absent from what is written
    for csv in out.iterdir():
        if csv != manifest:
            header = csv.read_text().split("\n", 2)[:2]
            assert not any(name in line for name in EFFECTS for line in header)
    campaign = load_campaign(manifest)
    assert [r.name for r in campaign.runs] == [r.name for r in sim.campaign.runs]
    return campaign, bench


def _summary(d) -> str:
    steps = ", ".join(f"{s.effect} (log10 p {s.evidence.log10_p:.1f}, ΔELPD {s.delta_elpd:.1f} ± {s.delta_elpd_se:.1f} "
                      f"{s.comparison.criterion}, RMSE {s.before.rmse_arcsec:.2f}″ → {s.after.rmse_arcsec:.2f}″)"
                      for s in d.steps) or "none"
    rejected = ", ".join(f"{s.effect} (log10 p {s.evidence.log10_p:.1f}, ΔELPD {s.delta_elpd:.1f} ± {s.delta_elpd_se:.1f} "
                         f"{s.comparison.criterion})" for s in d.rejected) or "none"
    sigs = " | ".join(", ".join(f"{e.effect} {e.log10_p:.1f}" for e in it) for it in d.signatures)
    per_run = ", ".join(f"{k} {v:.2f}″" for k, v in d.final.rmse_per_run.items())
    return (f"base RMSE {d.base.rmse_arcsec:.2f}″ → final {d.final.rmse_arcsec:.2f}″ ({per_run}); "
            f"final effects {d.final.effects}; "
            f"added: {steps}; rejected: {rejected}; signatures (log10 p) per iteration: {sigs}; "
            f"unexplained: {d.unexplained} {d.unexplained_description!r}; noise estimate {d.noise_arcsec:.2f}″; "
            f"notes: {d.notes}")


def _diagnose(campaign, seed):
    d = diagnose(campaign, DiagnoseOptions(), seed=seed)
    print(_summary(d))
    return d


# --- the seven effects, one at a time --------------------------------------------------------
def _stiffness_nonlinearity(rng):
    return ({"stiffness_nonlinearity": "three_segment"},
            {"k1_Nm_per_arcmin": rng.uniform(0.5, 0.7) * K, "k2_Nm_per_arcmin": rng.uniform(0.95, 1.05) * K,
             "k3_Nm_per_arcmin": rng.uniform(1.1, 1.3) * K,
             "t1_Nm": rng.uniform(0.15, 0.25) * RATED, "t2_Nm": rng.uniform(0.5, 0.7) * RATED},
            ("stiffness_Nm_per_arcmin",))


def _rate_dependence(rng):
    return ({"rate_dependence": True},
            {"creep_stiffness_Nm_per_arcmin": rng.uniform(500.0, 900.0), "creep_time_s": rng.uniform(20.0, 60.0)}, ())


def _kinematic_error(rng):
    # a cycloidal reducer's once-per-revolution error and its pin-count order
    amp, phase = rng.uniform(10.0, 30.0, 2), rng.uniform(0.0, 2 * np.pi, 2)
    return ({"kinematic_error": [1, 39]},
            {"kin_cos_arcsec": list(amp * np.cos(phase)), "kin_sin_arcsec": list(amp * np.sin(phase))}, ())


def _speed_dependence(rng):
    return ({"speed_dependence": {"viscous": True, "compliance_order": 0}},
            {"viscous_friction_Nm_per_rpm": rng.uniform(1.0, 3.0)}, ())


def _asymmetry(rng):
    return {"asymmetry": True}, {"compliance_asymmetry": rng.choice([-1.0, 1.0]) * rng.uniform(0.07, 0.13)}, ()


def _thermal_drift(rng):
    per_min = rng.choice([-1.0, 1.0], 4) * rng.uniform(0.5, 2.0, 4)  # one drift per run, ″/min
    return {"thermal_drift": True}, {"drift_arcsec_per_s": list(per_min / 60.0)}, ()


def _torque_offset(rng):
    return {"torque_offset": True}, {"torque_offset_Nm": rng.choice([-1.0, 1.0]) * rng.uniform(0.01, 0.02) * RATED}, ()


EFFECT_CASES = {
    "stiffness_nonlinearity": _stiffness_nonlinearity,
    "rate_dependence": _rate_dependence,
    "kinematic_error": _kinematic_error,
    "speed_dependence": _speed_dependence,
    "asymmetry": _asymmetry,
    "thermal_drift": _thermal_drift,
    "torque_offset": _torque_offset,
}

#: campaign per effect: base.toml unless the effect needs more to be told apart. In base.toml the two
#: TE runs differ in speed *and* load and direction, so a speed effect there only shows as a TE twist
#: that disagrees with the loops' stiffness — which a creep element explains as well: with viscous
#: friction 2.5 N·m/rpm on base.toml, diagnose adds rate_dependence (log10 p −150.8, ΔELPD 714.9 ± 62.3,
#: RMSE 1.68″ → 1.04″) while the speed signature stays at log10 p −0.0 (the base fit matches both TE
#: levels exactly by moving K). one_load.toml runs both TE runs forward at 380 N·m, so only speed can
#: make their levels differ (same run lengths: shapes shared with base.toml).
EFFECT_BENCH = {"speed_dependence": ONE_LOAD}

#: known failures of the implementation (numbers measured with the default seeds)
KNOWN_FAILURES: dict[str, str] = {}


@dataclass(frozen=True)
class Case:
    """A SYNTHETIC campaign with what was switched on in it (never in its manifest), and the
    seed its diagnosis runs with. ``scripts/diagnose_zoo.py`` tabulates the same cases."""

    campaign: object
    seed: int
    effects: dict  # the bench's [effects] (or what the test added to the readings)
    truth: dict  # the parameters drawn for them


def effect_case(folder: Path, effect: str) -> Case:
    """One effect of ``EFFECT_CASES`` switched on in its bench."""
    rng = np.random.default_rng(_seed("parameters", effect))
    effects, truth, drop = EFFECT_CASES[effect](rng)
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("noise", effect), drop,
                                       EFFECT_BENCH.get(effect, BASE))
    print(effect, truth)
    return Case(campaign, _seed("diagnose", effect) % 1000, effects, truth)


def _check_found(d, effect: str, truth_effects: dict):
    added = [s.effect for s in d.steps]
    assert added, f"nothing added: {_summary(d)}"
    assert added[0] == effect, f"first added {added[0]!r}, not {effect!r}: {_summary(d)}"
    extra = set(added) - {effect} - ENTANGLED[effect]
    assert not extra, f"added {sorted(extra)} besides {effect!r}: {_summary(d)}"
    assert d.final.rmse_arcsec <= 0.7 * d.base.rmse_arcsec, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)  # at the noise after its extension: nothing is left to report
    _check_finite(d)
    if effect == "kinematic_error":
        assert set(truth_effects["kinematic_error"]) <= set(d.final.effects["kinematic_error"]), _summary(d)


def _check_finite(d):
    """Every comparison the loop made is a finite number, and says which criterion decided."""
    for s in d.steps + d.rejected:
        assert np.isfinite(s.delta_elpd) and np.isfinite(s.delta_elpd_se), _summary(d)
        assert s.comparison.criterion in ("psis-loo", "linearised-loo") and s.comparison.reason, _summary(d)


#: effects the suite leaves to the diagnose zoo (scripts/diagnose_zoo.py runs every case) because
#: another test of the suite finds the same catalog entry: the kinematic error on the TE export
#: (test_te_exports_e2e.py), the drift in its warm-up shape (test_saturating_drift_closes_to_the_noise,
#: itself opt-in now, see ZOO_FOR_TIME),
#: the compliance asymmetry (entangled with the reshaped compliance curve: ENTANGLED; only the zoo
#: finds it on its own), the three-segment compliance behind the jumps of a
#: measured-like residual (the same campaign and truth with jumps in its readings: in the suite
#: its base fit's winsorised signature finds it, test_the_signature_behind_jumps_is_read_winsorised;
#: the trail that adds it first and nothing else, 105 s of the pool, and its clean case, 118 s,
#: rivals compiled, are zoo-only) — every case compiles its own extension (~35 s)
ZOO_ONLY = ("kinematic_error", "thermal_drift", "asymmetry", "stiffness_nonlinearity")
#: cases the suite runs only with ``TORSIONFIT_DIAGNOSE_ZOO_CASES=1``, for its time budget (15 min
#: on two cores): each compiles its own extension, some a rejected rival's as well (45, 37 and
#: 72 s in the pool; the warm-up drift below 60 s); no other test of the suite finds these
#: catalog entries, the zoo's table (docs/diagnose/zoo.md) does
ZOO_FOR_TIME = ("rate_dependence", "speed_dependence", "torque_offset")
RUN_ZOO_CASES = os.environ.get("TORSIONFIT_DIAGNOSE_ZOO_CASES") == "1"
ZOO_FOR_TIME_SKIP = pytest.mark.skipif(not RUN_ZOO_CASES, reason="a diagnose-zoo case left out of the suite for its "
                                       "time (scripts/diagnose_zoo.py runs it): TORSIONFIT_DIAGNOSE_ZOO_CASES=1 runs it here")


def _case_marks(name: str) -> tuple:
    if name in KNOWN_FAILURES:
        return (pytest.mark.xfail(strict=True, reason=KNOWN_FAILURES[name]),)
    if name in ZOO_FOR_TIME:
        return (ZOO_FOR_TIME_SKIP,)
    return ()


@pytest.mark.parametrize("effect", [pytest.param(name, marks=_case_marks(name))
                                    for name in EFFECT_CASES if name not in ZOO_ONLY])
def test_diagnose_finds_an_undeclared_effect(tmp_path, effect):
    case = effect_case(tmp_path, effect)
    d = _diagnose(case.campaign, case.seed)
    _check_found(d, effect, case.effects)


# --- a clean campaign ------------------------------------------------------------------------
def clean_case(folder: Path, seed: int) -> Case:
    campaign, _ = _undeclared_campaign(folder, {}, {}, seed + SEED_SHIFT)
    return Case(campaign, seed, {}, {})


@pytest.mark.parametrize("seed", [3, 1234])
def test_clean_campaign_adds_nothing(tmp_path, seed):
    case = clean_case(tmp_path, seed)
    d = _diagnose(case.campaign, case.seed)
    assert d.steps == [], _summary(d)
    assert not d.unexplained, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE
    assert not any(r.robust for r in d.final.context.runs)  # no jumps: least squares alone
    _check_finite(d)


# --- two effects at once -------------------------------------------------------------------
def two_effects_case(folder: Path) -> Case:
    """Creep and a two-order kinematic error in base.toml: a case of the diagnose zoo
    (scripts/diagnose_zoo.py, docs/diagnose/zoo.md), out of the suite for its length — creep
    alone is a test here, the kinematic error is found on the TE export (test_te_exports_e2e.py),
    and two effects found in turn are the zoo's TE case below."""
    rng = np.random.default_rng(_seed("parameters", "two"))
    e1, t1, _ = _rate_dependence(rng)
    e2, t2, _ = _kinematic_error(rng)
    campaign, _ = _undeclared_campaign(folder, e1 | e2, t1 | t2, _seed("noise", "two"))
    print(t1 | t2)
    return Case(campaign, 7, e1 | e2, t1 | t2)


# --- an effect behind jumps ------------------------------------------------------------------
#: isolated jumps of the angle reading (the bench's [noise] jump_share, jump_arcsec): 8 % of the
#: samples moved by ±60″ against 1″ noise, a residual that moves in jumps as a measured loop's does
JUMPS = {"jump_share": 0.08, "jump_arcsec": 60.0}


@pytest.fixture(scope="module")
def jumpy_case(tmp_path_factory) -> Case:
    """The stiffness_nonlinearity case of EFFECT_CASES with JUMPS in its readings (SYNTHETIC)."""
    effect = "stiffness_nonlinearity"
    rng = np.random.default_rng(_seed("parameters", effect))
    effects, truth, drop = EFFECT_CASES[effect](rng)
    noise = tomllib.loads(BASE.read_text()).get("noise", {}) | JUMPS
    campaign, _ = _undeclared_campaign(tmp_path_factory.mktemp("jumps"), effects, truth, _seed("noise", effect), drop,
                                       top={"noise": noise})
    return Case(campaign, _seed("diagnose", effect) % 1000, effects, truth)


def test_the_signature_behind_jumps_is_read_winsorised(jumpy_case):
    """The base fit's least-squares signature (the variogram's noise, which counts the jumps: 8×
    the white noise here) stays below the threshold, the robust one does not; diagnose's note
    says the residual moves in jumps and how they were read. (The base fit alone: the trail
    that adds the effect is the zoo-only test below.)"""
    from torsionfit.diagnose._context import fit_context
    from torsionfit.diagnose._loop import _signatures, fit_with, jump_note

    options = DiagnoseOptions()
    base = fit_with(jumpy_case.campaign, {}, options, jumpy_case.seed)
    assert all(r.robust for r in base.context.runs)  # the residual moves in jumps: tested winsorised as well
    least_squares = fit_context(jumpy_case.campaign, {}, base.map_result, robust=False)
    p = {robust: {e.name: ev for e, ev in _signatures(ctx, options, set())}["stiffness_nonlinearity"]
         for robust, ctx in ((False, least_squares), (True, base.context))}
    assert not p[False].significant(options.alpha) and p[True].significant(options.alpha), p
    note = jump_note(base.context.runs)
    assert note and "moves in jumps" in note and "weighing no more than" in note, note
    note = jump_note(least_squares.runs)
    assert note and "can stay below the threshold" in note, note


@ZOO_FOR_TIME_SKIP
def test_diagnose_finds_an_effect_behind_jumps(jumpy_case):
    """The trail adds the switched-on effect first and nothing but what it is entangled with,
    by its own rule (ΔELPD > 10 and > 2 SE), reading the signatures winsorised (above). Out of
    the suite for its time (about 100 s in the pool, the three-segment compliance and its
    rivals compiled)."""
    options = DiagnoseOptions()
    d = _diagnose(jumpy_case.campaign, jumpy_case.seed)
    assert [s.effect for s in d.steps][:1] == ["stiffness_nonlinearity"], _summary(d)
    assert options.earns_keep(d.steps[0].delta_elpd, d.steps[0].delta_elpd_se), _summary(d)
    extra = set(s.effect for s in d.steps) - {"stiffness_nonlinearity"} - ENTANGLED["stiffness_nonlinearity"]
    assert not extra, _summary(d)
    _check_finite(d)
    assert all(r.robust for r in d.base.context.runs)


# --- an effect outside the catalog -----------------------------------------------------------
def ripple_case(folder: Path) -> Case:
    """A sub-division error of the output encoder in base.toml (outside the catalog)."""
    rng = np.random.default_rng(_seed("parameters", "ripple"))
    amplitude, period = rng.uniform(2.0, 4.0), rng.uniform(40.0, 90.0)  # ″
    ripple = {"encoder_ripple": {"amplitude_arcsec": amplitude, "period_arcsec": period}}
    campaign, _ = _undeclared_campaign(folder, ripple, {}, _seed("noise", "ripple"))
    print(f"ripple {amplitude:.2f}″ every {period:.2f}″")
    return Case(campaign, 5, ripple, ripple["encoder_ripple"])


@pytest.mark.extended
def test_encoder_ripple_is_reported_unexplained(tmp_path):
    """A sub-division error of the output encoder, periodic in the measured angle: no catalog
    effect explains it, so nothing may be added and the leftover must be described."""
    case = ripple_case(tmp_path)
    campaign, period = case.campaign, case.truth["period_arcsec"]
    d = _diagnose(campaign, case.seed)
    assert d.steps == [], f"a catalog effect was forced in: {_summary(d)}"
    assert d.unexplained, _summary(d)
    assert "measured angle" in d.unexplained_description
    found = [ev for ev in d.leftovers if "measured angle" in ev.description]
    assert len(found) == 1, _summary(d)
    assert found[0].details["unit"] == "arcsec"
    assert found[0].details["period"] == pytest.approx(period, rel=0.05), _summary(d)
    numbers = [float(x) for x in re.findall(r"period ([0-9.eE+-]+) arcsec", found[0].description)]
    assert numbers and numbers[0] == pytest.approx(period, rel=0.05)
    _check_finite(d)
    # a refit that contains the current model cannot lose more than its few extra parameters'
    # worth (a Laplace-draw LOO once scored such a refit −34 000)
    assert all(s.delta_elpd > -50.0 for s in d.rejected), _summary(d)
    # diagnose.json: the finding, the criterion of every comparison, the final model's metrics
    doc = write_diagnosis(d, campaign, tmp_path / "out")
    saved = json.loads((tmp_path / "out" / "diagnose.json").read_text())
    assert saved["unexplained"] and saved["noise_estimate"] > 0
    assert all(s["criterion"] in ("psis-loo", "linearised-loo") for s in saved["steps"] + saved["rejected"])
    k = saved["final_metrics"]["metrics"]["stiffness_elastic"]
    assert k["hdi95"][0] < k["mean"] < k["hdi95"][1] and k["mean"] == pytest.approx(K, rel=0.05)
    assert "stiffness_elastic" in summary_text(doc)


# --- noise below one encoder step: the comparison must stay finite ----------------------------
TE_BENCH = BENCHES / "te_kinematic.toml"  # six TE runs, 3600 samples per revolution
#: what a right model leaves on TE_BENCH: 0.4″ white noise on the 1″ output encoder's reading
TE_NOISE_RMSE = float(np.sqrt(0.4**2 + 1.0 / 12.0))


def _kinematic_truth(rng) -> dict:
    """Orders 1, 2 and 39: a once-per-revolution error, its second harmonic, the pin count."""
    amp, phase = rng.uniform([15.0, 4.0, 3.0], [30.0, 10.0, 8.0]), rng.uniform(0.0, 2 * np.pi, 3)
    return {"kin_cos_arcsec": list(amp * np.cos(phase)), "kin_sin_arcsec": list(amp * np.sin(phase))}


def te_kinematic_case(folder: Path) -> Case:
    effects = {"kinematic_error": [1, 2, 39]}
    truth = _kinematic_truth(np.random.default_rng(_seed("parameters", "te-kinematic")))
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("noise", "te-kinematic"), base=TE_BENCH)
    print(truth)
    return Case(campaign, _seed("diagnose", "te-kinematic") % 1000, effects, truth)


# --- a warm-up: drift that saturates ----------------------------------------------------------
def warm_up_case(folder: Path) -> Case:
    """base.toml, clean, with a(1 − e^(−t/T)) added to each run's readings before writing."""
    from torsionfit.io import HysteresisRun
    from torsionfit.units import ANGLE_UNITS

    (folder / "clean").mkdir()
    clean, _ = _undeclared_campaign(folder / "clean", {}, {}, _seed("noise", "warm-up"))
    rng = np.random.default_rng(_seed("parameters", "warm-up"))
    runs, truth = [], {"amplitude_arcsec": [], "time_constant_s": []}
    for run in clean.runs:
        t = np.asarray(run.time_s) - run.time_s[0]
        a = rng.choice([-1.0, 1.0]) * rng.uniform(4.0, 8.0)
        tau = rng.uniform(0.1, 0.4) * t[-1]
        warm = a * ANGLE_UNITS["arcsec"] * (1.0 - np.exp(-t / tau))
        truth["amplitude_arcsec"].append(float(a))
        truth["time_constant_s"].append(float(tau))
        runs.append(replace(run, angle_rad=run.angle_rad + warm) if isinstance(run, HysteresisRun)
                    else replace(run, te_rad=run.te_rad + warm))
    campaign = load_campaign(write_campaign(replace(clean, runs=tuple(runs)), folder / "warm",
                                            label="SYNTHETIC diagnose test campaign (base.toml, readings changed by the test)"))
    return Case(campaign, _seed("diagnose", "warm-up") % 1000, {"thermal_drift": "warm_up"}, truth)


@ZOO_FOR_TIME_SKIP
def test_saturating_drift_closes_to_the_noise(tmp_path):
    """Each run of base.toml starts cold: a(1 − e^(−t/T)) added to its readings, T 10–40 % of the
    run, |a| 4–8″ (SYNTHETIC, added to the simulated campaign before it is written). A linear
    drift leaves the bend; the warm-up shape takes the residual to the noise."""
    case = warm_up_case(tmp_path)
    d = _diagnose(case.campaign, case.seed)
    assert {s.effect for s in d.steps} == {"thermal_drift"}, _summary(d)
    assert d.final.effects["thermal_drift"] == "warm_up", _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)
    _check_finite(d)


# --- kinematic error and speed dependence together, TE only ----------------------------------
TE_SPEED_BENCH = BENCHES / "te_speed.toml"  # ten TE runs: two loads, 2–12 rpm, both directions


def kinematic_speed_case(folder: Path, draw: int, samples_per_rev: int | None = None) -> Case:
    """Orders 1, 2, 39 and viscous friction 0.2–1.0 N·m/rpm (1–7″ of TE level between 2 and
    12 rpm against 0.4″ noise) in te_speed.toml; ``draw`` picks the parameters and the noise;
    ``samples_per_rev`` replaces the bench's 720 (the suite's case: 360, still over 9 per
    period of order 39)."""
    rng = np.random.default_rng(_seed("parameters", "te-speed", draw))
    truth = _kinematic_truth(rng) | {"viscous_friction_Nm_per_rpm": float(rng.uniform(0.2, 1.0))}
    effects = {"kinematic_error": [1, 2, 39], "speed_dependence": {"viscous": True, "compliance_order": 0}}
    top = {"te_samples_per_rev": samples_per_rev} if samples_per_rev else None
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("noise", "te-speed", draw), base=TE_SPEED_BENCH,
                                       top=top)
    print(truth)
    return Case(campaign, _seed("diagnose", "te-speed", draw) % 1000, effects, truth)


@pytest.mark.skipif(not RUN_ZOO_CASES,
                    reason="a diagnose-zoo case (scripts/diagnose_zoo.py; ~110 s of compiling ten TE runs): "
                           "TORSIONFIT_DIAGNOSE_ZOO_CASES=1 runs it here")
@pytest.mark.parametrize("draw", [0])  # others: kinematic_speed_case(…, draw)
def test_kinematic_error_and_speed_dependence_are_both_found(tmp_path, draw):
    """Both effects in one TE campaign: the harmonics first (the larger signature), then the TE
    level that changes with speed — a difference between runs, which only a joint test of the
    runs sees (their zero is shared) — and the residual ends at the noise (below one encoder
    step) with nothing left. (The kinematic error alone, te_kinematic_case, is the diagnose
    zoo's: scripts/diagnose_zoo.py.)"""
    case = kinematic_speed_case(tmp_path, draw, samples_per_rev=360)
    d = _diagnose(case.campaign, case.seed)
    added = [s.effect for s in d.steps]
    assert set(added) == {"kinematic_error", "speed_dependence"}, _summary(d)
    assert {1, 2, 39} <= set(d.final.effects["kinematic_error"]), _summary(d)
    assert d.final.rmse_arcsec <= 1.1 * TE_NOISE_RMSE, _summary(d)
    assert all(s.delta_elpd > 2 * s.delta_elpd_se > 0 for s in d.steps), _summary(d)
    assert not d.unexplained, _summary(d)
    _check_finite(d)


def test_the_summary_prints_the_final_models_widening_and_notes():
    """The final metrics' widening and every note they carry reach the summary, one line each."""
    from torsionfit.diagnose._report import FINAL_NOTES

    doc = {"rmse_base": 10.0, "steps": [], "rejected": [], "rmse_final": 10.0, "noise_estimate": 1.0, "added": [],
           "unexplained": False, "notes": [],
           "final_metrics": {"sampler": "laplace", "misfit_inflation": 44.0,
                             "metrics": {"play": {"mean": 1.0, "hdi95": [0.5, 1.5], "unit": "arcmin"}},
                             **{key: f"<{key}>" for key, _ in FINAL_NOTES}}}
    text = summary_text(doc)
    assert "likelihood tempered by 1/44 for misfit" in text
    for key, label in FINAL_NOTES:
        assert f"  {label}: <{key}>" in text
    doc["final_metrics"]["misfit_inflation"] = 1.0
    assert "tempered" not in summary_text(doc)


def test_the_summary_prints_each_backward_check():
    """A dropped effect and one that keeps earning each get a line, with what the check compared."""
    check = {"effect": "drift", "dropped": True, "effects_with": ["drift", "gap_hold"], "rmse_with": 320.0,
             "rmse_without": 324.0, "delta_elpd": 2.0, "delta_elpd_se": 3.0, "criterion": "psis-loo",
             "criterion_reason": ""}
    doc = {"rmse_base": 10.0, "steps": [], "rejected": [], "rmse_final": 10.0, "noise_estimate": 1.0, "added": [],
           "unexplained": False, "notes": [],
           "removals": [check, {**check, "effect": "gap_hold", "dropped": False, "delta_elpd": 90.0}]}
    lines = summary_text(doc).splitlines()
    assert any(line.startswith("- drift") and "dropped, no longer earns its keep: ΔELPD 2.0 ± 3.0" in line
               and "324″ without it, 320″ with it" in line for line in lines), lines
    assert any(line.startswith("- gap_hold") and "still earns its keep: ΔELPD 90.0" in line for line in lines), lines
