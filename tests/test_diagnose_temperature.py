"""Closing the loop across temperatures: the ``temperature_dependence`` signature on a
SYNTHETIC campaign whose runs sit at different temperatures and whose stiffness and friction
move with them (switched on in the bench, never named in the written manifest — only each
run's ``temperature_C`` is), and on the same campaign without it; the effect's fit recovers
both coefficients.

The bench ``tests/benches/effects/te_temperature.toml``: one loop at 40 °C and TE runs at one
load and speed in both directions at 25, 40 and 55 °C. Cases are shared with
``scripts/diagnose_zoo.py``.
"""

from pathlib import Path

import numpy as np
import pytest

from torsionfit.diagnose import DiagnoseOptions

from test_diagnose import Case, _seed, _undeclared_campaign

pytestmark = pytest.mark.slow

BENCH = Path(__file__).parent / "benches" / "effects" / "te_temperature.toml"
DIAGNOSE_ALPHA = DiagnoseOptions().alpha


def temperature_case(folder: Path, index: int, clean: bool = False) -> Case:
    """Case ``index``: α_C (compliance per kelvin) and α_f (friction level per kelvin) drawn
    from seeded ranges — index 0 both, index 1 the friction level only, as oil viscosity
    would; ``clean``: the same campaign without the effect."""
    rng = np.random.default_rng(_seed("temperature", index))
    if clean:
        effects, truth = {}, {}
    else:
        compliance = 0.0 if index % 2 else rng.choice([-1.0, 1.0]) * rng.uniform(0.002, 0.005)
        effects = {"temperature_dependence": True}
        truth = {"temperature_compliance_per_K": compliance, "temperature_friction_per_K": -rng.uniform(0.02, 0.04)}
    campaign, _ = _undeclared_campaign(folder, effects, truth, _seed("temperature noise", index, clean), (), BENCH)
    print("temperature case", index, "clean" if clean else truth)
    return Case(campaign, _seed("temperature diagnose", index) % 1000, effects, truth)


def _temperature_signature(case: Case):
    """The temperature signature at the base model's MAP — what ``diagnose`` ranks first."""
    from torsionfit.diagnose import CATALOG
    from torsionfit.diagnose._context import fit_context
    from torsionfit.fit import build_problem, fit_map
    from torsionfit.model import model_with_effects

    campaign = case.campaign
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm, free_friction_start=True)
    problem = build_problem(campaign, model)
    result = fit_map(problem, [r.name for r in campaign.runs], n_starts=DiagnoseOptions().n_starts, seed=case.seed)
    ctx = fit_context(campaign, {}, result)
    effect = next(e for e in CATALOG if e.name == "temperature_dependence")
    assert effect.applicable(ctx)
    return effect.signature(ctx, DIAGNOSE_ALPHA), ctx


def test_temperature_signature_found_with_it_and_not_without(tmp_path):
    """At the base model's MAP the temperature signature is overwhelming when compliance and
    friction move with temperature (and the extension keeps the friction coefficient: every
    temperature resolves it), and not significant on the same campaign without the effect. The
    whole loop — added first, closing to the noise, nothing else added — is the diagnose zoo's
    (scripts/diagnose_zoo.py, docs/diagnose/zoo.md: three temperature cases), out of the suite for
    its length."""
    (tmp_path / "on").mkdir()
    (tmp_path / "off").mkdir()
    found, ctx = _temperature_signature(temperature_case(tmp_path / "on", 0))
    assert found.significant(DIAGNOSE_ALPHA) and found.log10_p < -100, found
    assert found.details["friction"] and found.details["reference_C"] == 40.0, found.details
    clean, _ = _temperature_signature(temperature_case(tmp_path / "off", 0, clean=True))
    assert not clean.significant(DIAGNOSE_ALPHA), clean


def test_temperature_fit_recovers_both_coefficients(tmp_path):
    """The effect declared, a Laplace fit: α_C and α_f inside their 95 % HDIs, the stiffness at
    the reference temperature (40 °C) within 0.2 % (this noise draw puts it 3 posterior sd
    high, +0.10 %, with the friction level +2.8 %: the two trade along the TE span
    2C(|τ| + T_f); other draws land within 2 sd), and fit.json names the reference."""
    import json

    from torsionfit.report import FitOptions, fit_campaign, fit_json

    case = temperature_case(tmp_path, 0)
    fit = fit_campaign(case.campaign, FitOptions(sampler="laplace", n_starts=2, laplace_draws=2000, metric_draws=400,
                                                 progress=False, effects=case.effects), seed=2)
    doc = json.loads(json.dumps(fit_json(fit)))
    assert doc["diagnostics"]["converged"], doc["diagnostics"]
    assert doc["reference_temperature_C"] == 40.0 and doc["temperatures_C"] == [25.0, 40.0, 55.0]
    for name, key in (("temperature_compliance", "temperature_compliance_per_K"),
                      ("temperature_friction", "temperature_friction_per_K")):
        p = doc["parameters"][name]
        assert p["hdi95"][0] <= case.truth[key] <= p["hdi95"][1], (name, p, case.truth)
    k = doc["parameters"]["stiffness"]
    truth_k = 108.0 * 60 * 180 / np.pi  # N·m/rad
    assert k["mean"] == pytest.approx(truth_k, rel=0.002), k
    # the effect is recovered, not absorbed: α_C is resolved away from zero
    p = doc["parameters"]["temperature_compliance"]
    assert p["hdi95"][0] > 0 or p["hdi95"][1] < 0, p
