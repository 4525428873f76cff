"""Closing the loop on friction (DESIGN §1.1 "What real loops add", §3): SYNTHETIC campaigns
with friction that grows with the load, with several slip elements, or a damped gap crossing
(the gap trails the torque in time), undeclared.

Bench: ``tests/benches/friction/base.toml`` — two hysteresis loops (to 380 and to 190 N·m at
4 N·m/s, 2 Hz: 1071 and 596 samples), each preceded by two play ramps to ±30 N·m, 1″ angle
noise on a 1″ encoder, the base physics. Each test switches one friction effect on in the
bench's ``[effects]``/``[truth]`` with parameters drawn from a seeded generator (seeds fixed
before looking at the results; ``TORSIONFIT_DIAGNOSE_SEED`` shifts them, as in
``test_diagnose.py``, whose helpers write the bench, simulate, write the campaign without the
effect's name and read it back).

Cost: every campaign has the same shape, so the base model, the signatures and each extension
compile once per process (about a minute for the first diagnosis, 20–30 s per extension); a
diagnosis is 5–15 s once compiled. Every effect's second seed runs only with
``TORSIONFIT_DIAGNOSE_ZOO_CASES=1`` (the suite's time budget); the clean campaign runs both.
``make test`` finds the play ramps' torque zero and adds nothing to the clean campaign; the
load-dependent level and the slip elements, each alone (``make test`` finds both together on
the independent simulator's loop), the gap's damped crossing and its hold (each refitted as the other's rival), the level's lag and memory, the held gap's centre, the
gap crossed in held steps (from a declared held gap) and the nested-effect check are ``extended`` (``make test-extended``; the zoo's table and
the measured-loop validation use them too).
"""

from pathlib import Path

import numpy as np
import pytest

from torsionfit.diagnose import DiagnoseOptions, diagnose

from test_diagnose import RUN_ZOO_CASES, Case, _check_finite, _seed, _summary, _undeclared_campaign

BASE = Path(__file__).parent / "benches" / "friction" / "base.toml"
RATED = 380.0  # N·m
#: the RMSE a correct model leaves here: 1″ angle noise, the 1″ encoder's quantisation and the
#: torque sensor's 1.5 N·m noise carried through the loop's slope (a clean campaign's base fit:
#: 1.18–1.20″); a fit "at the noise" stays below
AT_NOISE = 1.3 * float(np.sqrt(1.0 + 1.0 / 12.0))

#: the clean campaign: both seeds in the suite (nothing new compiles for them)
CLEAN_SEEDS = [pytest.param(0, id="seed0"), pytest.param(1, id="seed1", marks=pytest.mark.slow)]
#: every effect's second seed is left out of the suite for its time (TORSIONFIT_DIAGNOSE_ZOO_CASES=1
#: runs them): the four undeclared cases' took 86 s of the pool, the level's lag and memory
#: (each refitted in the other's place when kept) and the held gap's centre (found undeclared
#: and in a declared centred band) about a minute each pair
SECOND_SEED_ZOO_ONLY = [pytest.param(0, id="seed0"), pytest.param(1, id="seed1", marks=pytest.mark.skipif(
    not RUN_ZOO_CASES, reason="second seed left out of the suite for its time: TORSIONFIT_DIAGNOSE_ZOO_CASES=1 runs it"))]


def _load_dependent(rng):
    # μ·380 N·m = 6–11 N·m of extra friction at the peak, against T_f = 6 N·m
    return {"load_dependent_friction": True}, {"friction_load_coefficient": rng.uniform(0.015, 0.03)}, ()


def _distributed(rng):
    # six slip elements; the friction level must matter against the noise (30 N·m ≈ 17″ of loop
    # half-width at 108 N·m/arcmin, the pre-sliding rounded over tens of N·m after each reversal:
    # at 12–16 N·m and spread 0.8–1.0 the one-element Dahl fit was already within the noise, an
    # effect too small to be a finding); Maxwell-slip has no Dahl torque
    return ({"distributed_friction": True},
            {"friction_torque_Nm": rng.uniform(25.0, 35.0), "breakaway_spread": rng.uniform(1.0, 1.2)},
            ("dahl_torque_Nm",))


