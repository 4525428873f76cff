"""Tempered SMC against the split normal on measured loops — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read where it lies, never copied.

Each loop is fitted as the measured validation fits it (scripts/measured_validation.py: the
file without its last large ramp, its design's model, iid noise with a level per cycle class,
the posterior widened for misfit) twice: with the split normal's draws (the validation's
sampler) and with tempered SMC from that split normal (``--sampler smc``). The page gives, per
loop, the split normal's Pareto k, the SMC run's schedule and whether its moves decorrelated the
particles at every stage, and the class metrics (model mean and 95 % HDI against the data's
reading of the same record) of both.

    .venv/bin/python scripts/measured_smc.py --units split-pccf-preload2-pos5 -o docs/measured/smc

The page is the output folder's: every loop's row saved there (``units/``), whichever run made it;
``--render`` writes it again from them without fitting. An SMC run keeps its state after every
stage in ``checkpoints/``: the same command after a stop goes on from there (``--force``: afresh).
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import measured_validation as mv  # noqa: E402

import torsionfit  # noqa: E402
from torsionfit._provenance import environment  # noqa: E402
from torsionfit.batch import executor  # noqa: E402
from torsionfit.io import load_campaign  # noqa: E402
from torsionfit.report import fit_campaign, metrics_against_data, smc_checkpoint_path  # noqa: E402
from torsionfit.sample import _smc as smc  # noqa: E402

METRICS = ("play", "stiffness_loading")

#: SMC's moves allowed per stage, the last (β = 1) too unless ``--final-moves`` says otherwise
DEFAULT_MAX_MOVES = 100


def _row_path(output: Path, unit: str) -> Path:
    return output / "units" / f"{unit}.json"


def _progress_lines(unit: str) -> None:
    """torsionfit's progress lines (the SMC stages) on stderr, named by this loop. Its own logger
    alone, as the CLI does: the root logger at INFO also prints other libraries' INFO lines (an
    array-shape note of arviz's per metric, jax's backend search)."""
    logger = logging.getLogger("torsionfit")
    for handler in list(logger.handlers):
        logger.removeHandler(handler)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"{unit}: %(message)s"))
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)


def _chain_path(output: Path, unit: str, particles: int, seed: int, optima_mixture: bool,
                gap_prior_from_crossings: bool, final_max_moves: int, max_moves: int = DEFAULT_MAX_MOVES) -> Path:
    """The fit's ``backend_path`` for SMC: its checkpoint is ``<this stem>-smc.npz``, one per loop
    and settings (a run of other settings neither reads nor overwrites it)."""
    tags = [f"p{particles}", f"s{seed}", f"m{final_max_moves}"] + (
        [f"a{max_moves}"] if max_moves != DEFAULT_MAX_MOVES else []) + (["mixture"] if optima_mixture else []) + (
        ["gap-prior"] if gap_prior_from_crossings else [])
    return output / "checkpoints" / f"{unit}-{'-'.join(tags)}.h5"


def _fit_both(unit: str, particles: int, seed: int, output: Path, draws: Path | None = None,
              optima_mixture: bool = False, progress: bool = False, gap_prior_from_crossings: bool = False,
              final_max_moves: int = DEFAULT_MAX_MOVES, resume: bool = True,
              max_moves: int = DEFAULT_MAX_MOVES) -> dict:
    """Fit one loop both ways and write its row at once (a run stopped part-way keeps its done loops).
    ``final_max_moves``: SMC's moves allowed at its last stage (β = 1), ``max_moves`` at every
    stage (the last gets the larger of the two). The SMC run keeps its state
    after every stage in ``output/checkpoints/`` (removed once the row is written); ``resume``: a
    run stopped part-way goes on from there (False: starts afresh).
    ``optima_mixture``: both start from the mixture over the optima (FitOptions.optima_mixture);
    ``gap_prior_from_crossings``: both with the gap's prior read off the data's gap crossings
    (FitOptions.gap_prior_from_crossings)."""
    args = mv.parse_args(["--units", unit, "-o", "unused", *(["--optima-mixture"] if optima_mixture else []),
                          *(["--gap-prior-from-crossings"] if gap_prior_from_crossings else [])])
    path = mv._data_path(unit)
    ramps = mv.test_numbers(path)
    last = mv.held_ramp(ramps, 1)
    out = {"unit": unit, "environment": environment()}
    draws_of, names = {}, []
    if progress:
        _progress_lines(unit)
    chain = _chain_path(output, unit, particles, seed, optima_mixture, gap_prior_from_crossings, final_max_moves,
                        max_moves)
    chain.parent.mkdir(parents=True, exist_ok=True)
    with torsionfit.float64(), tempfile.TemporaryDirectory() as folder:
        train = load_campaign(mv.manifest(unit, [r for r in ramps if r < last], Path(folder), None))
        for sampler in ("laplace", "smc"):
            options = dataclasses.replace(mv.fit_options(args, unit), sampler=sampler, smc_particles=particles,
                                          smc_max_moves=max_moves, smc_final_max_moves=final_max_moves,
                                          progress=progress,
                                          **({"backend_path": str(chain), "resume": resume} if sampler == "smc" else {}))
            t0 = time.perf_counter()
            fit = fit_campaign(train, options, seed=seed)
            seconds = time.perf_counter() - t0
            metrics, off = metrics_against_data(fit)
            d = fit.diagnostics
            draws_of[sampler], names = np.asarray(fit.draws_u), list(fit.map_result.names)
            if sampler == "laplace" and optima_mixture:
                out["laplace_optima"] = d.get("laplace_optima")
            if draws is not None:  # the particles / draws (unconstrained), to read other metrics off later
                draws.mkdir(parents=True, exist_ok=True)
                np.save(draws / f"{unit}-{sampler}.npy", draws_of[sampler].astype(np.float32))
            out[sampler] = {
                "seconds": seconds, "converged": bool(d["converged"]), "reason": d.get("reason", ""),
                "off_data": off,
                "metrics": {k: {"mean": metrics[k]["mean"], "hdi95": metrics[k]["hdi95"], "unit": metrics[k]["unit"],
                                "data": (metrics[k].get("data") or {}).get("value")} for k in METRICS if k in metrics},
                **({"pareto_k": d.get("laplace_pareto_k")} if sampler == "laplace" else
                   {k: d.get(k) for k in ("smc_betas", "smc_moves", "smc_acceptance", "smc_correlation_max",
                                          "approximation_pareto_k", "smc_moves_kind", "smc_modes", "smc_mode_shares",
                                          "smc_step_size", "smc_leapfrog_steps")}),
            }
    out["departure"] = departure(draws_of["laplace"], draws_of["smc"], names)
    out["particles"], out["seed"] = particles, seed
    out["kernel"] = kernel_settings()
    if optima_mixture:
        out["optima_mixture"] = True
    if gap_prior_from_crossings:
        out["gap_prior_from_crossings"] = True
    if final_max_moves != DEFAULT_MAX_MOVES:
        out["final_max_moves"] = final_max_moves
    if max_moves != DEFAULT_MAX_MOVES:
        out["max_moves"] = max_moves
    path = _row_path(output, unit)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, default=float))
    Path(smc_checkpoint_path(options)).unlink(missing_ok=True)  # the row holds the run now
    return out


#: coordinates listed per loop where the SMC particles depart most from the split normal's draws
DEPARTURE_SHOWN = 5


def kernel_settings() -> dict:
    """The HMC kernel's settings a row is made with (rows without: 8 leapfrog steps of the tuned
    step, jittered ±20 %)."""
    return {"step_spread": smc.HMC_STEP_SPREAD, "trajectory_length": smc.HMC_TRAJECTORY_LENGTH,
            "max_leapfrog_steps": smc.HMC_MAX_LEAPFROG_STEPS}


def kernel_text(row: dict) -> str:
    """The row's HMC moves in a few words: mean leapfrog steps per move over its stages."""
    steps = row["smc"].get("smc_leapfrog_steps")
    every = row.get("max_moves", DEFAULT_MAX_MOVES)
    last = max(row.get("final_max_moves", DEFAULT_MAX_MOVES), every)
    final = (f", {every} moves allowed at every stage" if every != DEFAULT_MAX_MOVES else "") + (
        f", {last} moves allowed at β = 1" if last != every else "")
    if row.get("kernel") is None or not steps:
        return "8, one step" + final
    return f"{np.mean(steps):.0f}, drawn steps" + final


