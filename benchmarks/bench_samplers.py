#!/usr/bin/env python
"""Benchmark: time to a converged posterior with emcee, NUTS and ``--sampler auto``, side by
side on the same MAP of each case.

Converged here means the target of the samplers' comparison: R̂ ≤ 1.01 and bulk ESS ≥ 400 for
every physical parameter (``arviz_stats``, on the entries of u that are model parameters —
rank-based, so the same on their SI values), plus each sampler's own rule (emcee: chain longer
than 50 τ_max; NUTS: also tail ESS ≥ 400 for every entry of u and no divergence). Reported per
case and sampler: wall time of the sampler (the MAP is shared and timed once), converged,
R̂ max, bulk ESS min, ESS per second and per evaluation (emcee: log-density evaluations;
NUTS: log-density gradients; auto: both, as it ran them).

Cases: ``10k`` — the SYNTHETIC 10 001-sample loop of ``bench_full_fit.py``
(``benchmarks/benches/full_fit_10k.toml``, base model); ``paper-small`` — ``data/paper-small``
(SYNTHETIC, base model, as ``torsionfit fit`` reads it); ``pos1``/``pos6`` — REAL measured
loops ``examples/cycloidal-jv/baseline-pccf-initial-pos{1,6}.toml`` (data in ../shared/data,
CC BY-SA 4.0; skipped when absent), base model, as ``torsionfit fit`` reads them; ``te`` —
``benchmarks/benches/samplers_te_kinematic.toml`` (SYNTHETIC, six TE runs, kinematic error at
orders 1, 2, 39 fitted with those harmonics). Every case is fitted as ``fit_campaign`` does
(MAP, then the posterior widened for misfit), so the samplers see the density ``torsionfit fit``
samples.

Budgets (each case capped, so that a run ends): emcee ``--max-steps`` (default 20 000), NUTS
``--max-draws`` per chain (default 2000, grown by half from run_nuts's first look, 200) after the fit's warm-up; auto is
emcee under its switch rule, then NUTS with the same budget. A sampler that does not converge
within them is reported "no" with the time it took to give up.

    python benchmarks/bench_samplers.py                       # every case
    python benchmarks/bench_samplers.py --cases 10k pos6      # some cases
    python benchmarks/bench_samplers.py --output benchmarks/results/samplers.md
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import inspect  # noqa: E402

import torsionfit  # noqa: E402
from _machine import machine, write_report  # noqa: E402
from torsionfit.fit import fit_map  # noqa: E402
from torsionfit.fit._misfit import widen_for_misfit  # noqa: E402
from torsionfit.io import load_campaign  # noqa: E402
from torsionfit.report import FitOptions, prepare_fit  # noqa: E402
from torsionfit.report._pipeline import AUTO_CHECK_EVERY, sample_posterior  # noqa: E402
from torsionfit.sample import ConvergenceWarning, chain_diagnostics  # noqa: E402

CASES = ("10k", "paper-small", "pos1", "pos6", "te")
#: the draws per chain of NUTS's first convergence check (run_nuts's default, which fit uses)
FIRST_LOOK_DRAWS = inspect.signature(torsionfit.sample.run_nuts).parameters["initial_draws"].default


def _cases():
    from torsionfit.bench import load_bench, simulate

    def bench(path, label, effects=None):
        def make():
            b = load_bench(path)
            return simulate(b, seed=b.seed).campaign, FitOptions(effects=effects or {}), label
        return make

    def manifest(path, label):
        return lambda: (load_campaign(path), FitOptions(), label)

    loops = ROOT / "examples" / "cycloidal-jv"
    real = ("REAL measured loop baseline-pccf-initial-{} (CC BY-SA 4.0), base model, every sample "
            "(as `torsionfit fit` with defaults)")
    return {
        "10k": bench(HERE / "benches" / "full_fit_10k.toml", "SYNTHETIC 10 001-sample loop, base model"),
        "paper-small": manifest(ROOT / "data" / "paper-small" / "campaign.toml",
                                "SYNTHETIC data/paper-small (3 loops, 3 TE runs), base model, every sample"),
        "pos1": manifest(loops / "baseline-pccf-initial-pos1.toml", real.format("pos1")),
        "pos6": manifest(loops / "baseline-pccf-initial-pos6.toml", real.format("pos6")),
        "te": bench(HERE / "benches" / "samplers_te_kinematic.toml",
                    "SYNTHETIC TE campaign (6 runs) with kinematic error, orders 1, 2, 39 fitted",
                    {"kinematic_error": [1, 2, 39]}),
    }


def _evaluations(res) -> int:
    """Log-density evaluations (emcee) or gradients (NUTS), the emcee part of auto included."""
    if res.sampler == "nuts":
        before = res.preceded_by or {}
        return int(res.n_grad_evals + before.get("n_steps", 0) * before.get("n_walkers", 0))
    return int(res.n_steps * res.n_walkers)


def run_case(name, make, samplers, budget, seed, on_row=lambda case: None):
    try:
        campaign, options, label = make()
    except (FileNotFoundError, OSError) as err:
        print(f"{name}: skipped ({err})", file=sys.stderr)
        return None
    campaign, _, problem = prepare_fit(campaign, options)
    runs = [r.name for r in campaign.runs]
    t = time.perf_counter()
    m = fit_map(problem, runs, n_starts=options.n_starts, seed=seed)
    problem, m = widen_for_misfit(problem, m)  # as fit_campaign (FitOptions.misfit_inflation)
    t_map = time.perf_counter() - t
    n_samples = sum(len(y) for y in problem.y)
    print(f"{name}: {label}; dim {problem.dim}; {n_samples} samples; MAP {t_map:.1f} s; "
          f"misfit inflation {1 / problem.likelihood_power:.2f}", file=sys.stderr, flush=True)
    rows = []
    n_phys = problem.n_model
    case = dict(name=name, label=label, dim=problem.dim, n_phys=n_phys, samples=n_samples, t_map=t_map,
                inflation=1 / problem.likelihood_power, rows=rows)
    for sampler in samplers:
        opts = dataclasses.replace(options, sampler=sampler, progress=False, **budget)
        load0 = os.getloadavg()[0]
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            res, used, why = sample_posterior(problem, m, opts, seed)
        wall = time.perf_counter() - t
        rhat, bulk, _ = chain_diagnostics(res.chain[:, :, :n_phys])
        ok = bool(res.converged and np.nanmax(rhat) <= 1.01 and np.nanmin(bulk) >= 400)
        ess, ev = float(np.nanmin(bulk)), _evaluations(res)
        before = getattr(res, "preceded_by", None) or {}
        rows.append(dict(case=name, sampler=sampler, used=used, why=why, wall=wall, converged=ok,
                         own=bool(res.converged), rhat=float(np.nanmax(rhat)), ess=ess, evals=ev,
                         ess_s=ess / wall, ess_ev=ess / max(ev, 1), steps=res.n_steps,
                         emcee_steps=int(before.get("n_steps", res.n_steps if used == "emcee" else 0)),
                         draws=int(res.chain.shape[0]) if used == "nuts" else 0,
                         divergent=getattr(res, "n_divergent", 0), reason=res.reason,
                         load=(load0, os.getloadavg()[0])))
        r = rows[-1]
        print(f"  {sampler:5s} → {used}: {wall:7.1f} s, converged {ok}, R̂ {r['rhat']:.3f}, ESS {ess:.0f}, "
              f"{ev} evaluations; {why}; {res.reason}", file=sys.stderr, flush=True)
        on_row(case)
    return case


def table(results) -> str:
    lines = ["| case | sampler | ran | sampler wall time (s) | converged | R̂ max | bulk ESS min | "
             "emcee steps / NUTS draws per chain | divergent | evaluations | ESS/s | ESS per 1000 evaluations | load |",
             "| --- | --- | --- | ---: | :---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for res in results:
        for r in res["rows"]:
            work = " + ".join(x for x in (f"{r['emcee_steps']} steps" if r["emcee_steps"] else "",
                                          f"{r['draws']} draws" if r["draws"] else "") if x)
            lines.append(f"| {r['case']} | {r['sampler']} | {r['used']} | {r['wall']:.1f} | "
                         f"{'yes' if r['converged'] else 'no'} | {r['rhat']:.3f} | {r['ess']:.0f} | {work} | "
                         f"{r['divergent']} | {r['evals']} | {r['ess_s']:.2f} | {1000 * r['ess_ev']:.2f} | "
                         f"{r['load'][0]:.1f}–{r['load'][1]:.1f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=CASES)
    ap.add_argument("--samplers", nargs="+", default=["emcee", "nuts", "auto"], choices=("emcee", "nuts", "auto"))
    ap.add_argument("--max-steps", type=int, default=20_000, help="emcee's budget (default 20 000, as fit)")
    ap.add_argument("--max-draws", type=int, default=2000, help="NUTS's budget of draws per chain (default 2000)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path, default=None)
    args = ap.parse_args(argv)
    from torsionfit._threads import single_blas_thread

    cases = _cases()
    budget = {"max_steps": args.max_steps, "max_draws": args.max_draws}
    command = (f"python benchmarks/bench_samplers.py --cases {' '.join(args.cases)} --samplers {' '.join(args.samplers)} "
               f"--max-steps {args.max_steps} --max-draws {args.max_draws} --seed {args.seed}"
               + (f" --output {args.output}" if args.output else ""))
    results = []
    with single_blas_thread(), torsionfit.float64():
        for i, name in enumerate(args.cases):
            def written(case, i=i):  # after every sampler: a long run that is stopped keeps what it measured
                if args.output:
                    done = [r for r in results if r is not case] + [case]
                    write_report(args.output, report(done, args, command, args.cases[i + 1:]))

            out = run_case(name, cases[name], args.samplers, budget, args.seed, written)
            if out is not None:
                results.append(out)
    if not args.output:
        print("\n".join(report(results, args, command, [])))


def report(results, args, command, pending) -> list[str]:
    doc = ["# Samplers: time to a converged posterior", "",
           f"Generated by `{command}`; every number below was measured by it on this run.", "",
           *[f"- {key}: {value}" for key, value in machine().items()],
           f"- budgets: emcee ≤ {args.max_steps} steps; NUTS 4 chains × ({FitOptions().n_warmup} warm-up steps + "
           f"≤ {args.max_draws} draws, grown by half from {FIRST_LOOK_DRAWS}); auto: emcee under its switch rule (checks every "
           f"{AUTO_CHECK_EVERY} steps), then NUTS with the same budget", ""]
    if pending:
        doc += [f"(Partial: cases {', '.join(pending)} had not run yet when this file was written.)", ""]
    doc += ["Converged: R̂ ≤ 1.01 and bulk ESS ≥ 400 for every physical parameter, and the sampler's own rule "
            "(emcee: chain ≥ 50 τ_max; NUTS: also tail ESS ≥ 400 for every entry of u and no divergence). "
            "Wall time of the sampler only (the MAP is shared). Evaluations: log-density calls (emcee) and "
            "log-density gradients (NUTS, warm-up included), both for auto. Load: the 1-minute load average at "
            "the start and the end of that sampler's run (2 cores: above 2, other processes shared them).", ""]
    for res in results:
        doc.append(f"- **{res['name']}**: {res['label']}; {res['samples']} samples; dim {res['dim']} "
                   f"({res['n_phys']} physical); MAP {res['t_map']:.1f} s; misfit inflation {res['inflation']:.2f}")
    doc += ["", table(results), "", "Choices and reasons:", ""]
    for res in results:
        for r in res["rows"]:
            doc.append(f"- {r['case']} / {r['sampler']}: {r['why']}" + (f" — {r['reason']}" if r["reason"] else ""))
    return doc

if __name__ == "__main__":
    main()
