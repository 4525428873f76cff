"""``torsionfit`` command line. Bad input → one line on stderr and exit code 2, never a traceback."""

import argparse
import json
import sys
from pathlib import Path

from ._errors import InputError

EXIT_INPUT_ERROR = 2


def _cmd_simulate(args) -> int:
    from .bench import load_bench, simulate
    from .io import write_campaign

    bench = load_bench(args.bench)
    sim = simulate(bench, seed=args.seed)
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
    if args.json:
        json.dump(result, sys.stdout, indent=2)
        print()
    else:
        if campaign.notes:
            print(campaign.notes)
        print(format_metrics_table(result))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="torsionfit",
        description="Torsional stiffness of gear reducers from test-bench data, with uncertainty.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    p = sub.add_parser("simulate", help="write a campaign (manifest + CSVs) from a virtual bench file")
    p.add_argument("bench", type=Path, help="bench file (TOML)")
    p.add_argument("-o", "--output", type=Path, required=True, help="output folder")
    p.add_argument("--seed", type=int, default=None, help="random seed (default: the bench file's)")
    p.set_defaults(func=_cmd_simulate)

    p = sub.add_parser("metrics", help="catalog metrics from the data alone (no model fit)")
    p.add_argument("campaign", type=Path, help="campaign manifest (TOML)")
    p.add_argument("--json", action="store_true", help="machine-readable JSON on stdout")
    p.add_argument("--lost-motion-pct", type=float, default=3.0, help="±x %% of rated torque for lost motion (default 3)")
    p.add_argument("--t1-Nm", type=float, default=None, help="catalog knee T1 (default 0.25·T_r)")
    p.add_argument("--t2-Nm", type=float, default=None, help="catalog knee T2 (default 0.75·T_r)")
    p.add_argument("--seed", type=int, default=None, help="unused: metrics are deterministic")
    p.set_defaults(func=_cmd_metrics)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except InputError as err:
        print(f"torsionfit {args.command}: error: {err}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except KeyboardInterrupt:
        print(f"torsionfit {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