def departure(split_normal: np.ndarray, particles: np.ndarray, names: list[str]) -> list[dict]:
    """The coordinates (unconstrained) whose SMC marginal departs most from the split normal's:
    the shift of the mean in the split normal's sd and the ratio of the sds, largest shift first."""
    sd = split_normal.std(axis=0)
    shift = (particles.mean(axis=0) - split_normal.mean(axis=0)) / np.where(sd > 0, sd, np.inf)
    width = particles.std(axis=0) / np.where(sd > 0, sd, np.inf)
    order = np.argsort(-np.abs(shift))[:DEPARTURE_SHOWN]
    return [{"name": names[i] if i < len(names) else f"u[{i}]", "shift_sd": float(shift[i]), "width_ratio": float(width[i])}
            for i in order]


def _done_row(output: Path, unit: str, particles: int, seed: int, optima_mixture: bool = False,
              gap_prior_from_crossings: bool = False, final_max_moves: int = DEFAULT_MAX_MOVES,
              max_moves: int = DEFAULT_MAX_MOVES) -> dict | None:
    """The row a previous run wrote for this unit with the same settings, else None."""
    path = _row_path(output, unit)
    if not path.is_file():
        return None
    row = json.loads(path.read_text())
    same = ((row.get("particles"), row.get("seed"), row.get("optima_mixture", False),
             row.get("gap_prior_from_crossings", False), row.get("final_max_moves", DEFAULT_MAX_MOVES),
             row.get("max_moves", DEFAULT_MAX_MOVES))
            == (particles, seed, optima_mixture, gap_prior_from_crossings, final_max_moves, max_moves))
    return row if same else None


