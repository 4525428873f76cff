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


def test_the_constraints_pin_every_dependency_and_numerical_package():
    """constraints.txt (what `make` installs with) pins each declared dependency and each package
    the provenance names to one version: a dependency added without `make lock` fails here."""
    import re
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    pins = {}
    for line in (root / "constraints.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            name, sep, version = line.partition("==")
            assert sep and version, f"constraints.txt: {line!r} is not name==version"
            pins[re.sub(r"[-_.]+", "-", name).lower()] = version
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    declared = project["dependencies"] + [d for extra in project["optional-dependencies"].values() for d in extra]
    names = {re.sub(r"[-_.]+", "-", re.match(r"[A-Za-z0-9_.-]+", d).group()).lower() for d in declared}
    missing = sorted((names | set(NUMERICAL_PACKAGES)) - set(pins))
    assert not missing, f"constraints.txt: no pin for {missing}; run `make lock`"
