"""torsionfit as a library in someone else's session: importing it changes no JAX setting, and
its fits still compute in float64 (JAX's scoped, thread-local switch), also in the batch
sampler's threads. Each check runs in a fresh interpreter: this test process has float64
switched on globally (conftest.py), which is exactly what the library must not rely on."""

import json
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).parent / "benches" / "rv_small_base.toml"
MODULES = ("torsionfit", "torsionfit.io", "torsionfit.model", "torsionfit.fit", "torsionfit.sample",
           "torsionfit.report", "torsionfit.bench", "torsionfit.metrics", "torsionfit.diagnose",
           "torsionfit.accept", "torsionfit.batch", "torsionfit.paper", "torsionfit.plots", "torsionfit.cli")


def _python(code: str, env_x64: str | None = None) -> str:
    """Run ``code`` in a fresh interpreter without any x64 setting from the environment; stdout."""
    env = {k: v for k, v in os.environ.items() if k != "JAX_ENABLE_X64"}
    if env_x64 is not None:
        env["JAX_ENABLE_X64"] = env_x64
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, env=env,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


@pytest.mark.parametrize("before", [False, True])
def test_import_leaves_jax_enable_x64_as_it_was(before):
    out = _python(f"""
        import importlib, jax
        jax.config.update("jax_enable_x64", {before})
        for name in {MODULES!r}:
            importlib.import_module(name)
        print(jax.config.jax_enable_x64)
        """)
    assert out.split() == [str(before)]


# SYNTHETIC units of rv_small_base at 1 Hz; the batch sampler (several units' emcee chains
# advanced together, each in its own thread) started at the bench's truth, and a laplace fit.
# Each function returns the numbers to compare.
_WORKLOAD = """
    import warnings
    from types import SimpleNamespace
    import numpy as np
    import torsionfit
    from torsionfit.batch import run_samplers
    from torsionfit.bench import load_bench, simulate
    from torsionfit.report import FitOptions, fit_campaign, fit_json, prepare_fit

    def unit(path, seed):
        sim = simulate(load_bench(path), seed=seed)
        _, model, problem = prepare_fit(sim.campaign)
        with torsionfit.float64():  # FitProblem's methods are building blocks: the caller's precision
            truth = {"friction_start": np.zeros(model.n_hysteresis), **sim.truth}
            noise = np.concatenate([np.full(problem.n_runs, np.log(1e-6)), np.zeros(problem.n_ar1)])
            u = np.concatenate([problem.physics_u(truth), np.zeros(problem.n_torque_lines), noise])
            sd = np.concatenate([0.01 * np.asarray(problem.prior_sd), np.full(noise.size, 0.1)])
        names = problem.names([r.name for r in sim.campaign.runs])
        return problem, SimpleNamespace(u=u, cov=np.diag(sd**2), names=names)

    def batch_sampler(path):
        warnings.simplefilter("ignore")
        units = [unit(path, seed) for seed in (1, 2)]
        kwargs = [{"check_every": 20, "progress": False, "seed": s, "max_steps": 40} for s in (0, 5)]
        chains = run_samplers([u[0] for u in units], [u[1] for u in units], kwargs)
        return {"dtypes": [str(c.chain.dtype) for c in chains],
                "chains": [np.asarray(c.chain).ravel()[-50:].tolist() for c in chains],
                "log_probs": [np.asarray(c.log_prob).ravel()[-50:].tolist() for c in chains]}

    def laplace_fit(path):
        warnings.simplefilter("ignore")
        fit = fit_campaign(simulate(load_bench(path), seed=1).campaign, FitOptions(sampler="laplace"), seed=0)
        metric = fit_json(fit)["metrics"]["stiffness_rated"]
        return {"dtypes": [str(fit.map_result.u.dtype)], "log_density": [float(fit.map_result.log_density)],
                "stiffness_rated": [metric["mean"], metric["sd"]]}

    def diagnosis(path):
        # the base fit alone (no refits), then the report a script writes: its final metrics
        # (widened for misfit, Laplace draws) are computed after diagnose() has returned
        import tempfile
        from torsionfit.diagnose import DiagnoseOptions, diagnose, write_diagnosis
        warnings.simplefilter("ignore")
        campaign = simulate(load_bench(path), seed=1).campaign
        d = diagnose(campaign, DiagnoseOptions(max_effects=0), seed=0)
        with tempfile.TemporaryDirectory() as out:
            final = write_diagnosis(d, campaign, out, seed=0)["final_metrics"]
        metric = final["metrics"]["stiffness_rated"]
        return {"dtypes": [str(d.final.map_result.u.dtype)], "misfit_inflation": [final["misfit_inflation"]],
                "stiffness_rated": [metric["mean"], metric["sd"]]}
"""


