"""Close the loop on the measured cycloidal loops — REAL data from ../shared/data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0): run ``diagnose`` on each unit and
write OUT/<unit>/diagnose.json with its figures, and OUT/measured-trail.md (the trail table
the README quotes) and OUT/measured-trail.json.

    .venv/bin/python scripts/diagnose_measured.py -o docs/diagnose            # the README's three loops
    .venv/bin/python scripts/diagnose_measured.py -o out/diagnose --all --jobs 2  # all 21 loops
    .venv/bin/python scripts/diagnose_measured.py --refit-each --units U ...  # what each effect earns alone
    .venv/bin/python scripts/diagnose_measured.py -o docs/diagnose/all-loops --no-backward --append --units U ...

The table and its JSON are written again as each unit finishes, so a run stopped part way keeps
the units it finished. ``--append`` re-runs the units named and keeps the other units' rows of
the table already in OUT (each unit's entry records the settings it was run with).
"""

import argparse
import functools
import json
import sys
import time
from pathlib import Path

import jax

from torsionfit._cache import enable_compilation_cache
from torsionfit.batch import executor
from torsionfit.diagnose import CATALOG, DiagnoseOptions, GapRelays, diagnose, summary_text, write_diagnosis
from torsionfit.fit import NoiseOptions
from torsionfit.io import decimate, load_campaign

ROOT = Path(__file__).resolve().parents[1]
MANIFESTS = ROOT / "examples" / "cycloidal-jv"
#: one loop per design, both new (initial) and at the same rotor position, and the most preloaded
#: split unit at another, whose gap is held up to the preload
DEFAULT_UNITS = ["baseline-pccf-initial-pos1", "split-pccf-initial-pos1", "split-pccf-preload3-pos6"]
NOISE_TEXT = {"off": "iid noise, `--ar1 off`", "on": "AR(1) noise", "auto": "the fit's default noise, AR(1) on these runs"}


def trail_rows(unit: str, doc: dict, seconds: float) -> list[str]:
    """Markdown rows of one unit's trail: the base fit, then one row per effect added."""
    rows = [f"| {unit} | base model | | {doc['rmse_base']:.0f} | {doc['base']['max_abs']:.0f} | | {seconds:.0f} |"]
    for s in doc["steps"]:
        rows.append(f"| | + {s['effect']} | {s['evidence']['log10_p']:.1f} | {s['rmse_before']:.0f} → {s['rmse_after']:.0f} | "
                    f"{s['max_abs_before']:.0f} → {s['max_abs_after']:.0f} | {s['delta_elpd']:.0f} ± {s['delta_elpd_se']:.0f} | |")
    keep = DiagnoseOptions()
    for s in doc["rejected"]:
        # earned its keep but another candidate of the same step earned more
        outgained = keep.earns_keep(s["delta_elpd"], s["delta_elpd_se"], s["rmse_before"], s["rmse_after"])
        rows.append(f"| | tried, {'outgained' if outgained else 'not kept'}: {s['effect']} | {s['evidence']['log10_p']:.1f} | {s['rmse_before']:.0f} → "
                    f"{s['rmse_after']:.0f} | | {s['delta_elpd']:.0f} ± {s['delta_elpd_se']:.0f} | |")
    for r in doc.get("removals", []):
        verdict = "dropped (redundant)" if r["dropped"] else "checked, kept"
        rows.append(f"| | {verdict}: {r['effect']} | | {r['rmse_without']:.0f} → {r['rmse_with']:.0f} | | "
                    f"{r['delta_elpd']:.0f} ± {r['delta_elpd_se']:.0f} | |")
    left = doc["unexplained_description"] if doc["unexplained"] else "nothing significant"
    rows.append(f"| | left unexplained: {left} | | {doc['rmse_final']:.0f} | | | |")
    return rows


def noise_options(args) -> NoiseOptions:
    """The fits' noise under ``--ar1`` and ``--student-t``."""
    return NoiseOptions(ar1={"auto": None, "on": True, "off": False}[args.ar1], student_t_dof=args.student_t)


def refit_each(units: list[str], args) -> int:
    """Print, per unit, the ΔELPD ± SE (the trail's comparison) of the base model plus each effect
    of the unit's validation model (scripts/measured_validation.py) alone over the base model."""
    from measured_validation import effects_for
    from torsionfit.diagnose._loop import fit_with
    from torsionfit.diagnose._selection import compare

    options = DiagnoseOptions(noise=noise_options(args))
    print("| unit | effect alone | RMSE (arcsec) | ΔELPD ± SE | earns its keep |")
    print("| --- | --- | ---: | ---: | --- |")
    for unit in units:
        campaign = decimate(load_campaign(MANIFESTS / f"{unit}.toml"), args.decimate)
        base = fit_with(campaign, {}, options, args.seed)
        print(f"| {unit} | base model | {base.rmse_arcsec:.0f} | | |", flush=True)
        for name, value in effects_for(unit, argparse.Namespace(effects=None)).items():
            trial = fit_with(campaign, {name: value}, options, args.seed, warm=base)
            c = compare(base.score, trial.score)
            print(f"| | {name} = {json.dumps(value)} | {base.rmse_arcsec:.0f} → {trial.rmse_arcsec:.0f} | "
                  f"{c.delta:.0f} ± {c.se:.0f} | {'yes' if options.earns_keep(c.delta, c.se, base.rmse_arcsec, trial.rmse_arcsec) else 'no'} |", flush=True)
        jax.clear_caches()
    return 0


