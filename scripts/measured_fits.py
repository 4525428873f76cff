"""Fit the large stiffness ramps (test_nr 100–102) of the measured baseline (initial) cycloidal
loops with the *base* model — REAL data from ../shared/data (JelmerV/Anti-Backlash-Cycloidal-
Actuator, CC BY-SA 4.0) — and print a Markdown table of stiffness, lost motion, backlash, gap and
friction with 95 % HDIs (posterior by emcee), next to the data-only metrics. Writes
OUT/<unit>/fit.json and figures, and OUT/measured-fits.md. The base model's view of these loops,
kept for comparison; the validation of the model real loops need is
``scripts/measured_validation.py``.

    .venv/bin/python scripts/measured_fits.py -o docs/measured [--sampler laplace]
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

import torsionfit  # noqa: F401
from torsionfit.io import load_campaign
from torsionfit.metrics import campaign_metrics
from torsionfit.plots import write_fit_figures
from torsionfit.report import FitOptions, fit_campaign, write_fit

from measured_validation import manifest

ROOT = Path(__file__).resolve().parents[1]
UNITS = ["baseline-pccf-initial-pos1", "baseline-pccf-initial-pos5", "baseline-pccf-initial-pos6"]
SHOW = [("stiffness_rated", "Nm/arcmin"), ("stiffness_elastic", "Nm/arcmin"), ("lost_motion", "arcmin"),
        ("backlash", "arcmin"), ("geometric_gap", "arcmin"), ("friction_torque", "Nm")]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=Path("out/measured"))
    parser.add_argument("--sampler", choices=("emcee", "laplace"), default="emcee")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-steps", type=int, default=60_000)
    parser.add_argument("--decimate", type=int, default=8, help="block means of N samples (the loops are sampled at ~400 Hz)")
    args = parser.parse_args(argv)
    if not (ROOT.parent / "shared" / "data" / "cycloidal-jv").is_dir():
        print("../shared/data/cycloidal-jv is absent: nothing to fit")
        return 0
    rows = []
    for unit in UNITS:
        with tempfile.TemporaryDirectory() as folder:  # the example manifest, stiffness ramps only
            campaign = load_campaign(manifest(unit, [100, 101, 102], Path(folder)))
        fit = fit_campaign(campaign, FitOptions(sampler=args.sampler, progress=False, decimate=args.decimate, max_steps=args.max_steps), seed=args.seed)
        doc = write_fit(fit, args.output / unit)
        write_fit_figures(fit, args.output / unit / "figures")
        data = campaign_metrics(campaign)["runs"][0]["metrics"]
        rows.append((unit, doc, data))
        print(f"{unit}: {doc['diagnostics']}", file=sys.stderr)
    lines = [
        "Measured loops (REAL data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), base model, "
        f"posterior by {args.sampler}, block means of {args.decimate} samples; rated torque 20 N·m assumed. Model value with 95 % HDI; data-only value in brackets.",
        "",
        "| unit | " + " | ".join(f"{n} ({u})" for n, u in SHOW) + " | RMSE (arcsec) | converged |",
        "| --- | " + " | ".join("---" for _ in SHOW) + " | --- | --- |",
    ]
    for unit, doc, data in rows:
        cells = []
        for name, _ in SHOW:
            e = doc["metrics"][name]
            lo, hi = e["hdi95"]
            ref = f" [{data[name]['value']:.3g}]" if name in data else ""
            cells.append(f"{e['mean']:.3g} ({lo:.3g}–{hi:.3g}){ref}")
        rmse = ", ".join(f"{v['value']:.0f}" for v in doc["rmse"].values())
        lines.append(f"| {unit.replace('baseline-pccf-', '')} | " + " | ".join(cells) + f" | {rmse} | {doc['diagnostics']['converged']} |")
    text = "\n".join(lines)
    args.output.mkdir(parents=True, exist_ok=True)
    (args.output / "measured-fits.md").write_text(text + "\n")
    (args.output / "measured-fits.json").write_text(json.dumps({u: d["metrics"] for u, d, _ in rows}, indent=2))
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
