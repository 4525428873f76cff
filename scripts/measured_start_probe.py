"""Is a measured loop's fitted friction level the likelihood's choice or its starts'? — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read where it lies, never copied.

On the preloaded split units the validation's fit puts the friction's median break-away at
4–9 N·m while the ±4 N·m play ramps are 1–1.5 N·m wide in torque (half-width at their mid
angle), and draws the play ramps 30–50 % too wide. For each unit this script fits the
validation's training part (the file without its last large ramp, the validation's model and
options) as ``fit_campaign`` does its MAP (the prior's starts and the nested start), then again
from that MAP with the friction level moved to the play ramps' reading and the gap's hold to
what the largest cycles' reading adds to it (the rest as at the MAP), and writes both optima:
the same log posterior means the data choose the level, a higher one from the moved start a
better optimum the validation's starts miss.

    .venv/bin/python scripts/measured_start_probe.py -o docs/measured/start-probe [--units ...] [--jobs 2]
"""

import argparse
import functools
import json
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import measured_validation as mv  # noqa: E402  (the validation's model, options and data split)

#: the preloaded units: play ramps far narrower in torque than the large cycles
DEFAULT_UNITS = [f"split-pccf-preload{p}-pos{q}" for p in (2, 3) for q in (1, 5, 6)]
SHOWN = ("friction_torque", "friction_load_coefficient", "friction_load_lag_time", "friction_load_memory", "breakaway_spread",
         "gap_hold_torque")
#: the default move: the friction level to the play ramps' reading, the hold to what the largest cycles add
READINGS_MOVE = "the friction level at the play ramps' reading and the hold at what the largest cycles add"
SYMBOLS = {"friction_torque": "T_f", "friction_load_coefficient": "μ", "friction_load_lag_time": "T_L",
           "friction_load_memory": "m", "breakaway_spread": "s", "gap_hold_torque": "T_h"}


def play_ramps(runs, angles) -> dict:
    """The smallest cycles' play (deg) and half-width in torque at their mid angle (N·m) of
    ``angles`` (rad, one per run; the data's or a model's), medians over the runs."""
    from torsionfit.fit._prior import cycle_friction_Nm
    from torsionfit.metrics._hysteresis import cycle_classes, play_of

    plays, widths = [], []
    for run, angle in zip(runs, angles):
        small = cycle_classes(run.time_s, run.torque_Nm, np.asarray(angle), name=run.name).smallest
        plays.append(math.degrees(play_of(small)))
        widths.append(cycle_friction_Nm(small))
    return {"play_deg": float(np.median(plays)), "half_width_Nm": float(np.median(widths))}


def probe(unit: str, move: dict | None = None, effects: dict | None = None) -> dict:
    """Both optima of ``unit``'s training part; ``move``: the moved start's physics values (SI),
    None for the readings' move."""
    import torsionfit
    from torsionfit.fit import fit_map
    from torsionfit.fit._prior import cycle_friction_readings_Nm
    from torsionfit.io import load_campaign
    from torsionfit.report import prepare_fit
    from torsionfit.report._pipeline import _nested_starts, hold_mode_values, moved_start

    folder = Path(tempfile.mkdtemp())
    path = mv._data_path(unit)
    ramps = mv.test_numbers(path)
    train = load_campaign(mv.manifest(unit, [r for r in ramps if r != max(ramps)], folder))
    if effects is None:  # the validation's model of this unit's design
        effects = mv.effects_for(unit, mv.parse_args([]))
    args = mv.parse_args(["--effects", json.dumps(effects)])
    options = mv.fit_options(args)
    small, large = cycle_friction_readings_Nm(train)
    if move is None:
        move = hold_mode_values(small, large)
    with torsionfit.float64():
        campaign, _, problem = prepare_fit(train, options)
        names = [r.name for r in campaign.runs]
        steps = dict(max_steps=options.map_steps, polish_steps=options.map_steps)
        fitted = fit_map(problem, names, n_starts=options.n_starts, seed=args.seed,
                         warm_starts=_nested_starts(campaign, options, problem, args.seed), **steps)
        start = moved_start(problem, fitted.u, move)
        moved = fit_map(problem, names, n_starts=0, seed=args.seed, warm_starts=start[None, :], **steps)
        runs = campaign.hysteresis_runs

        def summary(result):
            values = problem.physics_values(result.u[:problem.n_nonlinear])
            totals = [c["total"] for c, r in zip(result.components(), campaign.runs) if r.kind == "hysteresis"]
            return {"log_posterior": float(result.log_density), "converged": bool(result.converged),
                    **{k: float(np.ravel(values[k])[0]) for k in SHOWN if k in values},
                    "play_ramps": play_ramps(runs, totals)}

        return {"unit": unit, "effects": effects, "play_ramps_Nm": small, "largest_cycles_Nm": large, "move": move,
                "data_play_ramps": play_ramps(runs, [r.angle_rad for r in runs]),
                "validation_start": summary(fitted), "moved_start": summary(moved)}


