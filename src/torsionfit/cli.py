"""``torsionfit`` command line. Bad input → one line on stderr and exit code 2, never a traceback;
Ctrl-C → one line and exit code 130. Progress goes to stderr (``--quiet``: none), results to
stdout, and every JSON output records its provenance (version, seed, command line)."""

import argparse
import json
import logging
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path

from . import __version__
from ._errors import InputError
from ._provenance import command_line, provenance

EXIT_INPUT_ERROR = 2
#: exit code after Ctrl-C (128 + SIGINT, as shells report it)
EXIT_INTERRUPTED = 130
#: --ar1 choices: NoiseOptions.ar1 (auto: AR(1) on runs of >= 100 samples)
AR1 = {"auto": None, "on": True, "off": False}


def _cmd_simulate(args) -> int:
    from .bench import load_bench, simulate
    from .io import write_campaign

    bench = load_bench(args.bench)
    _say(args)(f"read {args.bench}: simulating {bench.label}")
    sim = simulate(bench, seed=args.seed)
    if bench.te_export is not None:
        # a bench with [te_export] writes a TE bench's own export layout (side-by-side fw/bw files)
        from .bench import write_te_export

        manifest = write_te_export(sim, bench, args.output)
        print(f"wrote {manifest} ({len(sim.campaign.runs)} TE runs in the bench-export layout, {bench.label})")
        return 0
    manifest = write_campaign(sim.campaign, args.output, label=bench.label, bench_file=bench.path)
    print(f"wrote {manifest} ({len(sim.campaign.runs)} runs, {bench.label})")
    return 0


def _cmd_metrics(args) -> int:
    from .io import load_campaign
    from .metrics import campaign_metrics, format_metrics_table

    campaign = load_campaign(args.campaign)
    result = campaign_metrics(
        campaign, lost_motion_pct=args.lost_motion_pct, t1_Nm=args.t1_Nm, t2_Nm=args.t2_Nm
    )
    # A metric that cannot be computed is a note of its run; no metric at all is bad input.
    if not any(run["metrics"] for run in result["runs"]):
        run = result["runs"][0]
        name, note = next(iter(run["notes"].items()))
        raise InputError(f"run {run['name']!r}: no metric could be computed ({name}: {note})")
    if args.json:
        json.dump({**result, "provenance": provenance(None, args.command_line)}, sys.stdout, indent=2)  # no seed: deterministic
        print()
    else:
        if campaign.notes:
            print(campaign.notes)
        print(format_metrics_table(result))
    return 0


def _progress(command: str, quiet: bool = False):
    """Progress callback: ``[command] text`` lines on stderr, or nothing when ``quiet``."""
    if quiet:
        return lambda text: None
    return lambda text: print(f"[{command}] {text}", file=sys.stderr, flush=True)


def _say(args):
    """The progress callback of the command ``args`` runs."""
    return _progress(args.command, args.quiet)


@contextmanager
def _progress_log(command: str, quiet: bool):
    """torsionfit's progress log lines (INFO: the MAP's starts, emcee's steps left) as
    ``[command] text`` on stderr while the command runs; none with ``quiet``. Undone after, as
    ``main`` is also called from Python."""
    logger = logging.getLogger("torsionfit")
    if quiet:
        yield
        return
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter(f"[{command}] %(message)s"))
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def _parse_effects(items) -> dict:
    """``--with NAME`` or ``--with NAME=VALUE`` (VALUE in TOML, as in a bench file's [effects])."""
    import tomllib

    from .bench import EFFECTS

    effects = {}
    for item in items or []:
        name, _, value = item.partition("=")
        name = name.strip()
        if name not in EFFECTS or name == "encoder_ripple":
            known = ", ".join(e for e in EFFECTS if e != "encoder_ripple")
            raise InputError(f"--with {item!r}: unknown effect {name!r}; expected one of {known}")
        if not value:
            effects[name] = True
            continue
        try:
            effects[name] = tomllib.loads(f"v = {value}")["v"]
        except tomllib.TOMLDecodeError:
            raise InputError(f"--with {item!r}: value {value!r} is not a TOML value (e.g. [1, 2, 39] or {{viscous = true}})") from None
    return effects


