"""The acceptance example of the README, on SYNTHETIC units of ``examples/accept/line-bench.toml``:

1. one unit (bench seed 1) decided from its emcee posterior:
   ``torsionfit accept CAMPAIGN --spec examples/accept/line-spec.toml -o OUT/unit --with SPEED``;
2. a small line of five units — three nominal (seeds 1–3), one worn (gap 1.6 arcmin instead of
   1.0) and one marginal (gap 1.32 arcmin: backlash near its 75″ limit) — decided as a batch
   from the Laplace approximation (screening): ``torsionfit accept FOLDER ... --sampler laplace``.

The campaigns are written by the virtual bench to CAMPAIGNS (default out/accept-campaigns, not
kept in git) and labelled SYNTHETIC with what was changed; the decisions go to OUT (default
docs/accept). Prints what the commands print.
"""

import argparse
import dataclasses
import sys
from pathlib import Path

from torsionfit.bench import load_bench, simulate
from torsionfit.cli import main
from torsionfit.io import write_campaign
from torsionfit.units import to_si

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "examples" / "accept" / "line-bench.toml"
SPEC = ROOT / "examples" / "accept" / "line-spec.toml"
SPEED = "speed_dependence={viscous = false, compliance_order = 2}"
#: the line: unit name → (bench seed, gap in arcmin or None for the bench's own)
LINE = {"unit-01": (1, None), "unit-02": (2, None), "unit-03": (3, None), "unit-04-worn": (4, 1.6),
        "unit-05-marginal": (5, 1.32)}


def write_unit(bench, folder: Path, seed: int, gap_arcmin: float | None) -> Path:
    """Simulate one SYNTHETIC unit (with the gap changed if given) and write its campaign."""
    label = f"{bench.label}, seed {seed}"
    if gap_arcmin is not None:
        bench = dataclasses.replace(bench, truth={**bench.truth, "gap": to_si(gap_arcmin, "angle", "arcmin")})
        label += f", gap changed to {gap_arcmin:g} arcmin (scripts/accept_example.py)"
    return write_campaign(simulate(bench, seed=seed).campaign, folder, label=label)


def run(argv) -> int:
    code = main(argv)
    print(f"exit code {code}", flush=True)
    return code


def cli() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-o", "--output", type=Path, default=ROOT / "docs" / "accept")
    parser.add_argument("--campaigns", type=Path, default=ROOT / "out" / "accept-campaigns")
    args = parser.parse_args()
    bench = load_bench(BENCH)
    line = args.campaigns / "line"
    for name, (seed, gap) in LINE.items():
        write_unit(bench, line / name, seed, gap)
    print("$ torsionfit accept unit-01 --spec line-spec.toml (emcee)", flush=True)
    run(["accept", str(line / "unit-01" / "campaign.toml"), "--spec", str(SPEC), "-o", str(args.output / "unit"),
         "--with", SPEED, "--no-progress", "--seed", "0"])
    print("$ torsionfit accept line/ --spec line-spec.toml --sampler laplace", flush=True)
    run(["accept", str(line), "--spec", str(SPEC), "-o", str(args.output / "line"), "--with", SPEED,
         "--sampler", "laplace", "--seed", "0"])


if __name__ == "__main__":
    sys.exit(cli())