def table(rows: list[dict], effects: dict, move_text: str) -> str:
    """The probe's table; the lag and the play ramps' columns where the rows have them."""
    shown = [k for k in SHOWN if any(k in r["validation_start"] for r in rows)]
    ramps = any("data_play_ramps" in r for r in rows)
    symbols = " / ".join(SYMBOLS[k] for k in shown)
    lines = [f"Friction level: the validation's MAP against the MAP from a start with {move_text} ({mv.SOURCE}; "
             f"model: {mv.model_text(rows, effects)}, the validation's options, the file without its last large ramp). "
             "Readings: half the cycles' width in torque at their mid angle. T_f: the friction elements' median "
             "break-away, μ its growth with the load, "
             + ("T_L the lag of the load it follows (s), " if "friction_load_lag_time" in shown else "")
             + ("m the share of its peak load it keeps as the torque travels back, " if "friction_load_memory" in shown else "")
             + "s the break-away spread (log-sd), T_h the gap's hold."
             + (" Play ramps: their play (deg) and half-width in torque (N·m), the data's and each optimum's." if ramps else ""),
             "",
             f"| unit | play ramps (N·m) | largest cycles (N·m) | MAP: {symbols} | log posterior | "
             f"moved start → {symbols} | log posterior | Δ |" + (" play ramps: data / MAP / moved |" if ramps else ""),
             "| --- " * (8 + ramps) + "|"]
    for r in rows:
        a, b = r["validation_start"], r["moved_start"]

        def params(x):
            return " / ".join(f"{x[k]:.3g}" for k in shown)

        def play(x):
            return f"{x['play_deg']:.3f}° {x['half_width_Nm']:.2f}"

        line = (f"| {r['unit']} | {r['play_ramps_Nm']:.2f} | {r['largest_cycles_Nm']:.2f} | {params(a)} | "
                f"{a['log_posterior']:.1f} | {params(b)} | {b['log_posterior']:.1f} | "
                f"{b['log_posterior'] - a['log_posterior']:+.1f} |")
        if ramps:
            line += f" {play(r['data_play_ramps'])} / {play(a['play_ramps'])} / {play(b['play_ramps'])} |"
        lines.append(line)
    return "\n".join(lines) + "\n"


def _move(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--move: expected NAME=VALUE (SI), got {text!r}") from None


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, required=True)
    parser.add_argument("--units", nargs="*", default=DEFAULT_UNITS)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--move", nargs="*", type=_move, metavar="NAME=VALUE",
                        help="the moved start's physics values in SI units (default: the readings' move)")
    parser.add_argument("--effects", type=json.loads, default=None,
                        help="model effects as JSON (default: the validation's model of each unit's design)")
    parser.add_argument("--table-only", action="store_true", help="rewrite the table from the folder's start-probe.json")
    args = parser.parse_args(argv)
    move = dict(args.move) if args.move else None
    move_text = ", ".join(f"{k} = {v:g}" for k, v in move.items()) if move else READINGS_MOVE
    if args.table_only:
        doc = json.loads((args.output / "start-probe.json").read_text())
        text = table(doc["units"], doc.get("effects") or mv.EFFECTS, doc.get("move", READINGS_MOVE))
        (args.output / "start-probe.md").write_text(text)
        print(text)
        return 0
    if not mv.DATA.is_dir():
        print(f"measured_start_probe: no measured data at {mv.DATA} (../shared/data next to the repository)")
        return 1
    work = functools.partial(probe, move=move, effects=args.effects)
    if args.jobs > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            rows = list(pool.map(work, args.units))
    else:
        rows = [work(u) for u in args.units]
    args.output.mkdir(parents=True, exist_ok=True)
    doc = {"source": mv.SOURCE, "effects": args.effects, "move": move_text, "units": rows}
    (args.output / "start-probe.json").write_text(json.dumps(doc, indent=1))
    text = table(rows, args.effects or mv.EFFECTS, move_text)
    (args.output / "start-probe.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