def _cmd_fit(args) -> int:
    from .fit import NoiseOptions, check_fittable
    from .io import load_campaign
    from .report import FitOptions, fit_campaign, summary_table, write_fit

    campaign = load_campaign(args.campaign)
    check_fittable(campaign)  # before the model is built from the rated torque
    out = Path(args.output)
    options = FitOptions(
        effects=_parse_effects(args.with_),
        noise=NoiseOptions(ar1=AR1[args.ar1], student_t_dof=args.student_t, cycle_class_noise=args.class_noise or args.first_excursion_class,
                           first_excursion_class=args.first_excursion_class,
                           first_excursion_conditioning=args.condition_first_excursions),
        sampler=args.sampler,
        n_walkers=args.walkers,
        max_steps=args.max_steps,
        n_chains=args.chains,
        max_draws=args.max_draws,
        progress=not args.quiet,
        backend_path=str(out / "chain.h5") if args.resume or args.save_chain else None,
        resume=args.resume,
        decimate=args.decimate,
        laplace_shape=args.laplace_shape,
        smc_particles=args.smc_particles,
        smc_max_moves=args.smc_moves,
        smc_final_max_moves=args.smc_final_moves,
    )
    say = _say(args)  # progress once the input is known good: bad input is one line
    say(f"read {args.campaign}: " + _campaign_line(campaign) + f"; sampler {args.sampler}")
    if options.backend_path is not None:
        out.mkdir(parents=True, exist_ok=True)  # the chain is written there from the first step
    fit = fit_campaign(campaign, options, seed=args.seed)
    say(f"writing {out}")
    doc = write_fit(fit, out, command=args.command_line)
    from .plots import write_fit_figures

    write_fit_figures(fit, out / "figures")
    print(summary_table(doc))
    print(f"wrote {out / 'fit.json'}" + (f", {out / 'posterior.nc'}" if fit.tree is not None else "") + f", {out / 'figures'}/")
    return 0


def _cmd_diagnose(args) -> int:
    from .diagnose import DiagnoseOptions, diagnose, summary_text, write_diagnosis
    from .fit import NoiseOptions, check_fittable
    from .io import decimate, load_campaign

    campaign = decimate(load_campaign(args.campaign), args.decimate)
    check_fittable(campaign)  # before the model is built from the rated torque
    options = DiagnoseOptions(initial_effects=_parse_effects(args.with_),
                              noise=NoiseOptions(ar1=AR1[args.ar1], student_t_dof=args.student_t),
                              robust_signatures=not args.least_squares_signatures, backward=not args.no_backward,
                              swap=not args.no_swap)
    say = _say(args)  # progress once the input is known good: bad input is one line
    say(f"read {args.campaign}: " + _campaign_line(campaign))
    result = diagnose(campaign, options, seed=args.seed, progress=say)
    doc = write_diagnosis(result, campaign, args.output, seed=args.seed, command=args.command_line)
    print(summary_text(doc))
    print(f"wrote {Path(args.output) / 'diagnose.json'}, {Path(args.output) / 'figures'}/")
    return 0


def _cmd_accept(args) -> int:
    from .accept import (EXIT_CODE, accept_campaign, accept_folder, batch_exit_code, load_spec, summary_text,
                         write_accept, write_batch_table)
    from .io import load_campaign
    from .report import FitOptions

    say = _say(args)
    spec = load_spec(args.spec)
    options = FitOptions(effects=_parse_effects(args.with_), sampler=args.sampler, max_steps=args.max_steps,
                         progress=not args.quiet, decimate=args.decimate)
    out = Path(args.output)
    if args.campaign.is_dir() and not (args.campaign / "campaign.toml").is_file():
        rows = accept_folder(args.campaign, spec, out, options, seed=args.seed, progress=say, command=args.command_line)
        paths = write_batch_table(rows, out, provenance=provenance(args.seed, args.command_line))
        counts = {d: sum(r["decision"] == d for r in rows) for d in ("accept", "reject", "indeterminate", "error")}
        print(f"{len(rows)} units: " + ", ".join(f"{n} {d}" for d, n in counts.items()))
        print(f"wrote {paths[0]}, {paths[1]}")
        return batch_exit_code(rows)
    # accept_campaign checks the spec against the campaign before any fit, then logs its progress
    result = accept_campaign(load_campaign(args.campaign), spec, options, seed=args.seed)
    print(summary_text(write_accept(result, out, command=args.command_line)))
    print(f"wrote {out / 'accept.json'}")
    return EXIT_CODE[result.decision.decision]