def _gap_lag(rng):
    # the gap (1′, crossed over ~10 N·m, ~2.5 s at 4 N·m/s) trails the mesh torque by 2–4 s: the
    # crossing moves 8–16 N·m later along each branch, the loaded flanks not at all
    return {"gap_lag": True}, {"gap_lag_time_s": rng.uniform(2.0, 4.0)}, ()


def _load_lag(rng):
    # the level follows |τ| through a lag of 30–40 s (the ramps to 380 N·m take 95 s; on the
    # measured loops T_L is 0.02–1 s against ramps of 10 s): on a ramp at 4 N·m/s the level
    # runs 120–160 N·m of load behind, μ·that = 6–10 N·m of friction; at 15–25 s (2–4 N·m) the
    # instantaneous level's refit absorbed it to within 10 % of the noise (log10 p −5)
    return ({"load_dependent_friction": {"lag": True}},
            {"friction_load_coefficient": rng.uniform(0.05, 0.06), "friction_load_lag_time_s": rng.uniform(30.0, 40.0)}, ())


def _load_memory(rng):
    # the level remembers the last peak of |τ|, let down by 10–20 % of the torque travelled back
    # (m = 0.8–0.9): where the 380 N·m loop's branches cross zero the level is still up by
    # μ·300–340 N·m = 6–10 N·m (0 for the instantaneous level), on the 190 N·m loop by half that,
    # at one loading rate — no lag in time makes both
    return ({"load_dependent_friction": {"memory": True}},
            {"friction_load_coefficient": rng.uniform(0.04, 0.05), "friction_load_memory": rng.uniform(0.8, 0.9)}, ())


def _gap_hold(rng):
    # the 1′ gap held by its own friction up to 20–40 N·m: each branch crosses it 20–40 N·m
    # later than the 6 N·m friction alone puts it, at the same torque on both loops (380 and
    # 190 N·m); the ±30 N·m play ramps cross it or not
    return {"gap_hold": True}, {"gap_hold_torque_Nm": rng.uniform(20.0, 40.0)}, ()


def _gap_centre(rng):
    # the held gap's band centred 8–15 N·m off zero torque, either side: each branch pair
    # crosses it at c ± T_h (hold 20–30 N·m), both crossings moved the same way along the torque,
    # the loaded flanks not moved (a torque offset would move them too)
    centre = rng.choice([-1.0, 1.0]) * rng.uniform(8.0, 15.0)
    return ({"gap_hold": {"centred": False}},
            {"gap_hold_torque_Nm": rng.uniform(20.0, 30.0), "gap_centre_torque_Nm": centre}, ())


def _gap_relays(rng):
    """A 4′ gap crossed in held steps (the measured baseline loops' staircase): half of it on a
    relay held ±16 N·m, the rest on two relays whose switches are not symmetric — one crossed
    at +24 N·m going up and at 0 coming down, one at 0 going up and at −8 N·m coming down —
    the grid's seven switches over ±24 N·m about a centre 0–3 N·m off zero (the ±30 N·m play
    ramps reach every switch less the 6 N·m friction). The rest of the 28 relays share e^−8 of
    the largest's logit each (< 1 % of the gap)."""
    from torsionfit.model import RelayGapBacklash

    relays = RelayGapBacklash()
    logits = np.full(relays.n_relays, -8.0)
    share = rng.uniform(0.2, 0.3)
    for (up, down), w in (((2 / 3, -2 / 3), 1.0 - 2 * share), ((1.0, 0.0), share), ((0.0, -1 / 3), share)):
        logits[relays.nearest_relay(up, down)] = np.log(w)
    return ({"gap_relays": True},
            {"gap_arcmin": 4.0, "gap_relay_span_Nm": 24.0, "gap_centre_torque_Nm": rng.uniform(0.0, 3.0),
             "gap_relay_logits": list(logits[1:] - logits[0])}, ())


