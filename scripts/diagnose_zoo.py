"""The undeclared-effect zoo: `diagnose` on every SYNTHETIC campaign the diagnose tests use, one table.

Each case is built by the same function, with the same seeds, as in ``tests/test_diagnose.py``
``tests/test_diagnose_friction.py`` and ``tests/test_diagnose_temperature.py`` (the virtual benches under ``tests/benches/``): an effect
switched on in the bench and never named in the written manifest, or one added to the readings.
The table (what was found, RMSE before and after, the noise estimate, ``unexplained``, ΔELPD ± SE
of each step) goes to ``docs/diagnose/zoo.md`` and between the markers ``<!-- zoo:begin -->`` and
``<!-- zoo:end -->`` of README.md when both are there. Compiled programs are kept in the
persistent cache of the command line (``TORSIONFIT_CACHE_DIR``), so a second run is faster.

    .venv/bin/python scripts/diagnose_zoo.py                          # every case (~15 diagnoses)
    .venv/bin/python scripts/diagnose_zoo.py --only clean ripple -o /tmp/zoo.md --no-readme
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the cases are the tests' own builders

import test_diagnose as td  # noqa: E402
import test_diagnose_friction as tf  # noqa: E402
import test_diagnose_temperature as tt  # noqa: E402

from torsionfit._cache import enable_compilation_cache  # noqa: E402
from torsionfit.diagnose import DiagnoseOptions, diagnose  # noqa: E402

BEGIN, END = "<!-- zoo:begin -->", "<!-- zoo:end -->"


@dataclass(frozen=True)
class Entry:
    name: str
    bench: str  # the bench file (tests/benches/…), what the readings were changed by
    build: object  # folder → td.Case
    expected: tuple  # effects diagnose should add (in any order)
    unexplained: bool = False  # expected value of ``unexplained``
    also_allowed: tuple = ()  # effects that may come along (physically entangled with the truth)


def _effect(name, bench="effects/base.toml"):
    return Entry(name, bench, lambda folder: td.effect_case(folder, name), (name,),
                 also_allowed=tuple(td.ENTANGLED[name]))


def _friction(name):
    return Entry(name, "friction/base.toml", lambda folder: tf.friction_case(folder, name, 0), (name,))


ZOO = (
    Entry("kinematic TE, 3600 samples/rev, 0.4″ noise", "effects/te_kinematic.toml", td.te_kinematic_case,
          ("kinematic_error",)),
    Entry("kinematic + speed (TE)", "effects/te_speed.toml", lambda folder: td.kinematic_speed_case(folder, 0),
          ("kinematic_error", "speed_dependence")),
    _effect("stiffness_nonlinearity"),
    _effect("rate_dependence"),
    _effect("asymmetry"),
    _effect("thermal_drift"),
    _effect("torque_offset"),
    _friction("load_dependent_friction"),
    _friction("distributed_friction"),
    _friction("gap_lag"),
    _friction("gap_hold"),
    _friction("play_torque_offset"),
    Entry("held gap about a torque of its own", "friction/base.toml",
          lambda folder: tf.friction_case(folder, "gap_centre", 0), ("gap_hold",)),
    # the lag in one step (as the memory's rival) or two (after the instantaneous level)
    Entry("friction level lagging the load", "friction/base.toml",
          lambda folder: tf.friction_case(folder, "friction_load_lag", 0), ("friction_load_lag",),
          also_allowed=("load_dependent_friction",)),
    Entry("friction level remembering the peak load", "friction/base.toml",
          lambda folder: tf.friction_case(folder, "friction_load_memory", 0), ("friction_load_memory",),
          also_allowed=("load_dependent_friction",)),
    Entry("warm-up drift", "effects/base.toml, a(1 − e^(−t/T)) added to the readings", td.warm_up_case,
          ("thermal_drift",)),
    _effect("kinematic_error"),
    _effect("speed_dependence", "effects/one_load.toml"),
    Entry("creep + kinematic", "effects/base.toml", td.two_effects_case, ("rate_dependence", "kinematic_error")),
    Entry("encoder ripple (outside the catalog)", "effects/base.toml", td.ripple_case, (), unexplained=True),
    Entry("clean", "effects/base.toml", lambda folder: td.clean_case(folder, 3), ()),
    Entry("temperature: stiffness and friction (TE at 25/40/55 °C)", "effects/te_temperature.toml",
          lambda folder: tt.temperature_case(folder, 0), ("temperature_dependence",)),
    Entry("temperature: friction level only", "effects/te_temperature.toml",
          lambda folder: tt.temperature_case(folder, 1), ("temperature_dependence",)),
    Entry("clean at three temperatures", "effects/te_temperature.toml",
          lambda folder: tt.temperature_case(folder, 0, clean=True), ()),
)


def _short(value) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    if isinstance(value, dict):
        return ", ".join(f"{k} {_short(v)}" for k, v in value.items())
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def row(entry: Entry, case, d, seconds: float) -> dict:
    added = [s.effect for s in d.steps]
    extra = set(added) - set(entry.expected) - set(entry.also_allowed)
    as_expected = set(entry.expected) <= set(added) and not extra and d.unexplained == entry.unexplained
    steps = "; ".join(f"{s.effect} {s.delta_elpd:.1f} ± {s.delta_elpd_se:.1f}" for s in d.steps) or "—"
    keep = DiagnoseOptions()
    rejected = "; ".join(
        f"{s.effect} {s.delta_elpd:.1f} ± {s.delta_elpd_se:.1f}"
        + (" (outgained)" if keep.earns_keep(s.delta_elpd, s.delta_elpd_se, s.before.rmse_arcsec, s.after.rmse_arcsec) else "")
        for s in d.rejected) or "—"
    return {
        "case": entry.name, "bench": entry.bench, "truth": _short(case.truth) or "nothing",
        "expected": ", ".join(entry.expected) or "nothing",
        "found": ", ".join(dict.fromkeys(added)) or "nothing",
        "rmse": f"{d.base.rmse_arcsec:.2f} → {d.final.rmse_arcsec:.2f}", "noise": f"{d.noise_arcsec:.2f}",
        "unexplained": ("true: " + d.unexplained_description[:90] + ("…" if len(d.unexplained_description) > 90 else ""))
        if d.unexplained else "false",
        "elpd": steps, "rejected": rejected, "ok": "yes" if as_expected else "**no**", "seconds": f"{seconds:.0f}",
        "criteria": sorted({s.comparison.criterion for s in d.steps + d.rejected}),
    }


COLUMNS = [("case", "undeclared effect"), ("found", "found (added)"), ("ok", "as expected"),
           ("rmse", "RMSE base → final (″)"), ("noise", "noise estimate (″)"), ("unexplained", "unexplained"),
           ("elpd", "ΔELPD ± SE per step"), ("rejected", "tried, not kept (ΔELPD ± SE)"), ("seconds", "wall (s)")]


#: the README's shorter table
README_COLUMNS = [c for c in COLUMNS if c[0] not in ("rejected", "seconds")]


def table(rows: list, columns=COLUMNS) -> str:
    lines = ["| " + " | ".join(h for _, h in columns) + " |", "| " + " | ".join("---" for _ in columns) + " |"]
    lines += ["| " + " | ".join(r[k].replace("|", "\\|") for k, _ in columns) + " |" for r in rows]
    return "\n".join(lines)


def page(rows: list, total_s: float, options: DiagnoseOptions) -> str:
    n_ok = sum(r["ok"] == "yes" for r in rows)
    criteria = sorted({c for r in rows for c in r["criteria"]})
    lines = [
        "# The undeclared-effect zoo (SYNTHETIC)",
        "",
        f"Produced by `.venv/bin/python scripts/diagnose_zoo.py` on {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC "
        f"({os.cpu_count()} logical CPUs, 1-min load average {os.getloadavg()[0]:.1f} at the end; "
        f"{total_s / 60:.1f} min for {len(rows)} diagnoses, each in a process of its own with the persistent compilation "
        "cache: a first run on a machine spends most of its time compiling).",
        "",
        "Every campaign is SYNTHETIC: simulated by the virtual bench from the bench file named below (under "
        "`tests/benches/`), with one or two effects switched on there — or added to the readings — and written "
        "without naming them, so `diagnose` sees only the data. The cases, their parameters and seeds are those of "
        "`tests/test_diagnose.py`, `tests/test_diagnose_friction.py` and `tests/test_diagnose_temperature.py` (first "
        "seed; the friction-only temperature case is the zoo's own). "
        f"Settings: `DiagnoseOptions()` (signature α {options.alpha:g}, up to {options.candidates_per_step} significant "
        f"signatures refitted per step and the one that earns the most kept, when ΔELPD > "
        f"{options.min_delta_elpd:g} and > {options.se_factor:g} SE (when none does at the base model's step, the next "
        f"ones, up to {options.max_candidates_first_step} refits there) — the others are listed as tried, *outgained* where "
        f"they earned their keep too; {options.loo_draws} Laplace draws for PSIS-LOO, "
        f"{options.n_starts} MAP starts). ΔELPD ± SE of each step added (criteria used: {', '.join(criteria) or 'none'}; "
        "SE from contiguous blocks of each run). The noise estimate is the measurement noise of the final fit's "
        "residuals (short-lag variogram, floored by the encoder). "
        f"**{n_ok} of {len(rows)} cases as expected** (the effects expected are added, nothing else except an "
        "effect entangled with the truth, and `unexplained` is what it should be).",
        "",
        table(rows),
        "",
        "What was switched on in each case (the bench's `[truth]` parameters, units in their names):",
        "",
    ]
    lines += [f"- **{r['case']}** (`{r['bench']}`; expected: {r['expected']}): {r['truth']}" for r in rows]
    return "\n".join(lines) + "\n"


def one(entry: Entry, options: DiagnoseOptions) -> dict:
    """The table row of one case (run in a child process)."""
    with tempfile.TemporaryDirectory() as folder:
        t0 = time.perf_counter()
        case = entry.build(Path(folder))
        say = lambda text: print(f"[{entry.name}] {text}", file=sys.stderr, flush=True)  # noqa: E731
        d = diagnose(case.campaign, options, seed=case.seed, progress=say)
        return row(entry, case, d, time.perf_counter() - t0)


def readme_with(readme: str, block: str) -> str | None:
    """``readme`` with the text between the zoo markers replaced by ``block``; None when the
    markers are not both there (in order)."""
    i, j = readme.find(BEGIN), readme.find(END)
    if i < 0 or j < i:
        return None
    return readme[:i + len(BEGIN)] + "\n" + block.rstrip("\n") + "\n" + readme[j:]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "diagnose" / "zoo.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")
    ap.add_argument("--no-readme", action="store_true", help="write the docs page only")
    ap.add_argument("--only", nargs="+", default=None, metavar="WORD",
                    help="cases whose name contains one of these words")
    ap.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    enable_compilation_cache()
    entries = ZOO if args.child is not None else [e for e in ZOO if args.only is None or any(w in e.name for w in args.only)]
    if not entries:
        print(f"--only {' '.join(args.only)}: no case matches; cases: {', '.join(e.name for e in ZOO)}", file=sys.stderr)
        return 2
    options = DiagnoseOptions()
    if args.child is not None:
        print(json.dumps(one(entries[args.child], options)))
        return 0
    rows, t_start = [], time.perf_counter()
    for entry in entries:
        # each case in a process of its own (the compiled programs come from the disk cache): one long
        # process running every case ran out of memory for new compiled code (LLVM "Cannot allocate
        # memory") twice, on the 13th case
        out = subprocess.run([sys.executable, __file__, "--child", str(ZOO.index(entry))], stdout=subprocess.PIPE,
                             text=True, check=True)
        rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
        print(f"[{entry.name}] found {rows[-1]['found']}, RMSE {rows[-1]['rmse']}″, unexplained "
              f"{rows[-1]['unexplained'][:5]}, as expected: {rows[-1]['ok']}", file=sys.stderr, flush=True)
        partial = args.output.with_suffix(".partial.md")  # what is done so far, if the run is cut short
        partial.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(page(rows, time.perf_counter() - t_start, options))
    text = page(rows, time.perf_counter() - t_start, options)
    args.output.write_text(text)
    partial.unlink()
    print(text)
    if not args.no_readme:
        n_ok = sum(r["ok"] == "yes" for r in rows)
        updated = readme_with(args.readme.read_text(), table(rows, README_COLUMNS) + (
            f"\n\n{n_ok} of {len(rows)} SYNTHETIC cases as expected (ΔELPD ± SE of each step added; RMSE and noise "
            "estimate in arcsec). What was switched on, the settings, the steps tried and not kept, and wall times: "
            "[`docs/diagnose/zoo.md`](docs/diagnose/zoo.md), made by `.venv/bin/python scripts/diagnose_zoo.py`.\n"))
        if updated is None:
            print(f"{args.readme}: no {BEGIN} … {END} markers; only {args.output} written", file=sys.stderr)
        else:
            args.readme.write_text(updated)
    return 0


if __name__ == "__main__":
    sys.exit(main())
