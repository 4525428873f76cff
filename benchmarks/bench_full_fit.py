#!/usr/bin/env python
"""Benchmark: the full analysis of one hysteresis loop — MAP + emcee to convergence — with
torsionfit against the best plain NumPy/SciPy pipeline for the same model and data.

The loop is simulated by the virtual bench (``benchmarks/benches/full_fit_10k.toml``: one
five-step loop, 10 001 samples, 1″ AR(1) angle noise, 1″ encoder, 1.5 N·m torque noise;
``--quick`` uses ``full_fit_2k.toml``, 2 001 samples). Both sides fit the same posterior —
the default ``fit_campaign`` configuration: base model with a free initial friction state,
latent torque knots, errors-in-variables variance, AR(1) noise, angle offset profiled —
with the same algorithm (4-start Levenberg–Marquardt MAP with noise re-estimation, Laplace
start, emcee with run_sampler's moves, walkers, seed and stopping rule):

- **torsionfit**: ``build_problem`` → ``fit_map`` → ``run_sampler``, as ``fit_campaign``
  calls them; JAX compilation included, and measured separately (``jax.monitoring``
  compile events; and a second, warm run in the same process).
- **NumPy/SciPy**: ``_scipy_pipeline.py`` — ``scipy.optimize.least_squares`` (MINPACK LM)
  for the MAP, a NumPy log-density vectorised over walkers, emcee for the posterior.
  ``tests/test_scipy_pipeline_reference.py`` checks its log-density equals torsionfit's.

Reported: wall time per stage, bulk ESS of the physical parameters (min over parameters,
``arviz_stats.ess`` on both chains after the same burn-in and thinning), ESS per second, and
the ratio of end-to-end time at equal ESS (the NumPy side's time to torsionfit's ESS, from
its measured ESS rate).

    python benchmarks/bench_full_fit.py            # full run (~5–8 min on 2 cores)
    python benchmarks/bench_full_fit.py --quick    # smoke run: 2 001 samples

The full run writes benchmarks/results/full_fit.md (``--output`` to change; ``--quick``
writes only when ``--output`` is given). SciPy is needed only here; it is not a torsionfit
dependency.
"""

import os

# One OpenBLAS thread: on a 2-core machine OpenBLAS's worker threads made the NumPy side's
# (samples × knots)·(knots × walkers) product 100× slower (10 ms instead of 0.1 ms) and, by
# spinning after each call, slowed its recurrence loop ~3×. XLA does not use OpenBLAS.
# Must be set before NumPy is imported.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from collections import defaultdict  # noqa: E402
from contextlib import contextmanager  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

try:
    import scipy  # noqa: F401
except ImportError:
    sys.exit("bench_full_fit.py needs SciPy for the NumPy/SciPy side (it is not a torsionfit "
             "dependency): install it into the venv, e.g. `.venv/bin/python -m pip install scipy`.")

import arviz_stats  # noqa: E402
import emcee  # noqa: E402
import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.monitoring  # noqa: E402
import jax.numpy as jnp  # noqa: E402

# this script calls torsionfit's internals directly: its process in float64, as torsionfit's fits
jax.config.update("jax_enable_x64", True)

import _scipy_pipeline as sp  # noqa: E402
from _machine import machine  # noqa: E402
import torsionfit.sample._emcee as tf_emcee  # noqa: E402
from torsionfit.sample._emcee import MOVES_DESCRIPTION  # noqa: E402
from torsionfit.bench import load_bench, simulate  # noqa: E402
from torsionfit.fit import NoiseOptions, build_problem, fit_map  # noqa: E402
from torsionfit.model import model_with_effects  # noqa: E402
from torsionfit.report import FitOptions  # noqa: E402
import torsionfit.model._friction as tf_friction  # noqa: E402
from torsionfit.sample import run_sampler  # noqa: E402

SEED = 0
GOAL_RATIO = 20.0
GOAL_WALL_S = 20.0
COMPILE_EVENTS = {
    "/jax/core/compile/jaxpr_trace_duration": "trace",
    "/jax/core/compile/jaxpr_to_mlir_module_duration": "lower",
    "/jax/core/compile/backend_compile_duration": "XLA compile",
}