def _play_offset(rng):
    # the torque reading's zero on the ±30 N·m play ramps 4–8 N·m off the large cycles', either
    # way (on the measured loops the play ramps' gap crossings centre −1.5 to +1.1 N·m off the
    # large ramps' against ±4 N·m ramps): the play ramps' loop moved along the torque, the large
    # cycles not at all
    return {"play_torque_offset": True}, {"play_torque_offset_Nm": rng.choice([-1.0, 1.0]) * rng.uniform(4.0, 8.0)}, ()


#: left to ``make test-extended`` for the suite's time (each compiles its extension and its rival's);
#: ``make test`` fits the held gap on a bench (tests/test_model_held_gap.py). The load-dependent
#: level and the slip elements (128 and 65 s of the pool) are found together in ``make test`` on
#: the independent simulator's loop (tests/test_independent_bench.py), each alone here
EXTENDED_CASES = ("gap_lag", "gap_hold", "distributed_friction", "load_dependent_friction")
CASES = {"load_dependent_friction": _load_dependent, "distributed_friction": _distributed, "gap_lag": _gap_lag,
         "gap_hold": _gap_hold, "play_torque_offset": _play_offset}
#: found in two steps (the load dependence, then its lag): a case of its own
LAG_STEPS = ["load_dependent_friction", "friction_load_lag"]
MEMORY_STEPS = ["load_dependent_friction", "friction_load_memory"]
BUILDERS = {**CASES, "friction_load_lag": _load_lag, "friction_load_memory": _load_memory, "gap_centre": _gap_centre,
            "gap_relays": _gap_relays}


def friction_case(folder: Path, effect: str | None, seed: int) -> Case:
    """``effect`` (None: nothing) switched on in base.toml, parameters and noise from ``seed``."""
    label = effect or "clean"
    effects, truth, drop = BUILDERS[effect](np.random.default_rng(_seed("parameters", effect, seed))) if effect else ({}, {}, ())
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("noise", label, seed), drop, BASE)
    print(label, truth)
    return Case(campaign, _seed("diagnose", label, seed) % 1000, effects, truth)


def _run(tmp_path, effect, seed):
    case = friction_case(tmp_path, effect, seed)
    d = diagnose(case.campaign, DiagnoseOptions(), seed=case.seed)
    print(_summary(d))
    _check_finite(d)
    return d


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.parametrize("effect", [pytest.param(name, marks=pytest.mark.extended) if name in EXTENDED_CASES else name
                                    for name in CASES])
def test_diagnose_finds_undeclared_friction(tmp_path, effect, seed):
    d = _run(tmp_path, effect, seed)
    assert d.base.rmse_arcsec > AT_NOISE, _summary(d)  # the effect is there to be found
    added = [s.effect for s in d.steps]
    assert added == [effect], _summary(d)
    step = d.steps[0]
    assert step.delta_elpd > 0 and step.delta_elpd > 2 * step.delta_elpd_se, _summary(d)
    assert d.final.rmse_arcsec < d.base.rmse_arcsec, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)  # at the noise after its extension: nothing is left to report
    if effect in ("gap_lag", "gap_hold"):
        # at one loading rate a damped and a held crossing both cross late: whichever signature
        # ranks first (on seed 1's held gap the lag's did), the other is refitted in its place and
        # the better kept — here the one switched on
        rival = {"gap_lag": "gap_hold", "gap_hold": "gap_lag"}[effect]
        assert rival in [s.effect for s in d.rejected], _summary(d)
    if effect == "gap_hold":
        # a band centred on zero: neither the hold's off-centre band nor the centre comes in
        assert d.final.effects == {"gap_hold": True}, _summary(d)
    if effect == "play_torque_offset":
        # the play ramps' own zero recovered (the loop's slope there: ~1′ of gap over ~10 N·m)
        fitted = float(d.final.map_result.values["play_torque_offset"])
        print("fitted play-ramp torque offset (N·m):", fitted)
        truth = BUILDERS[effect](np.random.default_rng(_seed("parameters", effect, seed)))[1]["play_torque_offset_Nm"]
        assert abs(fitted - truth) < 1.0, _summary(d)
    if effect == "load_dependent_friction":
        # the missing μ leaves a residual far above the noise: the fit with it removes most of it
        assert d.final.rmse_arcsec <= 0.7 * d.base.rmse_arcsec, _summary(d)


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.extended
def test_diagnose_finds_a_friction_level_lagging_the_load(tmp_path, seed):
    """In two steps (the instantaneous level, then its lag), or as the memory's rival: at one
    loading rate a remembered peak's signature can rank first, and the lag refitted in its
    place must win."""
    d = _run(tmp_path, "friction_load_lag", seed)
    assert [s.effect for s in d.steps] in (LAG_STEPS, ["friction_load_lag"]), _summary(d)
    assert d.final.effects == {"load_dependent_friction": {"lag": True}}, _summary(d)
    lag = d.steps[-1]
    assert lag.delta_elpd > 2 * lag.delta_elpd_se and lag.after.rmse_arcsec < lag.before.rmse_arcsec, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.extended
