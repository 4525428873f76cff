"""The main job on the bundled data (``make run``): catalog metrics of the bundled SYNTHETIC
campaigns, MAP fits with the loop split into its components, and the same for a measured
cycloidal loop from ../shared/data when that folder is present.

Writes OUT/metrics-*.json and OUT/figures/*.png; prints the tables.
"""

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import paper_tables

import torsionfit
from measured_validation import EFFECTS as MEASURED_EFFECTS
from torsionfit.fit import NoiseOptions, build_problem, fit_map
from torsionfit.fit._misfit import widen_for_misfit
from torsionfit.fit._noise_classes import refit_with_class_noise
from torsionfit.io import decimate, load_campaign
from torsionfit.metrics import campaign_metrics, format_metrics_table
from torsionfit.model import model_with_effects
from torsionfit.report import FitOptions
from torsionfit.plots import component_draws, plot_loop_components
from torsionfit.units import from_si

ROOT = Path(__file__).resolve().parents[1]
MEASURED = ROOT / "examples" / "cycloidal-jv" / "baseline-pccf-initial-pos1.toml"
#: parameter draws behind a figure's band
BAND_DRAWS = 200
#: the measured loop's noise as the validation fits it (scripts/measured_validation.py): iid, a
#: level per cycle class (play ramps, stiffness ramps), the posterior widened for the misfit the
#: residuals keep, so that the figure's band is the validated interval's width
MEASURED_NOISE = NoiseOptions(ar1=False, cycle_class_noise=True)


def fit_and_plot(campaign, effects, figure, source, run_index=0, seed=0, noise=None):
    """MAP fit of the campaign's hysteresis runs with ``effects`` switched on; plot one run with
    the 95 % band of Laplace draws around the MAP (``seed`` draws them). ``noise``: the fit's
    noise options (None: the default); with a level per cycle class the levels are read at the
    MAP and the fit repeated, and the posterior is widened for misfit, as ``fit_campaign`` does."""
    hyst = replace(campaign, runs=campaign.hysteresis_runs)
    model = model_with_effects([r.kind for r in hyst.runs], effects, hyst.reducer.rated_torque_Nm,
                               free_friction_start=True)
    t0 = time.perf_counter()
    steps = FitOptions().map_steps  # fit_campaign's LM budget
    problem = build_problem(hyst, model, noise or NoiseOptions())
    budget = {"max_steps": steps, "polish_steps": steps}
    result = fit_map(problem, [r.name for r in hyst.runs], n_starts=3, **budget)
    if noise is not None and noise.cycle_class_noise:
        with torsionfit.float64():  # the classes' residuals and the misfit ratio in the fit's precision
            problem, result = refit_with_class_noise(problem, result, seed=seed, **budget)
            problem, result = widen_for_misfit(problem, result)
    elapsed = time.perf_counter() - t0
    with torsionfit.float64():  # the model evaluated in the fit's precision
        comps = result.components()
        drive = result.problem.corrected_inputs(result.u)[run_index].torque_Nm
        # the band: components of draws from the MAP's Laplace approximation (seeded), every sample
        u_draws = np.random.default_rng(seed).multivariate_normal(result.u, result.cov, size=BAND_DRAWS, method="eigh")
        draws = component_draws(result.problem, u_draws, run_index, np.arange(len(hyst.runs[run_index])))
    plot_loop_components(hyst.runs[run_index], comps[run_index], source=source, drive_torque_Nm=drive, path=figure,
                         draws=draws, draws_label=f"95 % of {BAND_DRAWS} Laplace draws")
    v = result.values
    stiffness = f"stiffness {from_si(float(v['stiffness']), 'stiffness', 'Nm/arcmin'):.4g} N·m/arcmin, " if "stiffness" in v else ""
    print(f"  MAP ({elapsed:.1f} s, {result.message}): {stiffness}"
          f"friction {float(v['friction_torque']):.4g} N·m, gap {from_si(float(v['gap']), 'angle', 'arcmin'):.4g} arcmin")
    print(f"  figure: {figure}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=Path("out"))
    args = parser.parse_args(argv)
    figures = args.output / "figures"
    figures.mkdir(parents=True, exist_ok=True)

    for name in ("paper-small", "paper-large"):
        campaign = load_campaign(ROOT / "data" / name / "campaign.toml")
        result = campaign_metrics(campaign)
        (args.output / f"metrics-{name}.json").write_text(json.dumps(result, indent=2))
        print(f"== {name}: {campaign.notes}")
        print(format_metrics_table(result))

    print("== Tables 4 and 6 of the paper, evaluated the paper's way on the SYNTHETIC campaigns")
    paper_tables.main()

    campaign = load_campaign(ROOT / "data" / "paper-large" / "campaign.toml")
    print("== paper-large hysteresis runs, base model + creep (SYNTHETIC)")
    fit_and_plot(campaign, {"rate_dependence": True}, figures / "paper-large-loop-components.png",
                 "SYNTHETIC data (data/paper-large, calibrated to Cheng et al. 2023)", run_index=2)

    if MEASURED.is_file() and (ROOT.parent / "shared" / "data").is_dir():
        # the whole bench file (play ramps + stiffness ramps) as one run, block means of 16 of
        # the ~400 Hz samples, with the physics real loops need (see scripts/measured_validation.py)
        measured = decimate(load_campaign(MEASURED), 16)
        print(f"== measured: {measured.notes}")
        # the baseline design's model of the validation (scripts/measured_validation.py EFFECTS)
        # with one held crossing in place of the gap crossed in held steps: the relays' 28 shares
        # from this function's prior starts took 579 s here (62.9 s with the held gap); the
        # validation fits them from the held gap's optimum (torsionfit.report.fit_campaign)
        effects = {**{k: v for k, v in MEASURED_EFFECTS.items() if k != "gap_relays"}, "gap_hold": {"centred": False}}
        print("  model: the validation's baseline model with one held gap crossing in place of its held steps")
        fit_and_plot(measured, effects, figures / "cycloidal-baseline-initial-pos1-components.png",
                     "measured, JelmerV/Anti-Backlash-Cycloidal-Actuator (CC BY-SA 4.0), "
                     "the validation's baseline-design model, one held gap crossing", noise=MEASURED_NOISE)
    else:
        print("== measured loops skipped: ../shared/data is absent")
    return 0


if __name__ == "__main__":
    sys.exit(main())
