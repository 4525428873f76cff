"""How long `diagnose` takes on a three-run campaign (goal: under 2 minutes on 2 cores).

Two SYNTHETIC campaigns, each with an effect switched on in the bench and absent from the
manifest: ``benches/diagnose_three_runs.toml`` — two hysteresis loops at 2 and 10 N·m/s and one
transmission-error run, a creep element — and ``benches/diagnose_te_kinematic.toml`` — three TE
runs at 3600 samples per revolution, 0.4″ noise on a 1″ encoder, a kinematic error at orders 1,
2 and 39. For each campaign, each repeat runs in a fresh Python process with an empty persistent compilation cache (cold:
imports, simulation and every JAX compilation included), simulates the campaign with its own
noise seed and diagnoses it, then diagnoses a second campaign of the same shape in the same
process (warm: the shapes are compiled). A second fresh process then diagnoses a third campaign
with the cache the first one left on disk — what `torsionfit diagnose` costs for the next
campaign of a shape on the same machine (the CLI keeps that cache, torsionfit/_cache.py).
Reported: wall times, the share spent compiling (``jax.monitoring``), and what was found.

    .venv/bin/python benchmarks/bench_diagnose.py               # 3 repeats, writes results/diagnose.md
    .venv/bin/python benchmarks/bench_diagnose.py --repeats 1 --output /tmp/d.md --campaigns te_kinematic
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: name → (bench file, what is in it)
CAMPAIGNS = {
    "three_runs": (HERE / "benches" / "diagnose_three_runs.toml", "two loops, one TE run; creep switched on, not declared"),
    "te_kinematic": (HERE / "benches" / "diagnose_te_kinematic.toml",
                     "three TE runs, 3600 samples/rev, 0.4″ noise on a 1″ encoder; kinematic error at orders 1, 2, 39 "
                     "switched on, not declared"),
}
GOAL_S = 120.0
COMPILE_EVENT = "/jax/core/compile/backend_compile_duration"
TRACE_EVENTS = ("/jax/core/compile/jaxpr_trace_duration", "/jax/core/compile/jaxpr_to_mlir_module_duration")


def one(bench_file: Path, seed: int, cache: str) -> dict:
    """Runs in the child process: a diagnosis (cache folder ``cache``), then a warm one in the
    same process; returns the timings."""
    t_start = time.perf_counter()
    import jax.monitoring

    from torsionfit._cache import enable_compilation_cache

    enable_compilation_cache(cache)

    compile_s = {"xla": 0.0, "trace": 0.0}

    def listen(event, duration, **kwargs):
        if event == COMPILE_EVENT:
            compile_s["xla"] += duration
        elif event in TRACE_EVENTS:
            compile_s["trace"] += duration

    jax.monitoring.register_event_duration_secs_listener(listen)
    from torsionfit.bench import load_bench, simulate
    from torsionfit.diagnose import DiagnoseOptions, diagnose

    t_import = time.perf_counter()
    bench = load_bench(bench_file)
    campaign = simulate(bench, seed=seed).campaign
    t_sim = time.perf_counter()
    starts = []  # (time, what diagnose says it starts)

    d = diagnose(campaign, DiagnoseOptions(), seed=seed, progress=lambda text: starts.append((time.perf_counter(), text)))
    t_cold = time.perf_counter()
    ends = [t for t, _ in starts[1:]] + [t_cold]
    stages = [(round(end - t, 1), text) for (t, text), end in zip(starts, ends)]
    cold_compile = dict(compile_s)
    d2 = diagnose(simulate(bench, seed=seed + 1000).campaign, DiagnoseOptions(), seed=seed)
    t_warm = time.perf_counter()
    return {
        "seed": seed, "samples": [len(r) for r in campaign.runs],
        "import_s": t_import - t_start, "simulate_s": t_sim - t_import,
        "cold_diagnose_s": t_cold - t_sim, "cold_total_s": t_cold - t_start,
        "compile_xla_s": cold_compile["xla"], "compile_trace_lower_s": cold_compile["trace"],
        "warm_diagnose_s": t_warm - t_cold,
        "added": [s.effect for s in d.steps], "added_warm": [s.effect for s in d2.steps],
        "rejected": [s.effect for s in d.rejected],
        "rmse_base_arcsec": d.base.rmse_arcsec, "rmse_final_arcsec": d.final.rmse_arcsec,
        "unexplained": d.unexplained, "stages": stages, "load_1min": os.getloadavg()[0],
    }


def run_repeat(child, name: str, i: int) -> dict:
    """Repeat ``i`` of campaign ``name``: a cold process, then a new one with the cache it left."""
    bench_file = CAMPAIGNS[name][0]
    with tempfile.TemporaryDirectory() as cache:
        row = child(bench_file, i + 1, cache)
        row["disk"] = child(bench_file, i + 101, cache)
    print(f"{name} repeat {i + 1}: cold {row['cold_total_s']:.1f} s (diagnose {row['cold_diagnose_s']:.1f} s, XLA compile "
          f"{row['compile_xla_s']:.1f} s), warm {row['warm_diagnose_s']:.1f} s, new process with the disk cache "
          f"{row['disk']['cold_total_s']:.1f} s; added {row['added']}, {row['disk']['added']}; "
          f"RMSE {row['rmse_base_arcsec']:.2f}″ → {row['rmse_final_arcsec']:.2f}″, load {row['load_before']:.1f}", flush=True)
    return row


def campaign_section(name: str, rows: list) -> list[str]:
    """The markdown section of one campaign: verdicts, one row per repeat, the first repeat's stages."""
    bench_file, what = CAMPAIGNS[name]
    cold = [r["cold_total_s"] for r in rows]
    warm = [r["warm_diagnose_s"] for r in rows]
    disk = [r["disk"]["cold_total_s"] for r in rows]
    median_cold, median_disk = statistics.median(cold), statistics.median(disk)
    verdict = "met" if median_cold < GOAL_S else "NOT met"
    verdict_disk = "met" if median_disk < GOAL_S else "NOT met"
    loads = [r["load_before"] for r in rows] + [r["disk"]["load_before"] for r in rows]
    lines = [
        f"## `{name}`: `{bench_file.relative_to(HERE.parent)}`",
        "",
        f"SYNTHETIC: {what}; {rows[0]['samples']} samples.",
        "",
        f"**Cold (fresh process, empty compilation cache): median {median_cold:.1f} s — goal < {GOAL_S:.0f} s {verdict}.** "
        f"**Next campaign of the shape in a new process, with the disk cache the CLI keeps: median {median_disk:.1f} s — "
        f"goal {verdict_disk}.** Warm in the same process: median {statistics.median(warm):.1f} s. The 1-min load average "
        f"before each process is in the table ({min(loads):.1f}–{max(loads):.1f} on {os.cpu_count()} logical CPUs): other "
        "work on the machine slows every number.",
        "",
        "| repeat | load before | cold total (s) | of which import + simulate (s) | XLA compile (s) | trace + lower (s) | warm, same process (s) | new process, disk cache: load, total (s), XLA compile (s) | added | RMSE base → final (″) |",
        "| ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | --- |",
    ]
    for i, r in enumerate(rows, 1):
        d = r["disk"]
        lines.append(f"| {i} | {r['load_before']:.1f} | {r['cold_total_s']:.1f} | {r['import_s'] + r['simulate_s']:.1f} | "
                     f"{r['compile_xla_s']:.1f} | {r['compile_trace_lower_s']:.1f} | {r['warm_diagnose_s']:.1f} | "
                     f"{d['load_before']:.1f}, {d['cold_total_s']:.1f}, {d['compile_xla_s']:.1f} | "
                     f"{', '.join(dict.fromkeys(r['added'])) or 'none'} | {r['rmse_base_arcsec']:.2f} → {r['rmse_final_arcsec']:.2f} |")
    lines += ["", "Stages of the first repeat (as `diagnose` reports them; each until the next one starts, the last until "
              "the end, leftovers search included):", ""]
    lines += [f"- {s:.1f} s — {text}" for s, text in rows[0]["stages"]]
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--output", type=Path, default=HERE / "results" / "diagnose.md")
    ap.add_argument("--campaigns", nargs="+", choices=list(CAMPAIGNS), default=list(CAMPAIGNS))
    ap.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--bench", type=Path, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--cache", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child is not None:
        print(json.dumps(one(args.bench, args.child, args.cache)))
        return 0

    sys.path.insert(0, str(HERE))
    from _machine import machine

    import arviz_stats

    info = machine(arviz_stats=arviz_stats.__version__)
    # this process only starts the others; diagnose runs in them under float64 (its entry point switches it on)
    info["backend"] = info["backend"].split(", float64")[0] + ", float64 inside diagnose"
    info["threads"] = info["threads"].split(", persistent")[0] + (
        ", persistent JAX compilation cache: each repeat's two processes share a fresh temporary folder")
    for k, v in info.items():
        print(f"{k}: {v}", flush=True)

    def child(bench_file, seed, cache):
        load = os.getloadavg()[0]
        out = subprocess.run([sys.executable, __file__, "--child", str(seed), "--cache", cache, "--bench", str(bench_file)],
                             capture_output=True, text=True, check=True)
        row = json.loads(out.stdout.strip().splitlines()[-1])
        row["load_before"] = load
        return row

    lines = [
        "# `diagnose` on three-run campaigns",
        "",
        f"Produced by `benchmarks/bench_diagnose.py` ({args.repeats} repeat{'s' if args.repeats != 1 else ''} per campaign; "
        "all campaigns SYNTHETIC).",
        "",
        *[f"- {k}: {v}" for k, v in info.items()],
    ]
    for name in args.campaigns:
        lines += ["", *campaign_section(name, [run_repeat(child, name, i) for i in range(args.repeats)])]
    text = "\n".join(lines) + "\n"
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