def saved_rows(output: Path) -> list[dict]:
    """Every loop's row saved in ``output`` (its ``units/`` folder), by loop name: the page is the
    folder's, so a run of one loop adds its row to the others' instead of replacing them."""
    return [json.loads(p.read_text()) for p in sorted((output / "units").glob("*.json"))]


def page_particles(rows: list[dict], default: int) -> int | str:
    """The particles the page's header names: the rows' one count, else the range they span."""
    counts = sorted({r.get("particles", default) for r in rows}) or [default]
    return counts[0] if len(counts) == 1 else f"{counts[0]}–{counts[-1]} (each row its own)"


def _metric(entry: dict, name: str) -> str:
    m = entry["metrics"].get(name)
    if m is None:
        return "n/a"
    return f"{m['mean']:.4g} ({m['hdi95'][0]:.4g}–{m['hdi95'][1]:.4g})"


def markdown(rows: list[dict], particles: int | str, optima_mixture: bool = False, gap_prior_from_crossings: bool = False) -> str:
    start = (", both from the mixture of split normals over the optima the MAP starts reached, weighted by their Laplace "
             "evidence (--optima-mixture; the 'split normal' columns are that mixture's draws)" if optima_mixture else "")
    if gap_prior_from_crossings:
        start += (", both with the held gap's hold torque and the gap's crossing width centred on the data's gap "
                  "crossings (--gap-prior-from-crossings)")
    lines = [
        f"Tempered SMC against the split normal on measured loops ({mv.SOURCE}), each fitted as the validation fits it{start} "
        f"(`scripts/measured_smc.py`; SMC: {particles} particles, HMC moves with the particles' covariance as inverse "
        "mass matrix, at most 100 moves per stage (more at the last, β = 1, where the kernel column says so: there "
        "the moves sample the posterior itself); leapfrog steps: the mean per move, and the kernel — 'drawn steps': "
        "each move's step the tuned one over a log-uniform factor up to 30, the trajectory π/2 of the particles' spread "
        "long; 'one step': eight steps of the tuned one, as rows made before the drawn steps). k: the Pareto k of "
        "posterior/split normal at the split normal's draws (≤ 0.7: they stand for the posterior); stages: tempering "
        "steps from the split normal to the posterior; correlation: the largest correlation of a coordinate with its "
        "value at the start of its stage after the moves (converged only when at most 0.1 at every stage), read within "
        "separated modes where the particles sit in such (rows made before the rule say nothing of modes); metrics: "
        "model mean (95 % HDI) / the data's reading of the same record; off: the class metrics whose HDI misses "
        "the data's reading by more than two of its standard errors.",
        "",
        "| unit | k | split normal: play (arcmin) | SMC: play | split normal: stiffness_loading (N·m/arcmin) | "
        "SMC: stiffness_loading | data: play / stiffness_loading | off (split normal / SMC) | SMC stages | "
        "SMC moves per stage | leapfrog steps | SMC correlation | SMC converged | seconds (split normal / SMC) |",
        "| --- | ---: | --- | --- | --- | --- | --- | --- | ---: | --- | --- | ---: | --- | --- |",
    ]
    for r in sorted(rows, key=lambda r: r["unit"]):
        a, b = r["laplace"], r["smc"]
        data = " / ".join(f"{a['metrics'][k]['data']:.4g}" if a["metrics"].get(k, {}).get("data") is not None else "n/a"
                          for k in METRICS)
        off = f"{', '.join(a['off_data']) or 'none'} / {', '.join(b['off_data']) or 'none'}"
        lines.append(
            f"| {r['unit']} | {b['approximation_pareto_k']:.2f} | {_metric(a, 'play')} | {_metric(b, 'play')} | "
            f"{_metric(a, 'stiffness_loading')} | {_metric(b, 'stiffness_loading')} | {data} | {off} | "
            f"{len(b['smc_betas'])} | {', '.join(map(str, b['smc_moves']))} | {kernel_text(r)} | {b['smc_correlation_max']:.2f} | "
            f"{b['converged']} | "
            f"{a['seconds']:.0f} / {b['seconds']:.0f} |")
    lines += ["", mv.environment_text(rows, "smc.json")]
    for r in rows:  # per loop: the mixture's weights, the modes, the departure
        if r.get("laplace_optima"):
            lines += ["", f"{r['unit']}: the mixture's weights " + ", ".join(f"{c['weight']:.2f}" for c in r["laplace_optima"])
                      + " (the MAP's component first)."]
        modes = r["smc"].get("smc_modes") or []
        if max(modes, default=1) > 1:
            stages = ", ".join(str(i + 1) for i, k in enumerate(modes) if k > 1)
            shares = ", ".join(f"{s:.2f}" for s in r["smc"].get("smc_mode_shares") or [])
            lines += ["", f"{r['unit']}: the particles sat in separated modes the moves do not cross at stage(s) {stages} "
                          f"(the correlation read within them; at the last stage {len(r['smc']['smc_mode_shares'])} "
                          f"modes, shares {shares}, set by the tempering's weights)."]
        if r.get("departure"):
            lines += ["", f"{r['unit']}: where the particles depart most from the split normal (unconstrained "
                          "coordinates; mean shift in the split normal's sd, sd ratio): " + "; ".join(
                              f"{d['name']} {d['shift_sd']:+.1f} sd, ×{d['width_ratio']:.1f}" for d in r["departure"]) + "."]
    not_conv = [r for r in rows if not r["smc"]["converged"]]
    for r in not_conv:
        # a parameter's index (torque_line[initial-pos6][5].level) would read as a Markdown link
        reason = r["smc"]["reason"].replace("[", "\\[")
        lines += ["", f"{r['unit']}: {reason}."]
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--units", nargs="+", default=[])
    p.add_argument("-o", "--output", type=Path, required=True)
    p.add_argument("--particles", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=1)
    p.add_argument("--save-draws", type=Path, default=None, metavar="FOLDER",
                   help="also save each fit's draws (unconstrained parameters, .npy) in FOLDER")
    p.add_argument("--optima-mixture", action="store_true",
                   help="start both from the mixture of split normals over the optima the MAP starts reached "
                        "(FitOptions.optima_mixture)")
    p.add_argument("--gap-prior-from-crossings", action="store_true",
                   help="fit both with the gap's prior read off the data's gap crossings "
                        "(FitOptions.gap_prior_from_crossings)")
    p.add_argument("--final-moves", type=int, default=DEFAULT_MAX_MOVES,
                   help=f"SMC's moves allowed at its last stage, β = 1 (default {DEFAULT_MAX_MOVES}, as at the stages "
                        "before it; such rows are their own)")
    p.add_argument("--max-moves", type=int, default=DEFAULT_MAX_MOVES,
                   help=f"SMC's moves allowed at every stage (default {DEFAULT_MAX_MOVES}; the last gets the larger of "
                        "this and --final-moves; such rows are their own)")
    p.add_argument("--progress", action="store_true", help="print the fits' progress (the SMC stages) on stderr")
    p.add_argument("--force", action="store_true",
                   help="refit loops whose row a previous run with the same settings wrote (default: reuse it), "
                        "and start SMC runs afresh (default: a run stopped part-way goes on from its checkpoint)")
    p.add_argument("--render", action="store_true",
                   help="fit nothing: write the page from the rows saved in the output folder")
    args = p.parse_args(argv)
    if not args.units and not args.render:
        p.error("--units: name the loops to fit (or --render to write the page from the saved rows)")
    if args.render:
        return write_page(args.output, args.particles, args.optima_mixture, args.gap_prior_from_crossings)
    if not mv.DATA.is_dir():
        print(f"{mv.DATA} is absent: nothing to fit")
        return 0
    args.output.mkdir(parents=True, exist_ok=True)
    done = {u: None if args.force else _done_row(args.output, u, args.particles, args.seed, args.optima_mixture,
                                                 args.gap_prior_from_crossings, args.final_moves, args.max_moves)
            for u in args.units}
    todo = [u for u in args.units if done[u] is None]
    for u in args.units:
        if done[u] is not None:
            print(f"{u}: reusing {_row_path(args.output, u)} (--force refits it)")
    with executor(workers=args.jobs) as run_map:
        list(run_map(functools.partial(_fit_both, particles=args.particles, seed=args.seed,
                                       output=args.output, draws=args.save_draws,
                                       optima_mixture=args.optima_mixture,
                                       gap_prior_from_crossings=args.gap_prior_from_crossings,
                                       final_max_moves=args.final_moves, max_moves=args.max_moves,
                                       resume=not args.force,
                                       progress=args.progress), todo))  # each row saved as it is done
    return write_page(args.output, args.particles, args.optima_mixture, args.gap_prior_from_crossings)


def write_page(output: Path, particles: int, optima_mixture: bool = False, gap_prior_from_crossings: bool = False) -> int:
    """smc.json and smc.md in ``output`` from every row saved there."""
    rows = saved_rows(output)
    if not rows:
        print(f"{output / 'units'}: no saved rows to write a page from (fit some loops first: --units ...)")
        return 2
    count = page_particles(rows, particles)
    (output / "smc.json").write_text(json.dumps({"source": mv.SOURCE, "particles": count, "units": rows},
                                                indent=1, default=float))
    text = markdown(rows, count, optima_mixture, gap_prior_from_crossings)
    (output / "smc.md").write_text(text + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
