"""Which parameters the data leave at their prior (fit/_contraction.py). The statistics behind
it are in tests/test_fit_statistics.py (a TE-only campaign in one direction leaves the friction
its prior's); fit.json's record of it in tests/test_te_exports_e2e.py."""

from types import SimpleNamespace

import numpy as np

from torsionfit.fit._contraction import (PRIOR_DOMINATED_SD_RATIO, prior_dominated, prior_dominated_named,
                                         prior_dominated_note)


def _problem():
    p = lambda name, size, text: SimpleNamespace(name=name, size=size, description=text)  # noqa: E731
    return SimpleNamespace(physics=[p("stiffness", 1, "elastic stiffness K"), p("friction_torque", 1, "level T_f"),
                                    p("friction_start", 1, "state"), p("slip", 2, "slip shares")],
                           prior_sd=np.array([2.0, 1.0, 1.0, 0.5, 0.5]))


def test_the_posterior_sd_over_the_priors_names_what_the_data_leave_alone():
    rng = np.random.default_rng(1)
    # stiffness sharp; friction_torque, friction_start and slip[0] at their prior's width; then noise
    sd = np.array([0.02, 1.0, 1.0, 0.5, 0.1, 3.0, 3.0])
    draws = rng.standard_normal((20000, sd.size)) * sd
    found = prior_dominated(_problem(), draws)
    assert set(found) == {"friction_torque", "friction_start", "slip[0]"}
    assert all(abs(r - 1.0) < 0.03 for r in found.values())
    note = prior_dominated_note(found, _problem())
    # named: the reducer's scalar parameters; not the state before the first sample, nor one
    # element of a shape (the data pin a whole, not each element)
    assert note.startswith("the data barely inform friction_torque (level T_f: posterior sd 1.00× the prior's)")
    assert "friction_start" not in note and "slip" not in note
    assert prior_dominated_named(found, _problem()) == ["friction_torque"]
    assert prior_dominated_note({"friction_start": 1.0, "slip[0]": 1.0}, _problem()) is None
    # just below the bound: informed
    draws[:, 1] *= 0.95 * PRIOR_DOMINATED_SD_RATIO
    assert "friction_torque" not in prior_dominated(_problem(), draws)
    assert prior_dominated(_problem(), draws[:1]) == {}
