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
@pytest.mark.extended
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
    assert res.n_divergent == 0
    # Dual averaging over 150 warm-up steps leaves the chains' step sizes up to ~2.2x apart on
    # this posterior (seeds 0-2: 1.1-2.2x) while their trajectories stay alike; a chain caught
    # where the ridge narrows adapts a step many times smaller and runs the deepest trees
    steps = np.asarray(res.step_size)
    assert steps.max() < 4 * steps.min(), steps
    # 14-22 leapfrog steps per draw on average here (seeds 0-2; 14-29 per chain), with the gap's
    # closing share sampled as logit q or as log β − logit q alike: on block means of 8 the
    # no-load runs resolve that share too coarsely for its funnel to matter; at full resolution
    # it does (docs/benchmarks.md, the TE campaign). Before the lost-motion coordinates: hundreds
    per_chain = np.mean(np.asarray(res.n_leapfrog), axis=0)
    assert per_chain.mean() < 32 and per_chain.max() < 64, per_chain