def test_diagnose_finds_a_friction_level_remembering_the_peak_load(tmp_path, seed):
    """Found from the base model in one step (a remembered peak is not the instantaneous level
    plus a correction: see ``FrictionLoadMemory``), or after the instantaneous level; never as a
    lag."""
    d = _run(tmp_path, "friction_load_memory", seed)
    added = [s.effect for s in d.steps]
    assert added in (["friction_load_memory"], MEMORY_STEPS), _summary(d)
    assert d.final.effects == {"load_dependent_friction": {"memory": True}}, _summary(d)
    memory = d.steps[-1]
    assert memory.delta_elpd > 2 * memory.delta_elpd_se and memory.after.rmse_arcsec < memory.before.rmse_arcsec, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)


def _centre_case(tmp_path, seed, initial_effects):
    case = friction_case(tmp_path, "gap_centre", seed)
    d = diagnose(case.campaign, DiagnoseOptions(initial_effects=initial_effects), seed=case.seed)
    print(_summary(d))
    _check_finite(d)
    assert d.final.effects == {"gap_hold": {"centred": False}}, _summary(d)
    step = d.steps[-1]
    assert step.delta_elpd > 2 * step.delta_elpd_se and step.after.rmse_arcsec < step.before.rmse_arcsec, _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)
    assert not d.unexplained, _summary(d)
    values = d.final.map_result.values
    print("fitted centre, hold (N·m):", float(values["gap_centre_torque"]), float(values["gap_hold_torque"]))
    assert abs(float(values["gap_centre_torque"]) - case.truth["gap_centre_torque_Nm"]) < 1.0, _summary(d)
    assert abs(float(values["gap_hold_torque"]) - case.truth["gap_hold_torque_Nm"]) < 1.0, _summary(d)
    return d


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.extended
def test_diagnose_finds_a_held_gap_centred_off_zero(tmp_path, seed):
    """From the base model in one step: the held gap's signature tries a band about the centre
    where the data's crossings lie off the fit's, and the hold refitted there recovers both."""
    d = _centre_case(tmp_path, seed, {})
    assert [s.effect for s in d.steps] == ["gap_hold"], _summary(d)


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.extended
def test_diagnose_finds_the_centre_of_a_declared_held_gap(tmp_path, seed):
    """A held gap declared centred (as on a design known to hold its gap) whose band lies off
    zero: the centre's own signature (the score at c = 0, or the band moved to where the data's
    crossings lie off the fit's) finds it. Its absence on a centred band is
    ``test_diagnose_finds_undeclared_friction[gap_hold-*]``, which adds the hold alone, centred."""
    d = _centre_case(tmp_path, seed, {"gap_hold": True})
    assert [s.effect for s in d.steps] == ["gap_centre"], _summary(d)