def diagnose_unit(unit: str, args) -> tuple[list[str], dict, str]:
    """Run ``diagnose`` on one unit and write OUT/<unit>/: (its trail rows, its entry of
    measured-trail.json, its summary text)."""
    t0 = time.perf_counter()
    campaign = decimate(load_campaign(MANIFESTS / f"{unit}.toml"), args.decimate)
    say = lambda text: print(f"[{unit}] {text}", file=sys.stderr, flush=True)  # noqa: E731
    options = DiagnoseOptions(noise=noise_options(args), candidates_per_step=args.candidates_per_step,
                              max_candidates_first_step=args.max_candidates_first_step,
                              max_candidates_per_step=args.max_candidates_per_step,
                              robust_signatures=not args.least_squares_signatures, backward=not args.no_backward,
                              swap=not args.no_swap, catalog=catalog(args))
    result = diagnose(campaign, options, seed=args.seed, progress=say)
    doc = write_diagnosis(result, campaign, args.output / unit)
    seconds = time.perf_counter() - t0
    entry = {k: doc[k] for k in ("label", "added", "replaced", "unexplained", "unexplained_description", "rmse_base", "rmse_final")}
    entry["steps"] = [{k: s[k] for k in ("effect", "rmse_before", "rmse_after", "delta_elpd", "delta_elpd_se")} for s in doc["steps"]]
    entry["dropped"] = [r["effect"] for r in doc["removals"] if r["dropped"]]
    entry["seconds"] = seconds
    entry["settings"] = run_settings(args)
    entry["rows"] = trail_rows(unit, doc, seconds)
    # each loop compiles its own programs (its lengths): kept across 21 loops they exhausted
    # the compiler's memory at the 13th
    jax.clear_caches()
    return entry["rows"], entry, summary_text(doc)


def catalog(args) -> tuple:
    """The effects catalog: the default one, its relay gap tested from the smooth gap too under
    ``--relays-from-smooth-gap``."""
    if not args.relays_from_smooth_gap:
        return CATALOG
    return tuple(GapRelays(from_smooth_gap=True) if isinstance(e, GapRelays) else e for e in CATALOG)


#: the options that decide a trail (recorded with each unit's entry)
SETTINGS = ("decimate", "seed", "ar1", "student_t", "candidates_per_step", "max_candidates_first_step",
            "max_candidates_per_step", "least_squares_signatures", "no_backward", "no_swap", "relays_from_smooth_gap")


def run_settings(args) -> dict:
    """The options of this run that decide a unit's trail."""
    return {k: getattr(args, k) for k in SETTINGS}


def rows_by_unit(table_md: str) -> dict[str, list[str]]:
    """The trail rows of each unit in a measured-trail.md table: a unit's first row names it,
    its further rows have an empty first cell."""
    out, unit = {}, None
    for line in table_md.splitlines():
        if not line.startswith("| ") or line.startswith("| unit |") or line.startswith("| ---"):
            continue
        first = line.split("|")[1].strip()
        unit = first or unit
        if unit is not None:
            out.setdefault(unit, []).append(line)
    return out


def kept_units(output: Path, rerun: list[str]) -> tuple[dict, dict]:
    """(entries, rows) of the units of the table already in ``output`` that are not re-run;
    entries written before the rows were recorded with them take theirs from the table."""
    json_path, md_path = output / "measured-trail.json", output / "measured-trail.md"
    if not json_path.is_file():
        return {}, {}
    entries = {u: e for u, e in json.loads(json_path.read_text()).items() if u not in rerun}
    table = rows_by_unit(md_path.read_text()) if md_path.is_file() else {}
    rows = {}
    for unit, entry in entries.items():
        rows[unit] = entry.get("rows") or table.get(unit)
        if not rows[unit]:
            raise SystemExit(f"{json_path}: unit {unit} has no trail rows in it or in {md_path.name}; re-run it")
    return entries, rows


