"""The provenance every JSON output carries: the numerical environment beside version, seed and
command line (a fit is deterministic on one environment, not across them)."""

import json

import jax
import numpy as np

from torsionfit._provenance import NUMERICAL_PACKAGES, environment, provenance


def test_environment_names_the_packages_and_processor_a_rerun_must_match():
    env = environment()
    assert env["jax"] == jax.__version__ and env["numpy"] == np.__version__
    assert set(NUMERICAL_PACKAGES) <= set(env) and env["python"].count(".") == 2
    assert isinstance(env["cpu"], str) and env["cpu"]


def test_provenance_is_json_and_holds_the_environment():
    doc = json.loads(json.dumps(provenance(3, "torsionfit fit c.toml --seed 3")))
    assert doc == {"torsionfit_version": doc["torsionfit_version"], "seed": 3,
                   "command": "torsionfit fit c.toml --seed 3", "environment": environment()}
