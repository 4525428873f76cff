"""emcee for several units at once (torsionfit.batch.run_samplers): each unit's chain equals
``run_sampler`` on that unit alone; units stopping at different steps and a unit that fails do
not hold up the others. SYNTHETIC units of tests/benches/rv_small_base.toml at 1 Hz, started at
the bench's truth (a stand-in for the MAP, which takes long to compile); short chains."""

import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from torsionfit.batch import UnitBatcher, run_samplers
from torsionfit.bench import load_bench, simulate
from torsionfit.report import prepare_fit
from torsionfit.sample import ConvergenceWarning, run_sampler

# sampling runs its programs far longer than it compiles them (tests/conftest.py)
pytestmark = pytest.mark.runtime_bound

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
SHORT = {"check_every": 20, "progress": False}


def _unit(path, seed):
    """(problem, start): the start a small Gaussian around the truth, in u."""
    sim = simulate(load_bench(path), seed=seed)
    _, model, problem = prepare_fit(sim.campaign)
    truth = {"friction_start": np.zeros(model.n_hysteresis), **sim.truth}
    noise = np.concatenate([np.full(problem.n_runs, np.log(1e-6)), np.zeros(problem.n_ar1)])
    u = np.concatenate([problem.physics_u(truth), np.zeros(problem.n_torque_lines), noise])
    sd = np.concatenate([0.01 * np.asarray(problem.prior_sd), np.full(noise.size, 0.1)])
    return problem, SimpleNamespace(u=u, cov=np.diag(sd**2), names=problem.names([r.name for r in sim.campaign.runs]))


@pytest.fixture(scope="module")
def units(tmp_path_factory):
    path = tmp_path_factory.mktemp("bench") / "bench.toml"
    path.write_text(BENCH.read_text().replace("sample_rate_Hz = 5.0", "sample_rate_Hz = 1.0"))
    return [_unit(path, seed) for seed in (1, 2, 3)]


def _alone(problem, start, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        return run_sampler(problem, start, **kwargs)


def _same_chain(a, b):
    assert (a.n_steps, a.burn_in, a.thin, a.converged, a.reason) == (b.n_steps, b.burn_in, b.thin, b.converged, b.reason)
    np.testing.assert_allclose(b.chain, a.chain, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(b.log_prob, a.log_prob, rtol=1e-9)
    np.testing.assert_array_equal(b.acceptance_fraction, a.acceptance_fraction)


def test_units_sampled_together_equal_each_alone_also_when_they_stop_at_different_steps(units):
    """Three units with their own seeds and max_steps 40, 60, 100: the first two stop early
    (unconverged, as run_sampler does) and the calls shrink to two lanes, then to one."""
    problems, starts = zip(*units)
    kwargs = [{**SHORT, "seed": s, "max_steps": n} for s, n in ((0, 40), (5, 60), (9, 100))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        together = run_samplers(list(problems), list(starts), kwargs)
    for problem, start, kw, b in zip(problems, starts, kwargs, together):
        a = _alone(problem, start, **kw)
        assert not a.converged and "max_steps" in a.reason and b.n_steps == kw["max_steps"]
        _same_chain(a, b)


def test_a_unit_that_fails_is_its_result_and_the_others_go_on(units):
    """A start with NaN never gives a finite walker: initial_walkers gives up after its 100
    rounds (200 calls of the shared log-density) while the others sample on."""
    (p1, s1), (p2, s2), _ = units
    broken = SimpleNamespace(u=np.full_like(s1.u, np.nan), cov=s1.cov, names=s1.names)
    kwargs = [{**SHORT, "seed": 0, "max_steps": 40}] * 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        out = run_samplers([p1, p2, p1], [s1, broken, s1], kwargs)
    assert isinstance(out[1], RuntimeError) and "non-finite log-density" in str(out[1])
    _same_chain(_alone(p1, s1, **kwargs[0]), out[0])
    _same_chain(out[0], out[2])  # same problem, same seed: the same chain


def test_batcher_waits_only_for_running_units(units):
    """One call per round of chunks, on the running units' lanes only."""
    problems, starts = zip(*units)
    batcher = UnitBatcher(list(problems))
    chunk = np.tile(starts[0].u, (16, 1))
    batcher.leave(1)  # units 1 and 2 never ask: unit 0 must not wait for them
    batcher.leave(2)
    lp = batcher.evaluate(0, chunk)
    assert lp.shape == (16,) and np.all(np.isfinite(lp)) and batcher.calls == 1
    assert batcher._stacked[0] == (0,)  # one lane: the units that left are not computed on


def test_a_failing_shared_call_fails_only_the_unit_whose_own_call_fails(units, monkeypatch):
    """The shared units × walkers call raises (as for one unit's bad chunk); each unit is then
    evaluated alone: the good ones get their values, only the bad one its error."""
    import threading

    from torsionfit.batch import _sampler

    problems, starts = zip(*units)
    bad = problems[1]

    def shared(*args):
        raise RuntimeError("the shared call failed")

    alone = _sampler.batch_log_density

    def per_unit(problem, chunk):
        if problem is bad:
            raise ValueError("unit 1's own call failed")
        return alone(problem, chunk)

    monkeypatch.setattr(_sampler, "units_log_density", shared)
    monkeypatch.setattr(_sampler, "batch_log_density", per_unit)
    batcher = UnitBatcher(list(problems))
    chunks = [np.tile(s.u, (16, 1)) for s in starts]
    out = [None] * 3

    def ask(i):
        try:
            out[i] = batcher.evaluate(i, chunks[i])
        except Exception as err:  # noqa: BLE001
            out[i] = err

    threads = [threading.Thread(target=ask, args=(i,)) for i in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=120)
    assert isinstance(out[1], ValueError) and "unit 1" in str(out[1])
    for i in (0, 2):
        np.testing.assert_allclose(out[i], np.asarray(alone(problems[i], chunks[i])), rtol=1e-12)
    assert batcher.calls == 1
