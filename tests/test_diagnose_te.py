"""Closing the loop on TE-only SYNTHETIC campaigns with undeclared effects (DESIGN §3).

``tests/benches/effects/te_kinematic.toml``: six TE runs, 3600 samples per revolution, noise
below the encoder step; ``te_speed.toml``: ten runs at two loads and 2–12 rpm, for kinematic
error and speed dependence together. The campaigns are written and read back as in
``test_diagnose.py`` (the manifest never names the effect) with that file's helpers and seeds;
kept in a file of their own so that a parallel test run spreads the diagnoses over its workers.
``scripts/diagnose_zoo.py`` runs the same ``*_case`` functions.
"""

from pathlib import Path

import numpy as np
import pytest

from test_diagnose import BENCHES, Case, _check_finite, _diagnose, _seed, _summary, _undeclared_campaign


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


def test_kinematic_te_campaign_below_the_encoder_step_closes_with_kinematic_error(tmp_path):
    """Orders 1, 2 and 39 in TE runs at three loads, both directions: adding the harmonics takes
    the residual to the noise (below one encoder step), and the comparison that says so is a
    finite number — nothing else is added and nothing is left."""
    case = te_kinematic_case(tmp_path)
    d = _diagnose(case.campaign, case.seed)
    assert [s.effect for s in d.steps] == ["kinematic_error"], _summary(d)
    assert {1, 2, 39} <= set(d.final.effects["kinematic_error"]), _summary(d)
    assert d.final.rmse_arcsec <= 1.1 * TE_NOISE_RMSE < 0.1 * d.base.rmse_arcsec, _summary(d)
    step = d.steps[0]
    assert step.delta_elpd > 2 * step.delta_elpd_se > 0, _summary(d)
    _check_finite(d)
    assert not d.unexplained, _summary(d)


# --- kinematic error and speed dependence together, TE only ----------------------------------
TE_SPEED_BENCH = BENCHES / "te_speed.toml"  # ten TE runs: two loads, 2–12 rpm, both directions


def kinematic_speed_case(folder: Path, draw: int) -> Case:
    """Orders 1, 2, 39 and viscous friction 0.2–1.0 N·m/rpm (1–7″ of TE level between 2 and
    12 rpm against 0.4″ noise) in te_speed.toml; ``draw`` picks the parameters and the noise."""
    rng = np.random.default_rng(_seed("parameters", "te-speed", draw))
    truth = _kinematic_truth(rng) | {"viscous_friction_Nm_per_rpm": float(rng.uniform(0.2, 1.0))}
    effects = {"kinematic_error": [1, 2, 39], "speed_dependence": {"viscous": True, "compliance_order": 0}}
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("noise", "te-speed", draw), base=TE_SPEED_BENCH)
    print(truth)
    return Case(campaign, _seed("diagnose", "te-speed", draw) % 1000, effects, truth)


@pytest.mark.parametrize("draw", [0, 1])
def test_kinematic_error_and_speed_dependence_are_both_found(tmp_path, draw):
    """Both effects in one TE campaign: the harmonics first (the larger signature), then the TE
    level that changes with speed — a difference between runs, which only a joint test of the
    runs sees (their zero is shared) — and the residual ends at the noise with nothing left."""
    case = kinematic_speed_case(tmp_path, draw)
    d = _diagnose(case.campaign, case.seed)
    added = [s.effect for s in d.steps]
    assert set(added) == {"kinematic_error", "speed_dependence"}, _summary(d)
    assert {1, 2, 39} <= set(d.final.effects["kinematic_error"]), _summary(d)
    assert d.final.rmse_arcsec <= 1.1 * TE_NOISE_RMSE, _summary(d)
    assert all(s.delta_elpd > 2 * s.delta_elpd_se > 0 for s in d.steps), _summary(d)
    assert not d.unexplained, _summary(d)
    _check_finite(d)