def header(args) -> list[str]:
    """The table's caption and head under this run's settings."""
    return [
        "Closing the loop on measured loops (REAL data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0; "
        f"block means of {args.decimate} samples; rated torque 20 N·m assumed; {NOISE_TEXT[args.ar1]}"
        + (f", Student-t with ν = {args.student_t:g}" if args.student_t else "")
        + (", least-squares signatures" if args.least_squares_signatures else ", robust signatures")
        + (", no backward checks (`--no-backward`)" if args.no_backward else ", backward checks: each kept effect but the "
           "last refitted out of the final model, a redundant one dropped")
        + ("" if args.no_backward else ", no swaps (`--no-swap`)" if args.no_swap else ", swaps at the limit of effects")
        + (", the relay gap tested from the smooth gap too (`--relays-from-smooth-gap`)" if args.relays_from_smooth_gap else "")
        + "), "
        f"`scripts/diagnose_measured.py`, seed {args.seed}.",
        "",
        "| unit | step | log10 p of the signature | RMSE (arcsec) | max \\|residual\\| (arcsec) | ΔELPD ± SE | wall (s) |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]


def write_table(args, entries: dict, rows: dict) -> str:
    """Write OUT/measured-trail.md and .json with the units in name order; returns the table."""
    order = sorted(entries)
    text = "\n".join(header(args) + [r for u in order for r in rows[u]])
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "measured-trail.md").write_text(text + "\n")
    (args.output / "measured-trail.json").write_text(json.dumps({u: entries[u] for u in order}, indent=2))
    return text


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=Path("out/diagnose"))
    parser.add_argument("--units", nargs="+", default=DEFAULT_UNITS, help="manifest names under examples/cycloidal-jv")
    parser.add_argument("--all", action="store_true", help="every measured loop (21)")
    parser.add_argument("--decimate", type=int, default=16, help="block means of N samples (the loops are sampled at ~400 Hz)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--jobs", type=int, default=1, help="units diagnosed in this many processes at once")
    # iid, as the validation: with AR(1) noise the coefficient comes out near 1 on these files and a
    # smooth, ramp-long misfit costs (and an effect that removes it earns) little ELPD
    parser.add_argument("--ar1", choices=("auto", "on", "off"), default="off",
                        help="AR(1) residuals (default off, the validated setting on measured loops; auto: the fit's "
                             "default, on for runs of >= 100 samples)")
    parser.add_argument("--student-t", type=float, default=None, metavar="DOF",
                        help="Student-t noise with DOF degrees of freedom (the stick-slip jumps in its heavy tails)")
    parser.add_argument("--candidates-per-step", type=int, default=DiagnoseOptions().candidates_per_step,
                        help="significant signatures refitted per step, in the order of their least-squares test, the one "
                             "that earns the most kept (1: the first alone, kept when it earns its keep)")
    parser.add_argument("--max-candidates-first-step", type=int, default=DiagnoseOptions().max_candidates_first_step,
                        help="when none of the base model's step's candidates earns its keep, the next ones are tried, "
                             "up to this many refits in that step")
    parser.add_argument("--max-candidates-per-step", type=int, default=DiagnoseOptions().max_candidates_per_step,
                        help="the same at every later step (default: the first batch alone)")
    parser.add_argument("--least-squares-signatures", action="store_true",
                        help="signatures by least squares alone, against the mean-square variogram's noise, which counts "
                             "the jumps (default: where a residual moves in jumps, each also tested winsorised)")
    parser.add_argument("--no-backward", action="store_true",
                        help="no backward checks: the greedy trail alone (default: when it stops, each kept effect but "
                             "the last is refitted out, one the others made redundant is dropped and the trail goes on)")
    parser.add_argument("--no-swap", action="store_true",
                        help="no swaps (default: a trail at its limit of effects with a signature left refits its "
                             "weakest effect out and the candidate in its place, kept when it earns its keep)")
    parser.add_argument("--relays-from-smooth-gap", action="store_true",
                        help="test the gap crossed in held steps (gap_relays) on the smooth gap too, not only once a held "
                             "gap is in (where a held gap earns too little to be kept, the default trail never reaches them)")
    parser.add_argument("--append", action="store_true",
                        help="re-run the units named and keep the other units' rows of the table already in --output")
    parser.add_argument("--refit-each", action="store_true",
                        help="no trail: refit the base model plus each effect of the unit's validation model alone, "
                             "whatever its signature, and print the ΔELPD each earns (what the keep rule sees)")
    args = parser.parse_args(argv)
    if not (ROOT.parent / "shared" / "data" / "cycloidal-jv").is_dir():
        print("../shared/data/cycloidal-jv is absent: nothing to diagnose")
        return 0
    units = sorted(p.stem for p in MANIFESTS.glob("*.toml")) if args.all else args.units
    if args.refit_each:
        return refit_each(units, args)
    entries, rows = kept_units(args.output, units) if args.append else ({}, {})
    enable_compilation_cache()  # TORSIONFIT_CACHE_DIR chooses the folder, =off switches it off
    text = ""
    # units in processes of their own (one JAX runtime and one XLA thread each, pinned to a CPU)
    with executor(workers=args.jobs) as run_map:
        for unit, (unit_rows, entry, summary) in zip(units, run_map(functools.partial(diagnose_unit, args=args), units)):
            print(summary, file=sys.stderr)
            entries[unit], rows[unit] = entry, unit_rows
            text = write_table(args, entries, rows)  # a run stopped part way keeps the units it finished
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