def _cmd_batch(args) -> int:
    import hashlib

    from .accept import load_spec
    from .batch import (BatchOptions, WorkerProcessError, default_workers, exit_code, posterior_sample, run_batch,
                        unit_tasks)
    from .report import FitOptions

    spec = load_spec(args.spec) if args.spec else None
    if args.posterior_sample < 0 or args.group_size < 1 or (args.workers is not None and args.workers < 1):
        raise InputError("--posterior-sample must be ≥ 0, --group-size ≥ 1 and --workers ≥ 1")
    if args.workers is not None and args.scheduler:
        raise InputError("--workers is for this machine; with --scheduler the Dask cluster's workers run the units")
    units = [t.unit for t in unit_tasks(args.folder, args.output)]
    options = BatchOptions(
        fit=FitOptions(effects=_parse_effects(args.with_), sampler=args.sampler, max_steps=args.max_steps,
                       progress=False, decimate=args.decimate),
        spec=spec, spec_digest=hashlib.sha256(args.spec.read_bytes()).hexdigest() if spec else None,
        posterior_units=posterior_sample(units, args.posterior_sample, args.seed),
        figures=args.figures, group_size=args.group_size, seed=args.seed, command=args.command_line)
    say = _say(args)
    workers = args.workers if args.workers is not None else 1 if args.scheduler else default_workers()
    try:
        rows = run_batch(args.folder, args.output, options, scheduler=args.scheduler, force=args.force, progress=say,
                         workers=workers)
    except WorkerProcessError as err:
        print(f"torsionfit batch: error: {err}", file=sys.stderr)
        return 2
    counts = {}
    for row in rows:
        key = row.get("decision") or ("error" if row["status"] == "error" else
                                      "converged" if row.get("converged") else "not converged")
        counts[key] = counts.get(key, 0) + 1
    print(f"{len(rows)} units: " + ", ".join(f"{n} {k}" for k, n in counts.items()))
    print(f"wrote {Path(args.output) / 'batch.csv'}, {Path(args.output) / 'batch.json'}")
    return exit_code(rows, spec is not None)


def _cmd_paper(args) -> int:
    from .paper import paper_settings, posterior_line, run_paper

    say = _say(args)
    command = " ".join(["torsionfit paper -o DIR"] + (["--quick"] if args.quick else []) + ([f"--seed {args.seed}"] if args.seed else [])
                       + ([f"--sampler {args.sampler}"] if args.sampler else []))
    doc = run_paper(args.output, paper_settings(args.quick, args.seed, args.sampler), args.data, say, command)
    print(f"max deviation from the published tables {100 * doc['max_relative_deviation']:.3f} %; "
          f"wrote {args.output / 'tables.json'}, {args.output / 'README.md'}, {len(doc['figures'])} figure files")
    print(posterior_line(doc["fits"]))
    return 0


def _campaign_line(campaign) -> str:
    """One progress line: what was read."""
    n = sum(len(r) for r in campaign.runs)
    return (f"{len(campaign.runs)} runs ({len(campaign.hysteresis_runs)} hysteresis, {len(campaign.te_runs)} TE), "
            f"{n} samples")


def _interrupted(args) -> str:
    """The one line after Ctrl-C: what is kept and how to go on."""
    if args.command == "fit":
        if args.save_chain or args.resume:
            out = Path(args.output)
            files = {"emcee": f"{out / 'chain.h5'}", "nuts": f"{out / 'chain-nuts.npz'}", "smc": f"{out / 'chain-smc.npz'}"}
            where = files.get(args.sampler) or f"{files['emcee']} (emcee) or {files['nuts']} (NUTS)"
            return f"interrupted; the chain so far is kept in {where}: the same command with --resume continues it"
        return "interrupted; no chain was kept (--save-chain keeps one that --resume continues)"
    if args.command == "batch":
        return "interrupted; units already done keep their files: the same command skips them and does the rest"
    return "interrupted"


# Options several subcommands share; the defaults are the common name, default and help text,
# the keyword arguments keep the few places where a subcommand says it differently.
def _add_campaign(p) -> None:
    p.add_argument("campaign", type=Path, help="campaign manifest (TOML)")


def _add_output(p) -> None:
    p.add_argument("-o", "--output", type=Path, required=True, help="output folder")


def _add_seed(p, help="random seed (default 0)") -> None:
    p.add_argument("--seed", type=int, default=0, help=help)


def _add_with(p, help="switch a model extension on by hand (repeatable), as for fit") -> None:
    p.add_argument("--with", dest="with_", action="append", metavar="EFFECT[=VALUE]", help=help)


