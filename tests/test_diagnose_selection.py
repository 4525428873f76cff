"""Model selection for closing the loop (fast): the drift shapes, the linearised LOO against
brute-force leave-one-out, and the rule that picks the criterion."""

import numpy as np
import pytest

from torsionfit.model import model_with_effects, te_input
from torsionfit.model._drift import WARM_UP_FRACTIONS
from torsionfit._errors import InputError


def test_warm_up_drift_is_the_linear_drift_plus_saturating_exponentials():
    model = model_with_effects(["transmission_error", "transmission_error"], {"thermal_drift": "warm_up"}, 380.0)
    names = [p.name for p in model.parameters()]
    assert "drift" in names and "drift_warmup" in names
    t = np.linspace(5.0, 105.0, 201)  # the run starts at 5 s: drift counts from its first sample
    phi = np.linspace(0.0, 2 * np.pi, 201)
    inputs = [te_input(phi, 100.0, 5.0, 1, t), te_input(phi, 100.0, 5.0, -1, t)]
    values = {p.name: np.zeros(p.size) if p.linear else 1.0 for p in model.parameters()}
    amps = np.arange(1.0, 1.0 + 2 * len(WARM_UP_FRACTIONS))
    values["drift"] = np.array([0.0, 2e-3])
    values["drift_warmup"] = amps
    comps = model.components(values, inputs)
    tau = 100.0 * np.asarray(WARM_UP_FRACTIONS)
    k = len(WARM_UP_FRACTIONS)
    for r in range(2):
        expected = values["drift"][r] * (t - 5.0) + (1 - np.exp(-(t - 5.0)[:, None] / tau[None, :])) @ amps[r * k:(r + 1) * k]
        np.testing.assert_allclose(np.asarray(comps[r]["drift"]), expected, rtol=1e-12, atol=1e-15)
    linear = model_with_effects(["transmission_error"], {"thermal_drift": True}, 380.0)
    assert [p.name for p in linear.parameters() if p.name.startswith("drift")] == ["drift"]
    with pytest.raises(InputError, match="thermal_drift"):
        model_with_effects(["transmission_error"], {"thermal_drift": "quadratic"}, 380.0)