def _scoped_and_global(tmp_path, work: str) -> tuple[dict, dict]:
    """``work(bench)`` in a fresh interpreter (float64 never switched on globally: checked after,
    with the user's own JAX still float32) and in this process (switched on globally)."""
    path = tmp_path / "bench.toml"
    path.write_text(BENCH.read_text().replace("sample_rate_Hz = 5.0", "sample_rate_Hz = 1.0"))
    out = _python(_WORKLOAD + f"""
    import json, jax, jax.numpy as jnp
    result = {work}({str(path)!r})
    result["after"] = [jax.config.jax_enable_x64, str(jnp.ones(3).dtype)]
    print(json.dumps(result))
    """)
    scoped = json.loads(out.strip().splitlines()[-1])
    assert scoped.pop("after") == [False, "float32"]
    assert set(scoped.pop("dtypes")) == {"float64"}
    namespace: dict = {}
    exec(textwrap.dedent(_WORKLOAD), namespace)
    with warnings.catch_warnings():
        reference = namespace[work](str(path))
    reference.pop("dtypes")
    assert scoped.keys() == reference.keys()
    return scoped, reference


def test_the_batch_samplers_threads_compute_in_float64_without_touching_the_session(tmp_path):
    """Each unit's emcee runs in a thread of its own, which does not inherit the caller's scoped
    switch: the chains equal those of a process with float64 on globally (float32 anywhere on
    the way would move them by ~1e-7)."""
    scoped, reference = _scoped_and_global(tmp_path, "batch_sampler")
    for key in scoped:
        np.testing.assert_allclose(np.array(scoped[key]), np.array(reference[key]), rtol=1e-10, atol=1e-12)


@pytest.mark.slow  # compiling the MAP fit twice (two processes) takes a minute or two on 2 cores
def test_a_fit_computes_in_float64_without_touching_the_session(tmp_path):
    scoped, reference = _scoped_and_global(tmp_path, "laplace_fit")
    for key in scoped:
        np.testing.assert_allclose(scoped[key], reference[key], rtol=1e-10)


def test_import_leaves_the_matplotlib_backend_as_it_was():
    """A notebook's inline backend must survive ``import torsionfit.plots`` (and the paper,
    accept and diagnose figures): no matplotlib.use() on import."""
    out = _python(f"""
        import importlib, matplotlib
        matplotlib.use("svg")
        for name in {MODULES!r} + ("torsionfit.paper.figures", "torsionfit.accept._figure"):
            importlib.import_module(name)
        from torsionfit.diagnose import _report
        _report._plt()
        print(matplotlib.get_backend())
    """)
    assert out.strip().lower() == "svg"


@pytest.mark.slow  # a base fit, its signatures and the report's Laplace draws, twice (two processes)
def test_a_diagnosis_report_computes_in_float64_without_touching_the_session(tmp_path):
    """``write_diagnosis`` refits nothing but widens the final fit for misfit and draws its
    metrics after ``diagnose`` has returned: outside diagnose's scope, as a script calls it
    (float32 there moved the misfit inflation and the metrics of the committed trails)."""
    scoped, reference = _scoped_and_global(tmp_path, "diagnosis")
    for key in scoped:
        np.testing.assert_allclose(scoped[key], reference[key], rtol=1e-8)