def _add_sampler(p, default="emcee", choices=("emcee", "laplace"),
                 help="emcee posterior (default) or the MAP's Laplace approximation (fast screening)") -> None:
    p.add_argument("--sampler", choices=choices, default=default, help=help)


def _add_max_steps(p, help="cap on emcee steps") -> None:
    p.add_argument("--max-steps", type=int, default=20_000, help=help)


def _add_decimate(p, help="fit block means of N consecutive samples") -> None:
    p.add_argument("--decimate", type=int, default=1, metavar="N", help=help)


def _add_quiet(p) -> None:
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress on stderr (results on stdout, warnings and errors still shown)")
    p.add_argument("--no-progress", dest="quiet", action="store_true", help=argparse.SUPPRESS)  # the old spelling


def _moves_at_least(least: int, why: str = "the stages before the last get {least}"):
    """An argparse type: an integer of moves no smaller than ``least`` (by default the stages' own
    budget; ``why`` says what sets it)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer number of moves, got {text!r}") from None
        if value < least:
            raise argparse.ArgumentTypeError(f"expected at least {least} moves ({why.format(least=least)}), "
                                             f"got {value}")
        return value
    return parse


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="torsionfit",
        description="Torsional stiffness of gear reducers from test-bench data, with uncertainty.",
    )
    parser.add_argument("--version", action="version", version=f"torsionfit {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("simulate", help="write a campaign (manifest + CSVs) from a virtual bench file")
    p.add_argument("bench", type=Path, help="bench file (TOML)")
    _add_output(p)
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the bench file's)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("metrics", help="catalog metrics from the data alone (no model fit)")
    _add_campaign(p)
    p.add_argument("--json", action="store_true", help="machine-readable JSON on stdout")
    p.add_argument("--lost-motion-pct", type=float, default=3.0, help="±x %% of rated torque for lost motion (default 3)")
    p.add_argument("--t1-Nm", type=float, default=None, help="catalog knee T1 (default 0.25·T_r)")
    p.add_argument("--t2-Nm", type=float, default=None, help="catalog knee T2 (default 0.75·T_r)")
    p.set_defaults(func=_cmd_metrics)

    p = sub.add_parser("fit", help="fit the model: stiffness with uncertainty, its three parts, fit.json")
    _add_campaign(p)
    _add_output(p)
    _add_seed(p)
    _add_with(p, help="switch a model extension on by hand (repeatable), e.g. --with rate_dependence "
                      "--with 'kinematic_error=[1, 2, 39]' --with 'speed_dependence={viscous = true, compliance_order = 2}'")
    _add_sampler(p, default="auto", choices=("auto", "emcee", "nuts", "smc", "laplace"),
                 help="auto (default): emcee, or NUTS when emcee's first checks show it needs more than "
                      "--max-steps; emcee; nuts (gradient-based, BlackJAX); smc: tempered SMC from the split "
                      "normal to the posterior (where laplace's Pareto k says its draws do not stand for it); "
                      "laplace: the MAP's Gaussian approximation (fast screening). The choice and its reason go "
                      "to fit.json")
    p.add_argument("--smc-particles", type=int, default=1000, help="smc's particles (its draws; default 1000)")
    p.add_argument("--smc-moves", type=_moves_at_least(1, "a stage moves its particles at least once"), default=100,
                   help="smc's moves allowed at every stage (default 100): a stage whose particles have not forgotten "
                        "their start by then reads not converged; the last stage gets at least as many")
    p.add_argument("--smc-final-moves", type=_moves_at_least(100), default=100,
                   help="smc's moves allowed at the last stage, on the posterior itself (default 100, as at every "
                        "stage before it; more only sample the posterior longer)")
    p.add_argument("--laplace-shape", choices=("gaussian", "split"), default="gaussian",
                   help="laplace's draws: the Gaussian (default), or a split normal whose half-axes are measured "
                        "on the posterior (for posteriors that are not Gaussian: widened fits of measured loops)")
    p.add_argument("--walkers", type=int, default=None, help="emcee walkers (default max(32, 2·dim+2))")
    _add_max_steps(p, help="cap on emcee steps; reaching it gives converged: false (auto: the budget "
                           "against which emcee's first checks are judged)")
    p.add_argument("--chains", type=int, default=4, help="NUTS chains (default 4)")
    p.add_argument("--max-draws", type=int, default=4000,
                   help="cap on NUTS draws per chain (200, grown by half until converged); reaching it gives converged: false")
    p.add_argument("--ar1", choices=tuple(AR1), default="auto", help="AR(1) residuals (auto: runs of ≥ 100 samples)")
    p.add_argument("--student-t", type=float, default=None, metavar="DOF", help="Student-t likelihood with DOF degrees of freedom")
    p.add_argument("--class-noise", action="store_true",
                   help="a noise level per class of cycle amplitude (play ramps, stiffness ramps), their ratio read "
                        "from the residuals at the MAP; the shares go to fit.json")
    p.add_argument("--first-excursion-class", action="store_true",
                   help="with the class noise (implied): the ramps that first load a run beyond its earlier peaks "
                        "(the first large ramp) a class of their own, the repeated ramps' level the largest class's")
    p.add_argument("--condition-first-excursions", action="store_true",
                   help="the same first excursions drive the model's state but are out of the likelihood "
                        "(conditioning cycles); the samples left out go to fit.json")
    p.add_argument("--save-chain", action="store_true",
                   help="keep the chain in OUTPUT/chain.h5 (emcee) / OUTPUT/chain-nuts.npz (NUTS) / "
                        "OUTPUT/chain-smc.npz (smc: its particles after every stage)")
    p.add_argument("--resume", action="store_true", help="continue an interrupted run from those files")
    _add_decimate(p, help="fit block means of N consecutive samples (dense benches; recorded in fit.json)")
    p.set_defaults(func=_cmd_fit)

    p = sub.add_parser("diagnose", help="close the loop: find what the model misses, add it, report before/after")
    _add_campaign(p)
    _add_output(p)
    _add_seed(p)
    _add_with(p, help="start from a model with this extension already on (repeatable)")
    _add_decimate(p, help="diagnose block means of N consecutive samples (dense benches)")
    p.add_argument("--ar1", choices=tuple(AR1), default="auto",
                   help="AR(1) residuals (auto: runs of >= 100 samples); off for measured loops whose misfit is slow")
    p.add_argument("--student-t", type=float, default=None, metavar="DOF",
                   help="Student-t likelihood with DOF degrees of freedom (residuals that move in jumps)")
    p.add_argument("--least-squares-signatures", action="store_true",
                   help="signatures by least squares alone, against the noise of the residuals' mean-square variogram "
                        "(default: where a residual moves in jumps, each also tested winsorised at the noise read from median increments)")
    p.add_argument("--no-backward", action="store_true",
                   help="the greedy trail alone (default: when it stops, each kept effect but the last is refitted out of "
                        "the final model; one the others made redundant is dropped and the trail goes on without it)")
    p.add_argument("--no-swap", action="store_true",
                   help="no swaps (default: a trail at its limit of effects with a signature left refits the weakest "
                        "kept effect out and the candidate in its place, and keeps the swap when it earns its keep)")
    p.set_defaults(func=_cmd_diagnose)

    p = sub.add_parser(
        "accept", help="accept / reject / indeterminate against a spec, from the posterior (JCGM 106)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Decide a unit (or every campaign.toml under a folder) against a spec file from the\n"
                    "posterior probability of conformance p_c; writes OUTPUT/accept.json (a folder: one\n"
                    "OUTPUT/<unit>/accept.json each and OUTPUT/accept_batch.csv + .json, a row per unit).",
        epilog="exit codes: 0 accept, 3 reject, 4 indeterminate (retest; also: posterior not converged),\n"
               "2 bad input. Over a folder: 2 if any unit is in error, else 4 if any is indeterminate,\n"
               "else 3 if any is rejected, else 0.")
    p.add_argument("campaign", type=Path,
                   help="campaign manifest (TOML) or a folder holding one; any other folder: every campaign.toml under it")
    p.add_argument("--spec", type=Path, required=True, help="spec file (TOML): p_accept and [[requirement]] tables")
    _add_output(p)
    _add_seed(p)
    _add_sampler(p, choices=("emcee", "auto", "nuts", "laplace"),
                 help="emcee posterior (default); auto or nuts as for fit; laplace: the MAP's Laplace "
                      "approximation (fast screening). A posterior that does not converge gives indeterminate")
    _add_max_steps(p, help="cap on emcee steps; reaching it gives indeterminate")
    _add_with(p)
    _add_decimate(p)
    p.set_defaults(func=_cmd_accept)

    p = sub.add_parser(
        "batch", help="every campaign under a folder: fit, metrics, acceptance; one row per unit",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Fit every campaign.toml under FOLDER (units of one problem shape together), with the\n"
                    "decision against --spec when given; OUTPUT/<unit>/fit.json (+ accept.json, posterior.nc)\n"
                    "and OUTPUT/batch.csv + batch.json, a row per unit. A unit in error is a row with its\n"
                    "message; a re-run skips units already done with the same settings (--force redoes them).",
        epilog="exit codes: 2 if any unit is in error; with --spec else 4 if any is indeterminate, else 3 if\n"
               "any is rejected, else 0; without --spec else 4 if any posterior did not converge, else 0.")
    p.add_argument("folder", type=Path, help="folder: every campaign.toml in it or below is a unit")
    _add_output(p)
    p.add_argument("--spec", type=Path, default=None, help="spec file (TOML): decide every unit (as accept)")
    _add_seed(p, help="random seed of every unit (default 0)")
    _add_sampler(p, default="laplace", choices=("laplace", "emcee"),
                 help="every unit's posterior: the MAP's Laplace approximation (default) or emcee")
    p.add_argument("--posterior-sample", type=int, default=0, metavar="K",
                   help="K units, chosen by the seed, get the full emcee posterior (default 0)")
    _add_max_steps(p)
    _add_with(p)
    _add_decimate(p)
    p.add_argument("--group-size", type=int, default=16, metavar="G",
                   help="units per packet (one task of a worker; its units of one shape fitted together), at most (default 16)")
    p.add_argument("--workers", type=int, default=None, metavar="W",
                   help="worker processes on this machine (default: one per usable CPU, each pinned to it; 1 with a GPU; 1 = this process)")
    p.add_argument("--figures", action="store_true", help="also write each unit's figures")
    p.add_argument("--force", action="store_true", help="redo units already done")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the groups on a Dask distributed cluster, e.g. tcp://host:8786 (pip install 'torsionfit[dask]')")
    p.set_defaults(func=_cmd_batch)

    p = sub.add_parser("paper", help="reproduce Cheng et al. 2023 on the bundled SYNTHETIC campaigns: figures, tables.json, comparison page")
    _add_output(p)
    p.add_argument("--quick", action="store_true", help="quick settings: Laplace approximation, slowest loop only, decimated, small grid (tests)")
    _add_seed(p)
    _add_sampler(p, default=None, choices=("laplace", "emcee", "nuts", "auto"),
                 help="posterior of the fits: auto (default without --quick, as for fit), emcee or nuts within the "
                      "paper's budget, the MAP's Laplace approximation where that does not converge; laplace (default "
                      "with --quick) always. tables.json, the page and the last printed line say which each fit used")
    p.add_argument("--data", type=Path, default=None, help="folder holding paper-small/ and paper-large/ (default: the checkout's data/)")
    p.set_defaults(func=_cmd_paper)
    for p in sub.choices.values():
        _add_quiet(p)
    return parser


def _one_line_warnings(command: str):
    """``warnings.showwarning`` that prints torsionfit's own warnings (implausible data,
    extrapolated decisions, unconverged chains; a torsionfit warning class, or any warning
    raised in torsionfit's code: the fit's notes on its draws and on the metrics it leaves out)
    as one stderr line (``torsionfit CMD: warning: ...``) and any other warning as Python does."""
    default = warnings.showwarning
    package = Path(__file__).resolve().parent

    def ours(category, filename) -> bool:
        if category.__module__.split(".")[0] == "torsionfit":
            return True
        try:
            return Path(filename).resolve().is_relative_to(package)
        except (OSError, ValueError):  # a filename that is no path ("<string>")
            return False

    def show(message, category, filename, lineno, file=None, line=None):
        if ours(category, filename):
            print(f"torsionfit {command}: warning: {message}", file=sys.stderr, flush=True)
        else:
            default(message, category, filename, lineno, file, line)

    return show


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    args.command_line = command_line(argv)
    from ._cache import enable_compilation_cache

    from ._threads import single_blas_thread
    from ._x64 import float64

    enable_compilation_cache()  # TORSIONFIT_CACHE_DIR chooses the folder, =off switches it off
    try:
        # float64 for this call only (main() is called from Python too); one BLAS thread: spinning
        # BLAS threads would take the cores from XLA
        with single_blas_thread(), float64(), warnings.catch_warnings(), _progress_log(args.command, args.quiet):
            warnings.showwarning = _one_line_warnings(args.command)
            return args.func(args)
    except InputError as err:
        print(f"torsionfit {args.command}: error: {err}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except KeyboardInterrupt:
        print(f"torsionfit {args.command}: {_interrupted(args)}", file=sys.stderr, flush=True)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