@pytest.mark.parametrize("seed", SECOND_SEED_ZOO_ONLY)
@pytest.mark.extended
def test_diagnose_finds_a_held_gap_crossed_in_steps(tmp_path, seed):
    """A gap crossed in held steps, from a declared held gap (as on a design known to hold its
    gap; the held gap itself is found undeclared by ``test_diagnose_finds_undeclared_friction
    [gap_hold-*]``, whose single relay adds nothing further): the relays' signature finds the
    staircase (it ranked first, log10 p −99 on seed 0) and the fit with them removes nearly all
    of the held gap's misfit. Not all: on seed 0 the final RMSE was 1.47″ against 1.19″ of
    noise (6.90″ with the held gap; the 190 N·m loop 1.85″), with no signature left — the grid
    the fit settles on need not be the truth's (its span and centre are continuous, the shares
    re-arranged with them), so "at the noise" is not claimed."""
    case = friction_case(tmp_path, "gap_relays", seed)
    d = diagnose(case.campaign, DiagnoseOptions(initial_effects={"gap_hold": True}), seed=case.seed)
    print(_summary(d))
    _check_finite(d)
    assert d.base.rmse_arcsec > AT_NOISE, _summary(d)
    assert "gap_relays" in [s.effect for s in d.steps] and "gap_relays" in d.final.effects, _summary(d)
    step = next(s for s in d.steps if s.effect == "gap_relays")
    assert step.delta_elpd > 2 * step.delta_elpd_se and step.after.rmse_arcsec < step.before.rmse_arcsec, _summary(d)
    values = d.final.map_result.values
    print("fitted gap (′), span and centre (N·m):", float(values["gap"]) * 180 / np.pi * 60,
          float(d.final.map_result.problem.model.backlash.span_Nm(values)), float(values["gap_centre_torque"]))
    # at least 90 % of the held gap's RMSE beyond the noise removed
    assert d.final.rmse_arcsec - d.noise_arcsec <= 0.1 * (d.base.rmse_arcsec - d.noise_arcsec), _summary(d)
    assert not d.unexplained, _summary(d)
    assert abs(float(values["gap"]) * 180 / np.pi * 60 - 4.0) < 0.2, _summary(d)


@pytest.mark.parametrize("seed", CLEAN_SEEDS)
def test_clean_friction_campaign_adds_neither(tmp_path, seed):
    d = _run(tmp_path, None, seed)
    assert d.steps == [], _summary(d)
    last = {ev.effect: ev for ev in d.signatures[-1]}
    # the lag's signature needs a load-dependent level first: not tested here; the memory's is
    for name in [*CASES, "friction_load_memory"]:
        assert name in last and not last[name].significant(DiagnoseOptions().alpha), _summary(d)
    assert d.final.rmse_arcsec <= AT_NOISE, _summary(d)


@pytest.mark.slow
@pytest.mark.extended
def test_fit_with_a_nested_effect_ends_no_lower_than_the_fit_without_it(tmp_path):
    """SYNTHETIC, no lag in the data: the model with a damped gap crossing contains the one
    without it (T_g → 0), so its MAP starts from that optimum too and ends no lower — from the
    prior's starts alone it stopped in a worse optimum on measured loops. (Here, after the
    diagnoses, because it fits this file's campaign shape with the base model and the gap lag:
    programs this process has compiled already.)"""
    from torsionfit.report import FitOptions, fit_campaign

    campaign = friction_case(tmp_path, None, 0).campaign
    without = fit_campaign(campaign, FitOptions(sampler="laplace", progress=False), seed=0)
    with_lag = fit_campaign(campaign, FitOptions(effects={"gap_lag": True}, sampler="laplace", progress=False), seed=0)
    # log posterior: the start is the smaller model's optimum plus the lag's prior density three
    # sds out, −9/2 − log(2√(2π)) ≈ −6.1; from there LM only climbs
    assert with_lag.map_result.log_density >= without.map_result.log_density - 6.2
    # the lag stays negligible: the crossing of a clean loop is not damped
    assert float(with_lag.map_result.values["gap_lag_time"]) < 0.5  # s, against ~2.5 s to cross the gap
