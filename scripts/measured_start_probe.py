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
MOVED = ("friction_torque", "gap_hold_torque")
SHOWN = ("friction_torque", "friction_load_coefficient", "breakaway_spread", "gap_hold_torque")


def readings_Nm(campaign) -> tuple[float, float]:
    """(smallest, largest) cycles' half-width in torque at their mid angle (N·m), medians over runs."""
    from torsionfit.fit._prior import cycle_friction_Nm
    from torsionfit.metrics._hysteresis import grouped_cycles

    classes = grouped_cycles(campaign.hysteresis_runs)
    return (float(np.median([cycle_friction_Nm(c.smallest) for c in classes])),
            float(np.median([cycle_friction_Nm(c.largest) for c in classes])))


def probe(unit: str) -> dict:
    import torsionfit
    from torsionfit.fit import fit_map
    from torsionfit.io import load_campaign
    from torsionfit.report import prepare_fit
    from torsionfit.report._pipeline import _nested_starts

    folder = Path(tempfile.mkdtemp())
    path = mv._data_path(unit)
    ramps = mv.test_numbers(path)
    train = load_campaign(mv.manifest(unit, [r for r in ramps if r != max(ramps)], folder))
    args = mv.parse_args([])
    options = mv.fit_options(args)
    small, large = readings_Nm(train)
    with torsionfit.float64():
        campaign, _, problem = prepare_fit(train, options)
        names = [r.name for r in campaign.runs]
        steps = dict(max_steps=options.map_steps, polish_steps=options.map_steps)
        fitted = fit_map(problem, names, n_starts=options.n_starts, seed=args.seed,
                         warm_starts=_nested_starts(campaign, options, problem, args.seed), **steps)
        order = problem.names(tuple(names))[:problem.n_nonlinear]
        start = np.array(fitted.u, float)
        start[order.index("friction_torque")] = math.log(small)
        start[order.index("gap_hold_torque")] = math.log(max(large - small, small))
        moved = fit_map(problem, names, n_starts=0, seed=args.seed, warm_starts=start[None, :], **steps)

    def summary(result):
        values = problem.physics_values(result.u[:problem.n_nonlinear])
        return {"log_posterior": float(result.log_density), "converged": bool(result.converged),
                **{k: float(np.ravel(values[k])[0]) for k in SHOWN}}

    return {"unit": unit, "play_ramps_Nm": small, "largest_cycles_Nm": large,
            "validation_start": summary(fitted), "moved_start": summary(moved)}


def table(rows: list[dict]) -> str:
    lines = [f"Friction level: the validation's MAP against the MAP from a start with the friction level at the play "
             f"ramps' reading and the hold at what the largest cycles add ({mv.SOURCE}; model: base + "
             f"{json.dumps(mv.EFFECTS)}, the validation's options, the file without its last large ramp). "
             "Readings: half the cycles' width in torque at their mid angle. T_f: the friction elements' median "
             "break-away, μ its growth with the load, s the break-away spread (log-sd), T_h the gap's hold.", "",
             "| unit | play ramps (N·m) | largest cycles (N·m) | MAP: T_f / μ / s / T_h | log posterior | "
             "moved start → T_f / μ / s / T_h | log posterior | Δ |", "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for r in rows:
        a, b = r["validation_start"], r["moved_start"]

        def params(x):
            return " / ".join(f"{x[k]:.3g}" for k in SHOWN)

        lines.append(f"| {r['unit']} | {r['play_ramps_Nm']:.2f} | {r['largest_cycles_Nm']:.2f} | {params(a)} | "
                     f"{a['log_posterior']:.1f} | {params(b)} | {b['log_posterior']:.1f} | "
                     f"{b['log_posterior'] - a['log_posterior']:+.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, required=True)
    parser.add_argument("--units", nargs="*", default=DEFAULT_UNITS)
    parser.add_argument("--jobs", type=int, default=1)
    args = parser.parse_args(argv)
    if not mv.DATA.is_dir():
        print(f"measured_start_probe: no measured data at {mv.DATA} (../shared/data next to the repository)")
        return 1
    if args.jobs > 1:
        import multiprocessing
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs, mp_context=multiprocessing.get_context("spawn")) as pool:
            rows = list(pool.map(probe, args.units))
    else:
        rows = [probe(u) for u in args.units]
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "start-probe.json").write_text(json.dumps({"source": mv.SOURCE, "units": rows}, indent=1))
    text = table(rows)
    (args.output / "start-probe.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