# --- measurement helpers ------------------------------------------------------------------
class CompileClock:
    """Sums JAX's compile-stage durations (trace, lower to MLIR, XLA compile) per phase."""

    def __init__(self):
        self.phase = None
        self.by_phase = defaultdict(lambda: defaultdict(float))
        self.count = defaultdict(int)  # XLA compilations per phase
        jax.monitoring.register_event_duration_secs_listener(self._listen)

    def _listen(self, event, duration, **kwargs):
        stage = COMPILE_EVENTS.get(event)
        if stage is not None and self.phase is not None:
            self.by_phase[self.phase][stage] += duration
            if stage == "XLA compile":
                self.count[self.phase] += 1

    def total(self, phase) -> float:
        return float(sum(self.by_phase[phase].values()))


class CallTimer:
    """Wall time spent inside a callable (the log-density handed to emcee)."""

    def __init__(self, fn):
        self.fn, self.seconds, self.calls = fn, 0.0, 0

    def __call__(self, *args, **kwargs):
        t0 = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.seconds += time.perf_counter() - t0
            self.calls += 1


@contextmanager
def patched(obj, name, value):
    old = getattr(obj, name)
    setattr(obj, name, value)
    try:
        yield
    finally:
        setattr(obj, name, old)


def min_bulk_ess(chain: np.ndarray, n_physics: int, names) -> tuple[float, str, dict]:
    """Bulk ESS (arviz_stats, walkers as chains) of the first ``n_physics`` entries of u in a
    (draws, walkers, dim) chain: (min, its name, all). Bulk ESS is rank-normalised, so it is
    the same for u and for the constrained value."""
    ess = {names[j]: float(arviz_stats.ess(np.ascontiguousarray(chain[:, :, j].T), method="bulk"))
           for j in range(n_physics)}
    k = min(ess, key=ess.get)
    return ess[k], k, ess


