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
(SYNTHETIC, base model, decimated 2); ``pos1``/``pos6`` — REAL measured loops
``examples/cycloidal-jv/baseline-pccf-initial-pos{1,6}.toml`` (data in ../shared/data, CC BY-SA
4.0; skipped when absent), ``--decimate 16`` and the real-loop physics (load-dependent and
distributed friction, power-law stiffness, asymmetry).

    python benchmarks/bench_samplers.py                       # every case (long: emcee runs to its cap)
    python benchmarks/bench_samplers.py --cases 10k pos6      # some cases
    python benchmarks/bench_samplers.py --output benchmarks/results/samplers.md
"""

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from _machine import machine  # noqa: E402
from torsionfit.fit import fit_map  # noqa: E402
from torsionfit.io import load_campaign  # noqa: E402
from torsionfit.report import FitOptions, prepare_fit  # noqa: E402
from torsionfit.report._pipeline import sample_posterior  # noqa: E402
from torsionfit.sample import ConvergenceWarning, chain_diagnostics  # noqa: E402

REAL_EFFECTS = {"load_dependent_friction": True, "distributed_friction": True,
                "stiffness_nonlinearity": "power_law", "asymmetry": True}


def _cases():
    from torsionfit.bench import load_bench, simulate

    def tenk():
        bench = load_bench(HERE / "benches" / "full_fit_10k.toml")
        return simulate(bench, seed=bench.seed).campaign, FitOptions(), "SYNTHETIC 10 001-sample loop, base model"

    def paper_small():
        return (load_campaign(ROOT / "data" / "paper-small" / "campaign.toml"), FitOptions(decimate=2),
                "SYNTHETIC data/paper-small, base model, decimate 2")

    def measured(pos):
        def make():
            path = ROOT / "examples" / "cycloidal-jv" / f"baseline-pccf-initial-{pos}.toml"
            return (load_campaign(path), FitOptions(effects=REAL_EFFECTS, decimate=16),
                    f"REAL measured loop baseline-pccf-initial-{pos} (CC BY-SA 4.0), decimate 16, real-loop physics")
        return make

    return {"10k": tenk, "paper-small": paper_small, "pos1": measured("pos1"), "pos6": measured("pos6")}


def _evaluations(res) -> int:
    """Log-density evaluations (emcee) or gradients (NUTS), the emcee part of auto included."""
    if res.sampler == "nuts":
        before = res.preceded_by or {}
        return int(res.n_grad_evals + before.get("n_steps", 0) * before.get("n_walkers", 0))
    return int(res.n_steps * res.n_walkers)


def run_case(name, make, samplers, max_steps, seed):
    try:
        campaign, options, label = make()
    except (FileNotFoundError, OSError) as err:
        print(f"{name}: skipped ({err})", file=sys.stderr)
        return None
    campaign, _, problem = prepare_fit(campaign, options)
    runs = [r.name for r in campaign.runs]
    t = time.perf_counter()
    m = fit_map(problem, runs, n_starts=options.n_starts, seed=seed)
    t_map = time.perf_counter() - t
    print(f"{name}: {label}; dim {problem.dim}; MAP {t_map:.1f} s", file=sys.stderr, flush=True)
    rows = []
    n_phys = problem.n_model
    for sampler in samplers:
        opts = replace(options, sampler=sampler, max_steps=max_steps, progress=False)
        t = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            res, used, why = sample_posterior(problem, m, opts, seed)
        wall = time.perf_counter() - t
        rhat, bulk, _ = chain_diagnostics(res.chain[:, :, :n_phys])
        ok = bool(res.converged and np.nanmax(rhat) <= 1.01 and np.nanmin(bulk) >= 400)
        ess, ev = float(np.nanmin(bulk)), _evaluations(res)
        rows.append(dict(case=name, sampler=sampler, used=used, why=why, wall=wall, converged=ok,
                         own=bool(res.converged), rhat=float(np.nanmax(rhat)), ess=ess, evals=ev,
                         ess_s=ess / wall, ess_ev=ess / max(ev, 1), steps=res.n_steps,
                         divergent=getattr(res, "n_divergent", 0), reason=res.reason))
        r = rows[-1]
        print(f"  {sampler:5s} → {used}: {wall:7.1f} s, converged {ok}, R̂ {r['rhat']:.3f}, ESS {ess:.0f}, "
              f"{ev} evaluations; {why}; {res.reason}", file=sys.stderr, flush=True)
    return dict(name=name, label=label, dim=problem.dim, t_map=t_map, rows=rows)


def table(results) -> str:
    lines = ["| case | sampler | ran | sampler wall time (s) | converged | R̂ max | bulk ESS min | "
             "evaluations | ESS/s | ESS per 1000 evaluations |",
             "| --- | --- | --- | ---: | :---: | ---: | ---: | ---: | ---: | ---: |"]
    for res in results:
        for r in res["rows"]:
            lines.append(f"| {r['case']} | {r['sampler']} | {r['used']} | {r['wall']:.1f} | "
                         f"{'yes' if r['converged'] else 'no'} | {r['rhat']:.3f} | {r['ess']:.0f} | {r['evals']} | "
                         f"{r['ess_s']:.1f} | {1000 * r['ess_ev']:.2f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["10k", "paper-small", "pos1", "pos6"])
    ap.add_argument("--samplers", nargs="+", default=["emcee", "nuts", "auto"])
    ap.add_argument("--max-steps", type=int, default=20_000, help="emcee's budget (default 20 000, as fit)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--output", type=Path, default=None)
    args = ap.parse_args(argv)
    from torsionfit._threads import single_blas_thread

    cases = _cases()
    results = []
    with single_blas_thread():
        for name in args.cases:
            out = run_case(name, cases[name], args.samplers, args.max_steps, args.seed)
            if out is not None:
                results.append(out)
    doc = ["# Samplers: time to a converged posterior", "",
           f"`python benchmarks/bench_samplers.py --cases {' '.join(args.cases)} --samplers {' '.join(args.samplers)}` "
           f"(emcee budget {args.max_steps} steps, seed {args.seed}). {machine()}", "",
           "Converged: R̂ ≤ 1.01 and bulk ESS ≥ 400 for every physical parameter, and the sampler's own rule. "
           "Wall time of the sampler only (the MAP is shared). Evaluations: log-density calls (emcee) and "
           "log-density gradients (NUTS), both for auto.", ""]
    for res in results:
        doc.append(f"- **{res['name']}**: {res['label']}; dim {res['dim']}; MAP {res['t_map']:.1f} s")
    doc += ["", table(results), "", "Choices and reasons:", ""]
    for res in results:
        for r in res["rows"]:
            doc.append(f"- {r['case']} / {r['sampler']}: {r['why']}" + (f" — {r['reason']}" if r["reason"] else ""))
    text = "\n".join(doc) + "\n"
    print(text)
    if args.output:
        args.output.write_text(text)


if __name__ == "__main__":
    main()
