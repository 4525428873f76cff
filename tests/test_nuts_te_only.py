"""NUTS on a campaign of TE runs alone (the SYNTHETIC TE export of tests/benches/te_export.toml):
the lost-motion coordinates and the starts drawn in the sampler's coordinates. In a file of its
own, so that it runs in the parallel pool (one compiled NUTS program) rather than in
tests/test_nuts.py's process."""

from pathlib import Path

import jax.numpy as jnp
import numpy as np
import pytest

import torsionfit  # noqa: F401  (enables float64 in JAX)
from torsionfit.report import FitOptions
from torsionfit.sample import Coordinates, run_nuts

# sampling runs its programs far longer than it compiles them (tests/conftest.py)
pytestmark = pytest.mark.runtime_bound

BENCHES = Path(__file__).parent / "benches"


@pytest.mark.slow
def test_nuts_follows_the_lost_motion_ridge_of_a_te_export(tmp_path):
    """The SYNTHETIC TE export campaign (tests/benches/te_export.toml, block means of 8): gap
    and friction only show together there. With the lost-motion coordinates and starts drawn
    in the sampler's coordinates, the starts lie on the ridge, trajectories stay short and
    nothing diverges — before, with the gap's closing torque free and starts drawn in u, the
    chains spent their warm-up at the deepest trees (hundreds of leapfrog steps per draw)."""
    from torsionfit.bench import load_bench, simulate, write_te_export
    from torsionfit.fit import fit_map
    from torsionfit.io import load_campaign
    from torsionfit.report._pipeline import prepare_fit
    from torsionfit.sample._nuts import _densities, _initial_positions

    bench = load_bench(BENCHES / "te_export.toml")
    campaign = load_campaign(write_te_export(simulate(bench), bench, tmp_path / "export"))
    campaign, _, problem = prepare_fit(campaign, FitOptions(effects={"kinematic_error": [1, 2, 39]}, decimate=8))
    m = fit_map(problem, [r.name for r in campaign.runs], n_starts=2, seed=1)
    coords = Coordinates.of(problem).whitened(m.u, m.cov, problem)
    assert coords.lost_motion
    # the starts: Laplace draws in the sampler's coordinates land on the ridge
    z = _initial_positions(problem, coords, 8, np.random.default_rng(0))
    lp = np.asarray(_densities(problem, coords, jnp.asarray(z)))
    lp_map = float(_densities(problem, coords, jnp.zeros((1, problem.dim)))[0])
    assert np.all(lp > lp_map - 4 * problem.dim), lp - lp_map
    res = run_nuts(problem, m, seed=0, n_chains=4, n_warmup=150, initial_draws=100, max_draws=100, progress=False)
    steps = np.asarray(res.step_size)
    assert res.n_divergent == 0 and steps.max() < 2 * steps.min(), steps
    # 16.5 leapfrog steps per draw here, with the gap's closing share sampled as logit q or as
    # log β − logit q alike: on block means of 8 the no-load runs resolve that share too coarsely
    # for its funnel to matter; at full resolution it does (docs/benchmarks.md, the TE campaign)
    assert float(np.mean(res.n_leapfrog)) < 32, float(np.mean(res.n_leapfrog))