def interleaved_median_ms(fns: dict, repeats: int) -> dict:
    """Median wall time and median CPU time of this process (ms) per callable, calling them in
    turn after one warm-up each, so that load from other processes on a shared machine hits
    every candidate alike. CPU time (all threads) is the load-robust cross-check: a
    descheduled process accrues none."""
    for fn in fns.values():
        fn()
    wall, cpu = {k: [] for k in fns}, {k: [] for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            wall[k].append(time.perf_counter() - t0)
            cpu[k].append(time.process_time() - c0)
    out = {k: 1e3 * statistics.median(v) for k, v in wall.items()}
    out.update({k + "_cpu": 1e3 * statistics.median(v) for k, v in cpu.items()})
    return out


def say(msg):
    print(msg, file=sys.stderr, flush=True)


# --- the two pipelines ----------------------------------------------------------------------
def run_torsionfit(campaign, clock: CompileClock, label: str):
    """build_problem → fit_map → run_sampler, as fit_campaign calls them; times per stage."""
    names = [r.name for r in campaign.runs]
    out = {"times": {}}
    timer = {}

    original = tf_emcee._LogProb.__call__

    def timed_call(self, coords):
        t0 = time.perf_counter()
        try:
            return original(self, coords)
        finally:
            timer["s"] = timer.get("s", 0.0) + time.perf_counter() - t0
            timer["n"] = timer.get("n", 0) + 1
            rows = len(np.atleast_2d(coords))
            timer["chunks"] = timer.get("chunks", 0) - (-rows // (self.batch or rows))

    c0, t0 = time.process_time(), time.perf_counter()
    clock.phase = f"{label}:build"
    model = model_with_effects([r.kind for r in campaign.runs], {}, campaign.reducer.rated_torque_Nm,
                               free_friction_start=True)
    problem = build_problem(campaign, model, NoiseOptions())
    t1 = time.perf_counter()
    clock.phase = f"{label}:map"
    steps = FitOptions().map_steps  # fit_campaign's LM budget, as the NumPy side's
    map_result = fit_map(problem, names, n_starts=4, seed=SEED, max_steps=steps, polish_steps=steps)
    t2, c2 = time.perf_counter(), time.process_time()
    clock.phase = f"{label}:sample"
    with patched(tf_emcee._LogProb, "__call__", timed_call), warnings.catch_warnings():
        warnings.simplefilter("ignore", tf_emcee.ConvergenceWarning)
        result = run_sampler(problem, map_result, seed=SEED, max_steps=20_000, progress=False)
    t3, c3 = time.perf_counter(), time.process_time()
    clock.phase = None
    out["times"] = {"build": t1 - t0, "map": t2 - t1, "sample": t3 - t2, "total": t3 - t0, "cpu": c3 - c0,
                    "cpu_sample": c3 - c2}
    out["compile"] = {k: clock.total(f"{label}:{k}") for k in ("build", "map", "sample")}
    out["compile_stages"] = {k: dict(clock.by_phase[f"{label}:{k}"]) for k in ("build", "map", "sample")}
    out["compile_count"] = {k: clock.count[f"{label}:{k}"] for k in ("build", "map", "sample")}
    out.update(problem=problem, map=map_result, result=result, logp_s=timer.get("s", 0.0),
               logp_calls=timer.get("n", 0), logp_chunks=timer.get("chunks", 0))
    return out


def run_numpy(campaign, budget_s):
    """The NumPy/SciPy pipeline; times per stage, log-density and recurrence-loop time."""
    loop = CallTimer(sp._affine_rows)
    c0, t0 = time.process_time(), time.perf_counter()
    problem = sp.build(campaign)
    t1 = time.perf_counter()
    map_result = sp.fit_map(problem, n_starts=4, seed=SEED)
    t2, c2 = time.perf_counter(), time.process_time()
    logp = CallTimer(problem.log_density)

    def progress(step, tau_max, elapsed):
        say(f"    numpy emcee: {step} steps, τ_max {tau_max:.1f}, {elapsed:.0f} s")

    with patched(sp, "_affine_rows", loop):
        result = sp.run_emcee(_ProblemProxy(problem, logp), map_result, seed=SEED, budget_s=budget_s,
                              progress=progress)
    t3, c3 = time.perf_counter(), time.process_time()
    return {"times": {"build": t1 - t0, "map": t2 - t1, "sample": t3 - t2, "total": t3 - t0, "cpu": c3 - c0,
                      "cpu_sample": c3 - c2},
            "problem": problem, "map": map_result, "result": result, "logp_s": logp.seconds,
            "logp_calls": logp.calls, "loop_s": loop.seconds}


class _ProblemProxy:
    """The NumPy problem with its log-density replaced by a timed wrapper."""

    def __init__(self, problem, logp):
        self._problem, self._logp = problem, logp

    def __getattr__(self, name):
        return getattr(self._problem, name)

    def log_density(self, u):
        return self._logp(u)

    def __call__(self, u):
        return self._logp(u)


# --- per-call costs after the runs ------------------------------------------------------------
def per_call_costs(tf, npy):
    """Median ms of one log-density call on half the ensemble (what emcee asks for), and of
    the model forward alone, on each side, at the final walkers."""
    half = tf["result"].chain[-1][: tf["result"].n_walkers // 2]
    u_tf = jnp.asarray(half)
    problem = tf["problem"]
    fwd = eqx.filter_jit(eqx.filter_vmap(lambda p, u: p.nonlinear_prediction(u[:p.n_nonlinear])[0],
                                         in_axes=(None, 0)))
    p = npy["problem"]
    half_np = npy["result"].chain[-1][: npy["result"].chain.shape[1] // 2]
    tau = p.tau[:, None] + p.basis @ half_np[:, p.n_model:p.n_nonlinear].T
    d = np.diff(tau, axis=0)
    a = np.exp(-np.abs(d) / np.exp(half_np[:, 2]))
    b = np.sign(d) * (1 - a)
    z0 = np.tanh(half_np[:, 5])
    buf = np.empty_like(tau)
    # What the Dahl recurrence costs inside the compiled log-density (timed alone, a vmapped scan
    # compiles to a different layout): the same log-density with the recurrence replaced by an
    # element-wise stand-in x[n] = a[n]·x0 + b[n] (a wrong model, for timing only)
    with patched(tf_friction, "affine_scan", lambda a, b, x0, method="auto": a * x0 + b):
        # a new jit of run_sampler's own per-walker log-density (its compiled program is cached)
        no_scan = eqx.filter_jit(eqx.filter_vmap(tf_emcee._log_density_one, in_axes=(None, 0)))
        jax.block_until_ready(no_scan(problem, u_tf))  # traced (and compiled) with the stand-in
    # JAX and NumPy candidates in separate rounds: XLA's worker threads stay busy for a
    # moment after a call and would be charged to the NumPy call that follows
    tf_logp = tf_emcee.bound_log_density(problem)  # what run_sampler's emcee calls
    out = interleaved_median_ms({
        "tf_logp": lambda: np.asarray(tf_logp(u_tf)),
        "tf_forward": lambda: jax.block_until_ready(fwd(problem, u_tf)),
        "tf_logp_no_scan": lambda: jax.block_until_ready(no_scan(problem, u_tf)),
    }, 30)
    out.update(interleaved_median_ms({
        "np_logp": lambda: p.log_density(half_np),
        "np_logp_runs": lambda: p.log_density(half_np, recurrence="runs"),
        "np_forward": lambda: p.predict(half_np),
        "np_loop": lambda: sp._affine_rows(a, b, z0, buf),
    }, 15))
    out["half"] = len(half)
    sign = np.sign(np.diff(p.tau))
    sign = sign[sign != 0]
    out["runs"] = int(1 + np.sum(sign[1:] != sign[:-1]))
    return out


def disk_cache_child(bench_path: Path, cache_dir: Path) -> None:
    """In a new process: the torsionfit pipeline with JAX's disk cache in ``cache_dir`` (as the
    command line keeps it); prints its times as one JSON line."""
    from torsionfit._cache import enable_compilation_cache

    enable_compilation_cache(cache_dir)
    campaign = simulate(load_bench(bench_path)).campaign
    clock = CompileClock()
    tf = run_torsionfit(campaign, clock, "disk")
    print(json.dumps({"total": tf["times"]["total"], "compile": sum(tf["compile"].values()),
                      "map": tf["times"]["map"], "sample": tf["times"]["sample"]}))


def run_with_disk_cache(quick: bool) -> dict:
    """Two new processes on one fresh disk cache: the first compiles and fills it, the second
    reads it — the second campaign of a shape with the command line. Times of the second."""
    with tempfile.TemporaryDirectory(prefix="torsionfit-bench-cache-") as folder:
        cmd = [sys.executable, str(Path(__file__).resolve()), "--disk-cache-child", folder] + (["--quick"] if quick else [])
        runs = []
        for _ in range(2):
            proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
            runs.append(json.loads(proc.stdout.strip().splitlines()[-1]))
    return {"first": runs[0], "second": runs[1]}


# --- report ---------------------------------------------------------------------------------
def f(x, spec=".1f"):
    return "—" if x is None else format(x, spec)


def build_report(args, info, bench_path, n_samples, tf, warm, npy, costs, loads, wall, disk=None):
    r_tf, r_np = tf["result"], npy["result"]
    n_phys = tf["problem"].n_model
    names = list(tf["map"].names)
    ess_tf, who_tf, all_tf = min_bulk_ess(r_tf.chain, n_phys, names)
    ess_np, who_np, all_np = min_bulk_ess(r_np.chain, n_phys, names)
    t_tf, t_np = tf["times"], npy["times"]
    compile_tf = sum(tf["compile"].values())
    warm_total = warm["times"]["total"] if warm else None

    # time to torsionfit's ESS on the NumPy side: its build + MAP, then sampling at its
    # measured ESS rate (sampling time per unit of ESS, burn-in included)
    target = ess_tf
    np_sample_to_target = r_np.sampling_s * target / ess_np
    np_to_target = t_np["build"] + t_np["map"] + (t_np["sample"] - r_np.sampling_s) + np_sample_to_target
    ratio = np_to_target / t_tf["total"]
    # the same on CPU time (load-robust): the NumPy emcee CPU time scaled like its wall time
    np_cpu_to_target = t_np["cpu"] - t_np["cpu_sample"] + t_np["cpu_sample"] * target / ess_np
    ratio_cpu = np_cpu_to_target / t_tf["cpu"]
    scaled = "extrapolated" if ess_np < target else "scaled down"
    ratio_warm = np_to_target / warm_total if warm else None
    sampling_ratio = np_sample_to_target / t_tf["sample"]
    extrapolated = r_np.budget_hit or not r_np.converged
    steps_tf, steps_np = r_tf.n_steps, r_np.n_steps

    def x(num, den):
        return f"{num / den:.2f}×" if den > 0 else "—"

    rows = [
        ("loop samples", f"{n_samples}", f"{n_samples}", ""),
        ("parameters (dim of u) / physical / walkers",
         f"{tf['problem'].dim} / {n_phys} / {r_tf.n_walkers}",
         f"{npy['problem'].dim} / {npy['problem'].n_model} / {r_np.chain.shape[1]}", ""),
        ("build problem (s)", f(t_tf["build"], ".2f"), f(t_np["build"], ".2f"), x(t_np["build"], t_tf["build"])),
        ("MAP, 4 starts, 3 noise passes (s)", f(t_tf["map"], ".2f"), f(t_np["map"], ".2f"), x(t_np["map"], t_tf["map"])),
        ("emcee (s)", f(t_tf["sample"], ".1f"),
         f(t_np["sample"], ".1f") + (" (stopped by budget)" if r_np.budget_hit else ""),
         x(t_np["sample"], t_tf["sample"]) + (" (unequal ESS)" if extrapolated else "")),
        ("**end to end (s)**", f"**{t_tf['total']:.1f}**", f"**{t_np['total']:.1f}**",
         x(t_np["total"], t_tf["total"]) + (" (unequal ESS)" if extrapolated else "")),
        ("end to end, CPU time of this process, all threads (s)", f(t_tf["cpu"]), f(t_np["cpu"]),
         x(t_np["cpu"], t_tf["cpu"])),
        ("of which JAX compilation (s) [build / MAP / emcee]",
         f"{compile_tf:.1f} [{tf['compile']['build']:.1f} / {tf['compile']['map']:.1f} / {tf['compile']['sample']:.1f}]",
         "0", ""),
        ("end to end, warm rerun in the same process (s)", f(warm_total), "—", ""),
        ("end to end, new process, compiled programs from the disk cache (s)",
         f(disk["second"]["total"]) if disk else "—", "—", x(np_to_target, disk["second"]["total"]) if disk else ""),
        ("emcee steps (converged?)", f"{steps_tf} ({'yes' if r_tf.converged else 'no'})",
         f"{steps_np} ({'yes' if r_np.converged else 'no'})", ""),
        ("τ_max (steps) at the last check", f(float(np.max(r_tf.tau))), f(float(np.max(r_np.tau))), ""),
        ("burn-in / thin / kept draws per walker", f"{r_tf.burn_in} / {r_tf.thin} / {r_tf.n_draws}",
         f"{r_np.burn_in} / {r_np.thin} / {r_np.chain.shape[0]}", ""),
        ("emcee time per step (ms)", f(t_tf["sample"] / steps_tf * 1e3, ".2f"),
         f(r_np.sampling_s / steps_np * 1e3, ".2f"), x(r_np.sampling_s / steps_np, t_tf["sample"] / steps_tf)),
        (f"log-density, {costs['half']} walkers (ms per call)", f(costs["tf_logp"], ".2f"),
         f(costs["np_logp"], ".2f"), x(costs["np_logp"], costs["tf_logp"])),
        (f"log-density, {costs['half']} walkers (CPU ms per call, all threads)", f(costs["tf_logp_cpu"], ".2f"),
         f(costs["np_logp_cpu"], ".2f"), x(costs["np_logp_cpu"], costs["tf_logp_cpu"])),
        ("min bulk ESS, physical parameters", f"{ess_tf:.0f} ({who_tf})", f"{ess_np:.0f} ({who_np})", ""),
        ("ESS/s, emcee time", f(ess_tf / t_tf["sample"], ".2f"), f(ess_np / r_np.sampling_s, ".2f"),
         x(ess_tf / t_tf["sample"], ess_np / r_np.sampling_s)),
        ("ESS/s, end to end", f(ess_tf / t_tf["total"], ".2f"), f(ess_np / t_np["total"], ".2f"),
         x(ess_tf / t_tf["total"], ess_np / t_np["total"])),
        (f"**end to end to ESS = {target:.0f} (s)**", f"**{t_tf['total']:.1f}**",
         f"**{np_to_target:.1f}** ({scaled})", f"**{ratio:.2f}×**"),
        (f"end to end to ESS = {target:.0f}, CPU time (s)", f(t_tf["cpu"]), f"{np_cpu_to_target:.1f} ({scaled})",
         f"{ratio_cpu:.2f}×"),
    ]
    table = ["| | torsionfit (JAX) | NumPy/SciPy | torsionfit speed-up |", "|---|---|---|---|"]
    table += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]

    goal_ratio = ratio >= GOAL_RATIO
    goal_wall = t_tf["total"] < GOAL_WALL_S
    verdict = [
        f"- **End to end at equal ESS: torsionfit is {ratio:.2f}× faster than NumPy/SciPy** "
        f"({t_tf['total']:.1f} s vs {np_to_target:.1f} s to a min bulk ESS of {target:.0f}); "
        f"goal ≥ {GOAL_RATIO:g}×: **{'met' if goal_ratio else 'not met'}**"
        + ("" if goal_ratio else f" (short by a factor {GOAL_RATIO / ratio:.1f})") + ".",
        f"- On CPU time (less sensitive to other processes' load): {ratio_cpu:.2f}×.",
        f"- Without compilation (warm rerun): {ratio_warm:.2f}×." if warm else
        "- Warm rerun skipped (--no-warm).",
        (f"- In a new process whose programs come from JAX's disk cache, filled by an earlier process of "
         f"the same shape (the command line's next campaign of this shape): {disk['second']['total']:.1f} s end to "
         f"end, of which {disk['second']['compile']:.1f} s JAX compile events (tracing, lowering and reading "
         f"the cache), {np_to_target / disk['second']['total']:.2f}× (the process that filled the cache: "
         f"{disk['first']['total']:.1f} s).") if disk else "- Disk-cache runs skipped (--no-disk-cache).",
        f"- Sampling alone (emcee time to equal ESS): {sampling_ratio:.2f}×; MAP alone: "
        f"torsionfit {t_tf['map']:.1f} s vs SciPy {t_np['map']:.1f} s.",
        f"- torsionfit wall time including compilation: {t_tf['total']:.1f} s on "
        f"{len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()} cores; goal < {GOAL_WALL_S:g} s: "
        f"**{'met' if goal_wall else 'not met'}**" + ("" if goal_wall else
                                                     f" ({t_tf['total'] / GOAL_WALL_S:.1f}× over)") + ".",
    ]
    # a bound, not a forecast: torsionfit's end to end can be no shorter than its emcee
    # log-density calls. Generous to torsionfit: the smallest of three measurements of those
    # calls' total (this VM's speed drifts between them)
    measured = {
        f"{tf['logp_chunks']} evaluations of {costs['half']} walkers × the per-call median {costs['tf_logp']:.2f} ms":
            tf["logp_chunks"] * costs["tf_logp"] / 1e3,
        "timed around emcee's calls in the cold run, less the emcee stage's compilation":
            tf["logp_s"] - tf["compile"]["sample"],
    }
    if warm:
        measured["timed around emcee's calls in the warm rerun"] = warm["logp_s"]
    how, calls_s = min(measured.items(), key=lambda kv: kv[1])
    need = np_to_target / GOAL_RATIO
    verdict.append(
        f"- Ceiling with this log-density and these moves: if compilation, building, the MAP and emcee's own work "
        f"took no time, torsionfit's end to end would be its emcee log-density calls alone ({calls_s:.1f} s: {how}; "
        f"the smallest of {len(measured)} measurements): at most {np_to_target / calls_s:.1f}× faster. For "
        f"{GOAL_RATIO:g}× with nothing else costing, one {costs['half']}-walker evaluation would have to take "
        f"{1e3 * need / tf['logp_chunks']:.2f} ms, {calls_s / need:.1f}× faster than now.")
    if extrapolated:
        verdict.append(
            f"- The NumPy/SciPy emcee run {'was stopped by the time budget' if r_np.budget_hit else 'did not converge'} "
            f"({r_np.reason}); its time to ESS {target:.0f} is {scaled} linearly from the ESS it "
            f"reached ({ess_np:.0f} in {r_np.sampling_s:.0f} s of sampling).")
    else:
        verdict.append(
            f"- Both chains converged by the same rule; the NumPy/SciPy time to ESS {target:.0f} scales "
            f"its measured emcee time by {target:.0f}/{ess_np:.0f} (its own run reached ESS {ess_np:.0f}).")

    # where the time goes
    st = tf["compile_stages"]
    stage_txt = "; ".join(
        f"{k}: " + ", ".join(f"{s} {v:.1f} s" for s, v in st[k].items()) for k in ("build", "map", "sample") if st[k])
    tf_logp_share = tf["logp_s"] / t_tf["sample"]
    np_logp_share = npy["logp_s"] / t_np["sample"]
    where = [
        "## Where the time goes",
        "",
        "**torsionfit** (cold run):",
        f"- JAX compilation {compile_tf:.1f} s of {t_tf['total']:.1f} s ({100 * compile_tf / t_tf['total']:.0f} %; "
        f"{sum(tf['compile_count'].values())} XLA compilations: build {tf['compile_count']['build']}, "
        f"MAP {tf['compile_count']['map']}, emcee {tf['compile_count']['sample']}): {stage_txt}.",
        f"- MAP: {t_tf['map']:.1f} s, of which compilation {tf['compile']['map']:.1f} s"
        + (f"; warm {warm['times']['map']:.1f} s" if warm else "") + ".",
        f"- emcee: {t_tf['sample']:.1f} s for {steps_tf} steps; the log-density calls ({tf['logp_calls']}; "
        f"{tf['logp_chunks']} evaluations of {costs['half']} walkers) take {tf['logp_s']:.1f} s ({100 * tf_logp_share:.0f} %; first calls include "
        f"compilation), emcee's own work (proposals, bookkeeping, τ estimates) the rest. One call: "
        f"{costs['tf_logp']:.2f} ms, of which the model forward {costs['tf_forward']:.2f} ms. With the Dahl "
        f"recurrence replaced by an element-wise stand-in (for timing only) the call takes "
        f"{costs['tf_logp_no_scan']:.2f} ms: the serial scan, with moving the walkers' arrays into and out of "
        f"its layout, costs {costs['tf_logp'] - costs['tf_logp_no_scan']:.2f} ms; the rest is element-wise work "
        f"over samples × walkers (exp, tanh, log, sqrt, divisions, the knot correction), which XLA already fuses.",
        "",
        "**NumPy/SciPy**:",
        f"- MAP: {t_np['map']:.1f} s ({npy['map'].n_fev} residual evaluations with the Python-float "
        f"recurrence, {npy['map'].n_jev} forward-difference Jacobians as one walker-vectorised call each).",
        f"- emcee: {t_np['sample']:.1f} s for {steps_np} steps; log-density {npy['logp_s']:.1f} s "
        f"({100 * np_logp_share:.0f} %), of which the recurrence loop {npy['loop_s']:.1f} s. One call "
        f"({costs['half']} walkers): {costs['np_logp']:.2f} ms — model forward {costs['np_forward']:.2f} ms, "
        f"of which the loop over {n_samples} samples {costs['np_loop']:.2f} ms "
        f"({1e3 * costs['np_loop'] / n_samples:.2f} µs per sample for all walkers).",
        f"- Not compared, measured beside it: the same NumPy log-density with the Dahl recurrence "
        f"replaced by its closed form per monotone run (z − s decays as exp(−Σ|Δτ|/τ_d) while "
        f"sgn Δτ = s is fixed; {costs['runs']} runs in this loop; `recurrence='runs'`): "
        f"{costs['np_logp_runs']:.2f} ms per call, {costs['np_logp_runs'] / costs['tf_logp']:.2f}× the JAX call.",
    ]

    post = ["## Posterior agreement (sanity check)", "",
            "| parameter (u) | torsionfit mean ± sd | NumPy/SciPy mean ± sd | bulk ESS tf / np |", "|---|---|---|---|"]
    for j in range(n_phys):
        a, b = r_tf.chain[:, :, j].ravel(), r_np.chain[:, :, j].ravel()
        post.append(f"| {names[j]} | {a.mean():.5g} ± {a.std(ddof=1):.3g} | {b.mean():.5g} ± {b.std(ddof=1):.3g} "
                    f"| {all_tf[names[j]]:.0f} / {all_np[names[j]]:.0f} |")

    md = [
        "# Full fit: torsionfit vs a NumPy/SciPy pipeline (MAP + emcee to convergence)",
        "",
        "Generated by `benchmarks/bench_full_fit.py`" + (" --quick" if args.quick else "")
        + "; see `benchmarks/README.md` for what the numbers mean.",
        "",
        *(f"- {k}: {v}" for k, v in info.items()),
        f"- data: SYNTHETIC, `{bench_path.relative_to(HERE.parent)}` (one five-step loop, {n_samples} samples), "
        f"seed {SEED} for both MAP starts and emcee",
        "- posterior: base model, free initial friction state, latent torque knots, errors-in-variables "
        "variance, AR(1) noise, angle offset profiled (the default `fit_campaign` configuration); the NumPy "
        "log-density equals torsionfit's (tests/test_scipy_pipeline_reference.py)",
        "- speed-up column: NumPy/SciPy time ÷ torsionfit time (or torsionfit rate ÷ NumPy/SciPy rate); "
        "below 1× torsionfit is slower",
        f"- emcee: {MOVES_DESCRIPTION}, `vectorize=True`, τ checked every 500 steps, stop when the "
        "chain is > 50 τ_max and τ_max moved < 1 % (or the chain is > 100 τ_max), at least 1000 steps; "
        "burn-in 2 τ_max, thin τ_min/2 (run_sampler's rule, both sides)",
        f"- benchmark wall time: {wall:.0f} s; 1-min load average {loads[0]:.2f} at start, {loads[1]:.2f} at end "
        "(above ~1 means other processes shared the cores: all times are then inflated, not necessarily alike)",
        "",
        *table,
        "",
        *verdict,
        "",
        *where,
        "",
        *post,
        "",
    ]
    return "\n".join(md)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smoke run on a 2 001-sample loop")
    ap.add_argument("--output", type=Path, default=None,
                    help="Markdown file to write (default: results/full_fit.md; none with --quick)")
    ap.add_argument("--numpy-budget", type=float, default=None,
                    help="wall-time budget (s) of the NumPy/SciPy emcee run; when it would be exceeded "
                         "the run stops at a τ check and its time to equal ESS is extrapolated "
                         "(default 360, 120 with --quick)")
    ap.add_argument("--no-warm", action="store_true", help="skip the warm torsionfit rerun")
    ap.add_argument("--no-disk-cache", action="store_true",
                    help="skip the two torsionfit runs in new processes with JAX's disk cache")
    ap.add_argument("--disk-cache-child", type=Path, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    bench_path = HERE / "benches" / ("full_fit_2k.toml" if args.quick else "full_fit_10k.toml")
    budget = args.numpy_budget if args.numpy_budget is not None else (120.0 if args.quick else 360.0)
    output = args.output
    if output is None and not args.quick:
        output = HERE / "results" / "full_fit.md"

    if args.disk_cache_child is not None:
        return disk_cache_child(bench_path, args.disk_cache_child)
    info = machine(scipy=scipy.__version__, emcee=emcee.__version__, arviz_stats=arviz_stats.__version__)
    for k, v in info.items():
        say(f"{k}: {v}")
    campaign = simulate(load_bench(bench_path)).campaign
    n_samples = len(campaign.runs[0])
    say(f"data: {bench_path.name}, {n_samples} samples")

    loads = [os.getloadavg()[0]]
    start = time.perf_counter()
    clock = CompileClock()
    say("torsionfit (cold: compilation included) …")
    tf = run_torsionfit(campaign, clock, "cold")
    say(f"  {tf['times']}, compile {tf['compile']}")
    say("NumPy/SciPy …")
    npy = run_numpy(campaign, budget)
    say(f"  {npy['times']}")
    warm = None
    if not args.no_warm:
        say("torsionfit (warm rerun) …")
        warm = run_torsionfit(campaign, clock, "warm")
        say(f"  {warm['times']}, compile {warm['compile']}")
    disk = None
    if not args.no_disk_cache:
        say("torsionfit in new processes with the disk cache (the first fills it, the second is timed) …")
        disk = run_with_disk_cache(args.quick)
        say(f"  {disk}")
    costs = per_call_costs(tf, npy)
    wall = time.perf_counter() - start
    loads.append(os.getloadavg()[0])

    text = build_report(args, info, bench_path, n_samples, tf, warm, npy, costs, loads, wall, disk)
    print(text)
    if output is not None:
        output.parent.mkdir(parents=True, exist_ok=True)
        output.write_text(text)
        say(f"written to {output}")


if __name__ == "__main__":
    main()
