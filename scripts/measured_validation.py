"""Validate the model on every measured cycloidal loop in ../shared/data — REAL data
(JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0), read where it lies, never copied.

For each file (one run: the small play ramps and the large stiffness ramps together):

1. fit the file **without its last large ramp** (model, :data:`EFFECTS`: base +
   ``load_dependent_friction`` with its level following the load through a first-order lag
   (``{lag = true}``) + ``distributed_friction`` + power-law ``stiffness_nonlinearity`` +
   ``asymmetry`` + ``gap_relays`` (the gap crossed in held steps about a centre of its own, its
   prior on the data's crossing centre) + ``play_torque_offset``; the preloaded split-pinwheel design's, :data:`DESIGN_EFFECTS`:
   the level remembering the peak load in place of the lag, the held gap centred on zero, and
   ``preload_stiffening``;
   ``--effects`` to fit every unit with one model;
   block means of ``--decimate`` samples; iid noise with a level per cycle class (the play
   ramps, the stiffness ramps: their ratio read at the MAP, ``--no-class-noise`` for one level)
   and the posterior widened for structure the residuals keep, drawn from a split normal along the Laplace approximation's axes
   (``--laplace-shape gaussian`` for the Gaussian, whose draws of these non-Gaussian posteriors
   land where the posterior has no mass), ``--ar1`` for the fit's default AR(1) noise — with its coefficient near 1
   on these files the AR(1) likelihood counts the model's slow misfit as noise and fits the
   increments rather than the level: held out it predicted worse than the iid fit on 14 of 21);
2. predict the **whole file** with the fitted physics (the friction state carried through from
   the first sample, driven by the denoised measured torque), at the fit's sample rate (block
   means: at the raw 400 Hz the denoised torque still chatters through zero, which a sharp gap
   turns into spurious crossings), and score the held-out ramp: RMSE, and the share of its
   samples inside the 90 % posterior-predictive interval (parameter draws + the fitted noise,
   its marginal sd; :data:`NOISE_REPEATS` noise draws per parameter draw);
3. data-only ``play`` and ``stiffness_loading`` of the file, and the same definitions applied
   to the model's noise-free prediction per draw (model value, 95 % HDI);
4. the specialist reference (``benchmarks/pi_reference.py``: Prandtl–Ishlinskii + tanh gap by
   NNLS) on the same file and split — fitted to the raw samples as it is designed, scored on
   the same block means as the model — and the RMSE ratio; beside it the same reference with
   play weights ≥ 0 (the physically admissible Prandtl–Ishlinskii model: any break-away density).

Per configuration (the three rotor positions averaged like the data's authors) ``play`` and
the loading compliance are compared with the authors' numbers, read from the data's README;
the head of OUTPUT/validation.md is the README's table (:func:`summary_table`: per configuration
the authors', the data's and the model's numbers, per position the held-out ratio and coverage).

    .venv/bin/python scripts/measured_validation.py -o docs/measured/validation [--units baseline-pccf-initial-pos1 ...]

``--units`` with ``--append`` re-fits those units and keeps the table's other rows.
``--hold-out-ramp 2`` holds out the large ramp before the last instead (the model and the
references fitted to the file before it): whether a file whose last ramp is predicted badly
(or well) is one whose earlier ramp is too — whether the held-out error is the file's.
"""

import argparse
import functools
import json
import re
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import torsionfit  # noqa: F401
from torsionfit import InputError
from torsionfit._provenance import NUMERICAL_PACKAGES, environment
from torsionfit.batch import executor
from torsionfit.fit import NoiseOptions, model_inputs
from torsionfit.fit._problem import cycle_amplitude_shape
from torsionfit.io import decimate, load_campaign
from torsionfit.metrics import cycle_classes, loading_compliance_cycles, loading_fit, play_of
from torsionfit.metrics._hysteresis import CLASS_METRICS
from torsionfit.report import FitOptions, fit_campaign, metrics_against_data
from torsionfit.units import ANGLE_UNITS

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "data" / "cycloidal-jv"
EXAMPLES = ROOT / "examples" / "cycloidal-jv"
sys.path[:0] = [str(ROOT / "benchmarks"), str(ROOT / "scripts")]  # the reference fits; measured_metrics.py
ARCSEC = ANGLE_UNITS["arcsec"]
DEG = ANGLE_UNITS["deg"]
#: the held gap's band centred on a torque of its own, its prior on the data's crossing centre: on
#: the baseline loops the held-out RMSE falls on four of six (runin-pos1 from above the reference
#: to 0.79 of it) and rises on the two whose play ramps cross about another centre than their
#: large ramps (docs/validation.md); on the split design it rose on four of six: not there. The
#: play ramps' own torque zero places those two: with it the held-out RMSE falls on all six
#: baseline loops (initial-pos6 618″ → 386″); on the split design it rose on six of 15 and on
#: average (preload1-pos1 above the reference): not there either. The gap crossed in held steps
#: about that centre (``gap_relays``, whose relays include the held gap) in place of the one held
#: crossing: in sample lower on five of the six baseline loops, 90 % coverage 85–93 % on all six
#: (98 % on initial-pos6 before), and the authors' play and compliance of the run-in unit inside
#: the model's intervals (docs/validation.md)
EFFECTS = {"load_dependent_friction": {"lag": True}, "distributed_friction": True, "stiffness_nonlinearity": "power_law",
           "asymmetry": True, "gap_relays": True, "play_torque_offset": True}
#: the model of a design whose physics is declared beyond EFFECTS (the unit name's prefix →
#: its effects): the split-pinwheel design is preloaded (anti-backlash), so below a lift-off
#: torque a second, preloaded path stiffens it, and its small play ramps slide at a friction
#: level their own amplitude sets (the level remembers the peak load)
DESIGN_EFFECTS = {"split-pccf": {"load_dependent_friction": {"memory": True}, "distributed_friction": True,
                                 "stiffness_nonlinearity": "power_law", "asymmetry": True, "gap_hold": True,
                                 "preload_stiffening": True}}
#: the share of the held-out ramp a calibrated 90 % interval should cover (the done criterion)
COVERAGE_BAND = (0.80, 0.95)
#: noise draws per posterior draw for the 90 % predictive interval
NOISE_REPEATS = 20
SOURCE = "REAL measured data: JelmerV/Anti-Backlash-Cycloidal-Actuator, CC BY-SA 4.0"


def test_numbers(path: Path) -> list[int]:
    """The ``test_nr`` values of a measured file, in file order."""
    from pi_reference import read_loop

    return [int(v) for v in dict.fromkeys(read_loop(path)["test_nr"].tolist())]


def measured_files(data: Path | None = None) -> dict[str, Path]:
    """Every measured loop in the data folder (``DATA`` when None), by unit name
    ``<design>-<state>-<position>``: ``<design>/<state>-<position>.csv.gz`` (or ``.csv``), the
    layout of the data's README. A file of a configuration without an example manifest is
    validated too, read by :func:`generated_manifest_text`."""
    return {f"{path.parent.name}-{_stem(path)}": path for path in _data_files(data) if _stem(path).count("-") == 1}


def _data_files(data: Path | None = None) -> list[Path]:
    return sorted(p for p in (DATA if data is None else data).glob("*/*") if p.name.endswith((".csv", ".csv.gz")))


def _stem(path: Path) -> str:
    return path.name.removesuffix(".gz").removesuffix(".csv")


def files_out_of_layout(data: Path | None = None) -> list[Path]:
    """Measured files in the data folder not named ``<state>-<position>``: not validated (the
    run says so, naming them)."""
    return [p for p in _data_files(data) if _stem(p).count("-") != 1]


def not_validated(unit: str) -> str | None:
    """Why ``unit``'s file cannot be validated, in one line naming it (None: it can): the split
    reads the ``test_nr`` column and needs two large ramps (test_nr ≥ 100), the last to hold
    out and one to fit the large cycles on; the whole file must read (the manifest reader's
    checks: a reversed angle stops there)."""
    path = _data_path(unit)
    try:
        large = [r for r in test_numbers(path) if r >= 100]
    except ValueError as err:  # csv header without one of the README's columns
        return f"{path}: {err}; expected the data README's columns TIME, POSITION, TORQUE and test_nr"
    if len(large) < 2:
        return (f"{path}: {len(large)} large ramp(s) (test_nr ≥ 100), expected at least 2: one to fit, the last to "
                f"hold out")
    # the reader's own checks (columns, units, an angle that falls as the torque rises): a file
    # that stops there is named here, and the other units are validated
    with tempfile.TemporaryDirectory() as folder:
        try:
            run = load_campaign(manifest(unit, None, Path(folder))).runs[0]
            # the play and the loading slope are read off loops: ramps that form none give neither to compare
            classes = cycle_classes(run.time_s, run.torque_Nm, run.angle_rad, name=unit)
        except InputError as err:
            return str(err)
    why = classes.no_play_reason(unit) or classes.no_loading_reason(unit)
    return None if why is None else f"{path}: {why}"


def select_units(names: list[str] | None) -> list[str]:
    """The units named (every example manifest and every measured file found in the data folder
    when None); a design's name (``split-pccf``) stands for each of its units. SystemExit naming
    a name that matches none."""
    every = sorted({p.stem for p in EXAMPLES.glob("*.toml")} | set(measured_files()))
    if not names:
        return every
    out = []
    for name in names:
        found = [u for u in every if u == name or u.startswith(name + "-")]
        if not found:
            raise SystemExit(f"--units: {name!r} is no example manifest, measured file nor design of one ({', '.join(every)})")
        out += [u for u in found if u not in out]
    return out


def generated_manifest_text(unit: str, path: Path) -> str:
    """The manifest of ``unit``'s measured file ``path`` when it has no example manifest: the data
    README's format as scripts/measured_metrics.py reads it (TIME s, TORQUE N·m from motor
    current, POSITION output revolutions, encoder steps of 2^-16 rev — the reader checks the
    declared step against the column's own), with the examples' assumed rating of 20 N·m, which
    the fit's priors read, and the run's peak read off its cycles (``peak_torque_Nm = "data"``:
    a unit of a weaker material whose stiffness ramps saturate below the assumed rating is read,
    not stopped for not reaching it)."""
    from measured_metrics import CREDIT, MANIFEST

    design, stem = unit.rsplit("-", 2)[0], _stem(path)
    text = MANIFEST.format(folder=design, stem=stem, credit=CREDIT, file=json.dumps(path.as_posix()))
    text = text.replace('kind = "hysteresis"\n', 'kind = "hysteresis"\npeak_torque_Nm = "data"\n', 1)
    return text.replace("[reducer]\n", "[reducer]\nrated_torque_Nm = 20.0  # assumed, as in the example manifests\n", 1)


def _manifest_text(unit: str) -> str:
    """The example manifest of ``unit`` with the data path resolved on this machine, else the
    generated one of its measured file."""
    example = EXAMPLES / f"{unit}.toml"
    if example.is_file():
        return example.read_text().replace('file = "../../../shared/', f'file = "{ROOT.parent}/shared/')
    files = measured_files()
    if unit not in files:
        raise SystemExit(f"{unit}: no example manifest ({example}) and no measured file under {DATA}")
    return generated_manifest_text(unit, files[unit])


def manifest(unit: str, select: list[int] | None, folder: Path, condition: list[int] | None = None) -> Path:
    """A manifest for ``unit`` reading the whole file (``select`` None) or the given ramps:
    the example manifest with its ``[runs.select]`` replaced, written to ``folder``; the ramps
    ``condition`` conditioning rows (``[runs.condition]``)."""
    text = _manifest_text(unit)
    text = re.sub(r"\n\[runs\.select\].*\Z", "\n", text, flags=re.S)  # the last table of the examples
    if select is not None:
        text = text.rstrip() + f"\n\n[runs.select]\ntest_nr = {select}\n"
    if condition:
        text = text.rstrip() + f"\n\n[runs.condition]\ntest_nr = {condition}\n"
    out = folder / f"{unit}-{'all' if select is None else 'train'}.toml"
    out.write_text(text)
    return out


def draw_values(problem, draws_u) -> dict:
    """Every parameter of each draw (rows of ``draws_u``), SI, stacked: the physics, and the
    linear ones (angle offset, drift, kinematic harmonics) at their optimum given the draw's."""
    return {k: np.asarray(v) for k, v in jax.vmap(problem.full_values)(jnp.asarray(draws_u)).items()}


def _predict(fit, whole, values: dict) -> np.ndarray:
    """Noise-free angle (rad) of the fitted model over the whole file, one row per draw;
    ``values``: every parameter of the draws (physics and linear, SI), stacked."""
    model = fit.problem.model
    inp = model_inputs(whole)[0]

    @jax.jit
    def one(v):
        return model.predict(v, [inp])[0]

    n = len(next(iter(values.values())))
    return np.stack([np.asarray(one({k: x[i] for k, x in values.items()})) for i in range(n)])


def _hdi(x, prob=0.95):
    x = np.sort(np.asarray(x, float))
    k = max(1, int(np.floor(prob * len(x))))
    if k >= len(x):
        return float(x[0]), float(x[-1])
    i = int(np.argmin(x[k:] - x[:len(x) - k]))
    return float(x[i]), float(x[i + k])


def play_crossing_shift_Nm(loop: dict, decimate_by: int) -> float:
    """The large ramps' gap-crossing centre minus the play ramps' (N·m), read off a data file's
    (``pi_reference.read_loop``) block means of ``decimate_by`` samples as the held-out error page
    reads them (``scripts/measured_held_out_error.py``: class_crossings); 0 when either class
    shows no crossing both ways."""
    from measured_held_out_error import class_crossings

    n = loop["angle_rad"].size // decimate_by
    means = {k: _block(loop[k], decimate_by, n) for k in ("time_s", "torque_Nm", "angle_rad")}
    nr = _block(loop["test_nr"], decimate_by, n, how=np.max)
    c = class_crossings({**means, "test_nr": nr, "prediction_rad": means["angle_rad"][None, :]})
    shift = c["large_data"]["centre_Nm"] - c["play_data"]["centre_Nm"]
    return float(shift) if np.isfinite(shift) else 0.0


def play_rows(loop: dict, path: Path) -> int:
    """How many rows of the file the play ramps (``test_nr`` < 100) take, all before the large ones."""
    nr = loop["test_nr"]
    if np.any(np.diff((nr >= 100).astype(int)) < 0):
        raise SystemExit(f"--align-play-crossings: {path}: the play ramps (test_nr < 100) must all come before the large ones")
    return int(np.sum(nr < 100))


def _play_torque_shifted(campaign, n_play_rows: int, shift_Nm: float, decimated_by: int):
    """``campaign`` (one run: the file's ramps in file order, the play ramps' ``n_play_rows``
    first; block means of ``decimated_by`` samples) with the play ramps' torque moved by
    ``shift_Nm`` — a diagnostic: their crossings then centre where the large ramps' do (the data
    changed in memory only)."""
    import dataclasses

    (run,) = campaign.runs
    torque = np.array(run.torque_Nm, float)
    torque[:n_play_rows // decimated_by] += shift_Nm
    return dataclasses.replace(campaign, runs=(dataclasses.replace(run, torque_Nm=torque),))


def held_ramp(ramps: list[int], from_end: int = 1) -> int:
    """The test number of the large ramp (``≥ 100``) held out: the last (``from_end`` 1), the one
    before it (2), …; the fit sees the ramps before it."""
    large = sorted(r for r in ramps if r >= 100)
    if not 1 <= from_end < len(large):
        raise SystemExit(f"--hold-out-ramp {from_end}: expected 1 to {len(large) - 1}, as the file has {len(large)} large "
                         f"ramps (test_nr ≥ 100) and at least one must be left to fit")
    return large[-from_end]


def held_text(from_end: int) -> str:
    """The held-out ramp in words."""
    return "the last large ramp" if from_end == 1 else (
        "the large ramp before the last" if from_end == 2 else f"the {from_end}th large ramp from the end")


def _data_path(unit: str) -> Path:
    """The measured file of ``unit`` (its example manifest's, else the one found in the data folder)."""
    return Path(re.search(r'file = "([^"]+)"', _manifest_text(unit)).group(1))


def design_effects(design: str) -> dict:
    """The model of ``design``: :data:`DESIGN_EFFECTS`'s entry, else that of a listed design of
    the same construction in another material (the name before the material: ``split-pla`` is
    the split pinwheel, preloaded as ``split-pccf`` is), else :data:`EFFECTS`."""
    if design in DESIGN_EFFECTS:
        return DESIGN_EFFECTS[design]
    construction = design.split("-")[0]
    return next((e for d, e in DESIGN_EFFECTS.items() if d.split("-")[0] == construction), EFFECTS)


def effects_for(unit: str | None, args) -> dict:
    """The model's effects for ``unit``: ``--effects`` when given, else its design's
    (:func:`design_effects`, by the unit name's prefix) or :data:`EFFECTS`."""
    if args.effects is not None:
        return args.effects
    return design_effects(_design(unit)) if unit else EFFECTS


def fit_options(args, unit: str | None = None) -> FitOptions:
    """The validation's fit of ``unit``: iid noise with the posterior widened for misfit unless ``--ar1``."""
    return FitOptions(effects=effects_for(unit, args), sampler=args.sampler, progress=False, decimate=args.decimate,
                      laplace_shape=args.laplace_shape,
                      max_steps=args.max_steps, n_starts=args.starts, misfit_inflation=not args.no_misfit_inflation,
                      hop_to_the_hold=getattr(args, "hop_to_the_hold", False),
                      gap_prior_from_crossings=getattr(args, "gap_prior_from_crossings", False),
                      optima_mixture=getattr(args, "optima_mixture", False),
                      noise=NoiseOptions(ar1=None if args.ar1 else False, cycle_amplitude_noise=args.cycle_noise,
                                         student_t_dof=getattr(args, "student_t", None),
                                         cycle_class_noise=args.class_noise,
                                         first_excursion_class=getattr(args, "first_excursion_class", False),
                                         first_excursion_conditioning=getattr(args, "condition_first_excursions", False),
                                         torque_error_variance=not args.no_torque_error_variance))


def validate(unit: str, folder: Path, args) -> dict:
    path = _data_path(unit)
    ramps = test_numbers(path)
    from_end = getattr(args, "hold_out_ramp", 1)
    last = held_ramp(ramps, from_end)  # the ramps after it (--hold-out-ramp): predicted, unscored
    # --condition-first-ramp: the first large ramp (test_nr ≥ 100) drives the state, unfitted
    condition = [min(r for r in ramps if r >= 100)] if getattr(args, "condition_first_ramp", False) else None
    train = load_campaign(manifest(unit, [r for r in ramps if r < last], folder, condition))
    whole = decimate(load_campaign(manifest(unit, None, folder)), args.decimate)
    shift = None
    if getattr(args, "align_play_crossings", False):
        from pi_reference import read_loop

        loop = read_loop(path)
        shift, n_play = play_crossing_shift_Nm(loop, args.decimate), play_rows(loop, path)
        train, whole = (_play_torque_shifted(c, n_play, shift, by) for c, by in ((train, 1), (whole, args.decimate)))
    t0 = time.perf_counter()
    options = fit_options(args, unit)
    fit = fit_campaign(train, options, seed=args.seed)
    seconds = time.perf_counter() - t0
    problem = fit.problem
    # the product's own check on the fitted file (fit.json): the class metrics read off the
    # model's prediction of the training record against the data's reading of it
    fit_metrics, fit_off = metrics_against_data(fit)
    rng = np.random.default_rng(args.seed)
    pick = rng.choice(len(fit.draws_u), size=min(args.draws, len(fit.draws_u)), replace=False)
    draws = fit.draws_u[pick]
    # the posterior is widened by fit_campaign when the residuals keep structure (fit/_misfit.py)
    inflation = float(fit.diagnostics.get("misfit_inflation", 1.0))
    pred = _predict(fit, whole, draw_values(problem, draws))  # (draws, N)
    # the MAP's own prediction beside the posterior mean: where a parameter is not identified,
    # Laplace draws reach absurd values and the mean follows them, not the fit
    pred_map = _predict(fit, whole, draw_values(problem, np.asarray(fit.map_result.u)[None]))[0]
    sigma, rho = problem.noise_values(jnp.asarray(fit.map_result.u))
    # the fit's noise is for block means of `decimate` samples; the AR(1) marginal sd of the
    # misfit is what a held-out sample scatters by (the misfit, not the encoder, dominates)
    marginal = float(sigma[0] / np.sqrt(1.0 - float(rho[0]) ** 2))
    run = whole.runs[0]
    y = np.asarray(run.angle_rad)
    if args.cycle_noise:
        # noise level of the largest cycles, scaled by the amplitude of each sample's cycle
        s = float(np.exp(fit.map_result.u[problem.n_nonlinear]))
        shape = cycle_amplitude_shape(run.torque_Nm)
        marginal = np.sqrt((s * shape) ** 2 + float(problem.floors[0]) ** 2) / np.sqrt(1.0 - float(rho[0]) ** 2)
    nr = _block(_test_nr_of(path), args.decimate, len(y), np.min)
    held, fitted = nr == last, nr < last
    mean = pred.mean(axis=0)
    # the likelihood's noise: Gaussian, or Student-t with the fit's scale
    nu = getattr(args, "student_t", None)
    # several noise draws per posterior draw: the 5 % and 95 % quantiles of 200 draws alone
    # scatter by about a percent of coverage, enough to put a loop on either side of the band
    shape = (NOISE_REPEATS, *pred[:, held].shape)
    unit_noise = rng.standard_t(nu, shape) if nu else rng.standard_normal(shape)
    noisy = (pred[None, :, held] + np.broadcast_to(marginal, y.shape)[held] * unit_noise).reshape(-1, int(held.sum()))
    lo, hi = np.quantile(noisy, [0.05, 0.95], axis=0)
    inside = float(np.mean((y[held] >= lo) & (y[held] <= hi)))
    large_train = (nr >= 100) & fitted
    out = {
        "unit": unit,
        "effects": options.effects,
        "seconds_fit": seconds,
        # the fit repeats to the digit on this environment, not across environments
        "environment": environment(),
        **({} if shift is None else {"play_torque_shift_Nm": shift}),
        "rmse_in_sample_arcsec": float(np.sqrt(np.mean((y[fitted] - mean[fitted]) ** 2)) / ARCSEC),
        "rmse_in_sample_large_arcsec": float(np.sqrt(np.mean((y[large_train] - mean[large_train]) ** 2)) / ARCSEC),
        "rmse_held_out_arcsec": float(np.sqrt(np.mean((y[held] - mean[held]) ** 2)) / ARCSEC),
        "rmse_held_out_map_arcsec": float(np.sqrt(np.mean((y[held] - pred_map[held]) ** 2)) / ARCSEC),
        "held_out_ramp": last,
        "coverage90_held_out": inside,
        "noise_marginal_arcsec": float(np.max(marginal)) / ARCSEC,
        "misfit_inflation": inflation,
        "diagnostics": fit.diagnostics,
        "physics_map": {k: float(np.asarray(v)) for k, v in fit.map_result.values.items() if np.ndim(v) == 0},
        "fit_json_off_data": fit_off,
        "fit_json_class_metrics": {k: {"mean": e["mean"], "hdi95": e["hdi95"], "unit": e["unit"], "data": e.get("data")}
                                   for k, e in fit_metrics.items() if k in CLASS_METRICS},
    }
    # data-only and model play / loading compliance, same definitions
    t, tau = np.asarray(run.time_s), np.asarray(run.torque_Nm)
    out.update(data_metrics(t, tau, y, unit))
    plays, comps = [], []
    for row in pred[: args.metric_draws or len(pred)]:
        try:
            classes = cycle_classes(t, tau, row, name=unit)  # once per draw, for both metrics
            play = play_of(classes.play_class(unit))
            fit = loading_fit(classes.loading_class(unit), play, name=unit)
            plays.append(play / DEG)
            comps.append([fit.compliance_pos / DEG, fit.compliance_neg / DEG])
        except Exception as err:  # noqa: BLE001 - a draw whose loop the definition cannot read
            out.setdefault("model_metric_notes", []).append(str(err))
    if plays:
        comps = np.asarray(comps)
        mean_c = comps.mean(axis=1)
        out["play_model_deg"] = {"mean": float(np.mean(plays)), "hdi95": _hdi(plays), "draws": [float(v) for v in plays]}
        out["compliance_model_deg_per_Nm"] = {"mean": float(np.mean(mean_c)), "hdi95": _hdi(mean_c),
                                             "pos": float(np.mean(comps[:, 0])), "neg": float(np.mean(comps[:, 1])),
                                             "draws": [float(v) for v in mean_c]}
    out["reference"] = _reference(path, args.decimate, len(y), last)
    out["ratio_held_out"] = out["rmse_held_out_arcsec"] / out["reference"]["oos_rest"]
    _figure(unit, t, tau, y, pred, lo, hi, held, fitted, args.output / "figures", held_text(from_end))
    if args.save_predictions is not None:
        # for re-scoring without a refit; derived from the measured file: keep outside the repository
        args.save_predictions.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.save_predictions / f"{unit}.npz", time_s=t, torque_Nm=tau, angle_rad=y, test_nr=nr,
                            prediction_rad=pred.astype(np.float32), prediction_map_rad=pred_map,
                            noise_marginal_rad=np.broadcast_to(marginal, y.shape), seed=args.seed)
    return out


def data_metrics(t, tau, y, unit: str) -> dict:
    """Data-only play and loading compliance of one file (deg, deg/N·m), and the loading
    compliance branch by branch: its cycle-to-cycle scatter."""
    classes = cycle_classes(t, tau, y, name=unit)
    play, large = play_of(classes.play_class(unit)), classes.loading_class(unit)
    fit = loading_fit(large, play, name=unit)
    pos, neg = loading_compliance_cycles(large, play, name=unit)
    return {"play_data_deg": play / DEG, "compliance_data_deg_per_Nm": [fit.compliance_pos / DEG, fit.compliance_neg / DEG],
            "compliance_data_cycles_deg_per_Nm": {"pos": (pos / DEG).tolist(), "neg": (neg / DEG).tolist()}}


def refresh_data_metrics(rows: list[dict], decimate_by: int) -> None:
    """Recompute each row's data-only metrics from its measured file (no model fit)."""
    for row in rows:
        with tempfile.TemporaryDirectory() as folder:
            run = decimate(load_campaign(manifest(row["unit"], None, Path(folder))), decimate_by).runs[0]
        row.update(data_metrics(np.asarray(run.time_s), np.asarray(run.torque_Nm), np.asarray(run.angle_rad), row["unit"]))


def compliance_se(row: dict) -> float | None:
    """Standard error (deg/N·m) of a file's loading compliance, mean of + and −, from the
    scatter of its branches' compliances (None when a side has a single branch)."""
    cyc = row.get("compliance_data_cycles_deg_per_Nm")
    if not cyc or min(len(cyc["pos"]), len(cyc["neg"])) < 2:
        return None
    pos, neg = np.asarray(cyc["pos"]), np.asarray(cyc["neg"])
    return 0.5 * float(np.sqrt(pos.var(ddof=1) / pos.size + neg.var(ddof=1) / neg.size))


def _test_nr_of(path: Path) -> np.ndarray:
    from pi_reference import read_loop

    return read_loop(path)["test_nr"]


def _block(x, size: int, n: int, how=np.mean) -> np.ndarray:
    """Blocks of ``size`` samples reduced by ``how`` (as ``torsionfit.io.decimate`` does, the
    remainder dropped), checked to give ``n`` values."""
    x = np.asarray(x, float)
    out = how(x[: len(x) // size * size].reshape(-1, size), axis=1)
    if len(out) != n:
        raise RuntimeError(f"{len(x)} rows in blocks of {size} give {len(out)} values, the campaign has {n}")
    return out


def reference_prediction(loop: dict, signed: bool = True, held_nr: int | None = None) -> np.ndarray:
    """The Prandtl–Ishlinskii reference fitted to a file's raw samples (``read_loop``) before the
    ramp ``held_nr`` (default: the last large ramp): its prediction of every raw sample (rad)."""
    from pi_reference import PIReference

    offset = loop["angle_rad"].mean()  # the offset column absorbs it; keeps NNLS well scaled
    fitted = loop["test_nr"] < (loop["test_nr"].max() if held_nr is None else held_nr)
    return PIReference(signed_play=signed).fit(loop["torque_Nm"], loop["angle_rad"] - offset, fitted).predict() + offset


def _reference(path: Path, size: int, n: int, held_nr: int) -> dict:
    """The Prandtl–Ishlinskii reference fitted to the raw samples before the held-out ramp
    ``held_nr``, scored on the ``n`` block means of ``size`` samples of that ramp (as the model)."""
    from pi_reference import PIReference, read_loop
    from repeat_reference import held_out_prediction

    t0 = time.perf_counter()
    d = read_loop(path)
    y = d["angle_rad"] - d["angle_rad"].mean()
    fitted = d["test_nr"] < held_nr
    held = _block(d["test_nr"], size, n, np.min) == held_nr
    out = {}
    # the reference as designed (play weights of either sign: a loop drawn counter-clockwise where
    # the torque estimate runs ahead of the gap crossing, which no physical hysteresis does), and
    # the physically admissible PI (weights ≥ 0: a break-away density of any shape, clockwise)
    for key, signed in (("oos_rest", True), ("physical_oos_rest", False)):
        e = _block(reference_prediction(d, signed, held_nr) - d["angle_rad"], size, n)[held]
        out[key] = float(np.sqrt(np.mean(e**2)) / ARCSEC)
    # the reference as designed with a damped gap crossing, its lag chosen on the fitted rows
    fit, lag = PIReference().fit_lagged(d["time_s"], d["torque_Nm"], y, fitted)
    out["lagged_oos_rest"] = float(np.sqrt(np.mean(_block(fit.predict() - y, size, n)[held] ** 2)) / ARCSEC)
    out["lag_s"] = lag
    # no model: the earlier large ramps' own twist at the same torque on the same branch — the
    # ramp-to-ramp walk (and the noise of a few ramps' average) is all its error
    e = _block(held_out_prediction(d, held_nr) - d["angle_rad"], size, n)[held]
    covered = np.isfinite(e)
    out["repeat_oos"] = float(np.sqrt(np.mean(e[covered] ** 2)) / ARCSEC)
    out["repeat_covered"] = float(np.mean(covered))
    return out | {"seconds": time.perf_counter() - t0}


def refresh_references(rows: list[dict], size: int, hold_out_ramp: int = 1) -> None:
    """Recompute every row's reference columns in place (cheap: no model fit)."""
    for row in rows:
        path = _data_path(row["unit"])
        n = len(_test_nr_of(path)) // size
        row["reference"] = _reference(path, size, n, held_ramp(test_numbers(path), hold_out_ramp))
        row["ratio_held_out"] = row["rmse_held_out_arcsec"] / row["reference"]["oos_rest"]


def _figure(unit, t, tau, y, pred, lo, hi, held, fitted, folder: Path, held_name: str = "the last large ramp"):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(1, 2, figsize=(13, 5))
    mean = pred.mean(axis=0)
    ax[0].plot(tau[fitted], y[fitted] / DEG, ".", ms=1, color="0.6", label="measured, fitted part")
    ax[0].plot(tau[held], y[held] / DEG, ".", ms=1, color="k", label="measured, held-out ramp")
    shown = fitted | held
    ax[0].plot(tau[shown], mean[shown] / DEG, "-", lw=0.6, color="C1", label="model (posterior mean)")
    ax[0].set_xlabel("torque (N·m, from motor current)")
    ax[0].set_ylabel("twist (deg)")
    ax[0].legend(fontsize=7, markerscale=6)
    ax[0].set_title(f"{unit} (REAL data, CC BY-SA 4.0)", fontsize=9)
    th = t[held]
    ax[1].fill_between(th, lo / DEG, hi / DEG, color="C1", alpha=0.3, lw=0, label="90 % predictive interval")
    ax[1].plot(th, y[held] / DEG, "-", lw=0.6, color="k", label="measured")
    ax[1].plot(th, mean[held] / DEG, "-", lw=0.6, color="C1", label="model")
    ax[1].set_xlabel("time (s)")
    ax[1].set_title(f"held out: {held_name}, predicted from the file before it", fontsize=9)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(folder / f"{unit}.png", dpi=80)
    plt.close(fig)


def _converged(row: dict) -> str:
    """The fit's word; for a MAP that stopped short of its tolerance, how far its optimum is."""
    d = row["diagnostics"]
    step = d.get("map_newton_step_sd")
    return f"{d['converged']}" + (f" (MAP {step:.2g} sd short)" if not d["converged"] and step is not None else "")


def _pareto_k(row: dict) -> str:
    """The Pareto k of the posterior/approximation ratios at the fit's Laplace draws (n/a: a row
    written before the fit read it, or a sampler's)."""
    k = row["diagnostics"].get("laplace_pareto_k")
    return "n/a" if k is None else f"{k:.2f}"


def pareto_k_text(rows: list[dict]) -> str:
    """A sentence on whether the Laplace draws stand for the widened posterior; empty when no row
    has the k."""
    ks = np.array([r["diagnostics"]["laplace_pareto_k"] for r in rows if r["diagnostics"].get("laplace_pareto_k") is not None])
    if not ks.size:
        return ""
    good = int(np.sum(ks <= 0.7))
    return (f"The Laplace draws stand for the widened posterior (Pareto k of the posterior/approximation density ratios at "
            f"them ≤ 0.7) on {good} of {ks.size} loops (k {np.nanmin(ks):.2f}–{np.nanmax(ks):.2f}, median {np.nanmedian(ks):.2f}): "
            + ("where it is above, the intervals — the predictive interval's parameter part, the model's play and compliance — "
               "are the split normal's, not the posterior's, and `torsionfit fit` says so (`laplace_pareto_k_note`)."
               if good < ks.size else "their intervals are the posterior's."))


def rival_text(rows: list[dict]) -> str:
    """A sentence on the loops whose starts reached another optimum the data support about as
    well (the fit's diagnostics.map_other_optima, fit/_map.py rival_optima); empty when no row
    has the record."""
    have = [r for r in rows if r["diagnostics"].get("map_other_optima") is not None]
    if not have:
        return ""
    rivals = {r["unit"]: [o for o in r["diagnostics"]["map_other_optima"] if o["rival"]] for r in have}
    flagged = [u for u, o in rivals.items() if o]
    # the starts' other end points at least a posterior sd from the MAP (closer: the MAP, stopped short)
    away = [[o for o in r["diagnostics"]["map_other_optima"] if o["distance_sd"] >= 1.0] for r in have]
    counts = [len(a) for a in away]
    short = [sum(not o["converged"] for o in a) for a in away]
    text = (f"Besides the MAP the starts ended at {min(counts)}–{max(counts)} other points at least a posterior sd "
            f"from it (median {np.median(counts):.0f}; {sum(short)} of them short of the solver's tolerance); on "
            f"{len(flagged)} of {len(have)} "
            f"loops another converged optimum lies 3 posterior sd or more from the MAP and within 3 of its log "
            f"posterior as widened (`map_rival_note`)")
    if flagged:
        gaps = [min(o["log_density_gap_widened"] for o in rivals[u]) for u in flagged]
        dist = [o["distance_sd"] for u in flagged for o in rivals[u]]
        text += (f": the closest such optimum {min(gaps):.2g}–{max(gaps):.2g} below the MAP's log posterior, "
                 f"{min(dist):.0f}–{max(dist):.0f} sd away. The intervals are drawn around one optimum and do not reach "
                 f"the others the data support about as well")
    return text + "."


def _short_text(rows: list[dict]) -> str:
    """The summary's note on MAPs that stopped short (rows fitted since the fit records it)."""
    short = [(r["unit"], r["diagnostics"]["map_newton_step_sd"]) for r in rows
             if not r["diagnostics"]["converged"] and r["diagnostics"].get("map_newton_step_sd") is not None]
    if not short:
        return ""
    each = ", ".join(f"{unit} {step:.2g}" for unit, step in short)
    return (f" (the MAP stopped short of the solver's tolerance, its Gauss–Newton step to the optimum in posterior sd: "
            f"{each})")


def _map_rmse(row: dict) -> str:
    v = row.get("rmse_held_out_map_arcsec")
    return "n/a" if v is None else f"{v:.0f}"


def _physical(row: dict) -> str:
    ref = row["reference"].get("physical_oos_rest")
    return "n/a" if ref is None else f"{ref:.0f}"


def _lagged(row: dict) -> str:
    ref = row["reference"]
    return "n/a" if "lagged_oos_rest" not in ref else f"{ref['lagged_oos_rest']:.0f} ({ref['lag_s']:.1f})"


def _repeat(row: dict) -> str:
    ref = row["reference"].get("repeat_oos")
    return "n/a" if ref is None else f"{ref:.0f}"


def authors_table() -> dict:
    """(play deg, compliance +, compliance −) per '<design>-<state>' from the data README (the
    table scripts/measured_metrics.py reads); a row without the + and − sides gives its mean
    compliance for both."""
    from measured_metrics import authors_numbers

    out = {}
    for (design, state), a in authors_numbers(DATA / "README.md").items():
        pos, neg = a["compliance_pos"], a["compliance_neg"]
        out[f"{design}-{state}"] = (a["play_deg"], *((a["compliance"],) * 2 if pos is None else (pos, neg)))
    return out


def _config(unit: str) -> str:
    return unit.rsplit("-", 1)[0]


def configuration_values(group: list[dict], authors: tuple | None) -> dict | None:
    """A configuration's play (deg) and loading compliance (deg/N·m), its positions' rows
    ``group`` averaged like the data's authors: theirs (``authors``: play, compliance +, −; None:
    the README has none, and so is the result), the data's (``d_se``: the standard error of the
    mean compliance, None where a file has too few branches) and the model's (mean, 95 % HDI;
    None where a row has no model draws)."""
    if not authors:
        return None
    ses = [compliance_se(r) for r in group]
    out = {"a_play": authors[0], "a_comp": 0.5 * (authors[1] + authors[2]),
           "d_play": float(np.mean([r["play_data_deg"] for r in group])),
           "d_comp": float(np.mean([np.mean(r["compliance_data_deg_per_Nm"]) for r in group])),
           # the positions' mean: independent files, so their standard errors add in quadrature
           "d_se": float(np.sqrt(np.sum(np.square(ses)))) / len(ses) if all(v is not None for v in ses) else None,
           "play_model": None, "compliance_model": None}
    ok = [r for r in group if r.get("play_model_deg") and r.get("compliance_model_deg_per_Nm")]
    if ok:
        # the positions' mean, draw by draw: the units' posteriors are independent, so the
        # k-th draws of each, averaged, are a draw of the mean
        def of_mean(key):
            n = min(len(r[key]["draws"]) for r in ok)
            draws = np.mean([r[key]["draws"][:n] for r in ok], axis=0)
            return float(np.mean(draws)), _hdi(draws)

        out["play_model"], out["compliance_model"] = of_mean("play_model_deg"), of_mean("compliance_model_deg_per_Nm")
    return out


#: the head of the summary table, in validation.md and in the README's measured section
SUMMARY_HEAD = "Per configuration (the README's table):"


def summary_table(rows: list[dict]) -> str:
    """The README's table: per configuration (positions averaged like the data's authors) the
    authors', the data's and the model's play and loading compliance, and per position the
    held-out RMSE over the Prandtl–Ishlinskii reference's and the 90 % interval's coverage."""
    authors = authors_table()
    lines = ["| configuration | play [°] authors / data / model (95 % HDI) | compliance [°/N·m] authors / data / model (95 % HDI) "
             "| held-out RMSE ÷ reference, per position | 90 % interval coverage, per position |",
             "| --- | --- | --- | --- | --- |"]
    for config in dict.fromkeys(_config(r["unit"]) for r in sorted(rows, key=lambda r: r["unit"])):
        group = sorted((r for r in rows if _config(r["unit"]) == config), key=lambda r: r["unit"])
        v = configuration_values(group, authors.get(config))
        if v is None:
            play = compliance = "n/a (no authors' numbers)"
        else:
            model = v["play_model"]
            play = f"{v['a_play']:.3f} / {v['d_play']:.3f} / " + (
                f"{model[0]:.3f} ({model[1][0]:.3f}–{model[1][1]:.3f})" if model else "n/a")
            model = v["compliance_model"]
            compliance = f"{v['a_comp']:.4f} / {v['d_comp']:.4f} / " + (
                f"{model[0]:.4f} ({model[1][0]:.4f}–{model[1][1]:.4f})" if model else "n/a")
        ratio = ", ".join(f"{r['ratio_held_out']:.2f}" for r in group)
        cover = ", ".join(coverage_text(r["coverage90_held_out"]) for r in group)
        positions = "/".join(r["unit"].rsplit("-", 1)[1] for r in group)
        lines.append(f"| {config} ({positions}) | {play} | {compliance} | {ratio} | {cover} |")
    return "\n".join(lines)


#: the likelihood's noise, as the table's header names it
NOISE_TEXT = {
    "iid": "iid noise with the posterior widened for structure the residuals keep",
    "iid-class": "iid noise with a level per cycle class (play ramps, stiffness ramps; their ratio read at the MAP) "
                 "and the posterior widened for structure the residuals keep",
    "iid-class-first": "iid noise with a level per cycle class (play ramps, the ramps that first load the file beyond its "
                       "earlier peaks, the repeated stiffness ramps; their ratios read at the MAP) and the posterior widened "
                       "for structure the residuals keep",
    "iid-conditioned": "iid noise, the ramps that first load the file beyond its earlier peaks conditioning only (they "
                       "drive the model's state, out of the likelihood) and the posterior widened for structure the "
                       "residuals keep",
    "iid-class-ramp-conditioned": "iid noise with a level per cycle class (play ramps, stiffness ramps; their ratio read at "
                                  "the MAP), the file's first large ramp conditioning rows (they drive the model's state, "
                                  "out of the likelihood) and the posterior widened for structure the residuals keep",
    "iid-class-conditioned": "iid noise with a level per cycle class (play ramps, stiffness ramps; their ratio read at the MAP), "
                             "the ramps that first load the file beyond its earlier peaks conditioning only (they drive "
                             "the model's state, out of the likelihood) and the posterior widened for structure the "
                             "residuals keep",
    "ar1": "AR(1) noise",
}


def _noise(args) -> str:
    """The key of the run's noise in :data:`NOISE_TEXT`, ``-t<DOF>`` appended for Student-t noise."""
    nu = getattr(args, "student_t", None)
    return _noise_shape(args) + (f"-t{nu:g}" if nu else "")


def noise_text(noise: str) -> str:
    """How the table's header names the noise of key ``noise`` (:func:`_noise`)."""
    shape, _, nu = noise.partition("-t")
    text = NOISE_TEXT[shape]
    return text.replace("noise", f"Student-t noise (ν = {nu})", 1) if nu else text


def _noise_shape(args) -> str:
    if args.ar1:
        return "ar1"
    if args.class_noise:
        if getattr(args, "condition_first_excursions", False):
            return "iid-class-conditioned"
        if getattr(args, "condition_first_ramp", False):
            return "iid-class-ramp-conditioned"
        return "iid-class-first" if getattr(args, "first_excursion_class", False) else "iid-class"
    return "iid-conditioned" if getattr(args, "condition_first_excursions", False) else "iid"


def coverage_text(share: float, band=COVERAGE_BAND) -> str:
    """A coverage in whole percent, or to a tenth where whole percents would put it on the
    other side of ``band``'s edge (95.2 % is above an 80–95 % band, "95 %" would not say so)."""
    whole = round(100 * share)
    inside, shown = band[0] <= share <= band[1], band[0] <= whole / 100 <= band[1]
    return f"{whole:.0f} %" if inside == shown else f"{100 * share:.1f} %"


def posterior_text(sampler: str, laplace_shape: str, optima_mixture: bool = False) -> str:
    """How the table names the posterior of a run with ``sampler`` and ``laplace_shape``."""
    if sampler != "laplace":
        return sampler
    if optima_mixture:
        return ("laplace (a mixture of split normals, one at each distinct optimum the MAP starts reached, "
                "weighted by its Laplace evidence: FitOptions.optima_mixture)")
    return "laplace (a split normal along the Laplace approximation's axes, each half-axis's width read off the posterior)" \
        if laplace_shape == "split" else "laplace (the Gaussian)"


def mixture_text(rows: list[dict]) -> str:
    """One line on the optima mixture's components (diagnostics.laplace_optima); empty without it."""
    have = [r for r in rows if r["diagnostics"].get("laplace_optima") is not None]
    if not have:
        return ""
    many = {r["unit"]: r["diagnostics"]["laplace_optima"] for r in have if len(r["diagnostics"]["laplace_optima"]) > 1}
    text = f"Optima mixture: more than one component on {len(many)} of {len(have)} loops"
    if many:
        text += " (" + "; ".join(
            f"{u}: weights " + ", ".join(f"{c['weight']:.2f}" for c in comps) for u, comps in many.items()) + ")"
    return text + "."


def _design(unit: str) -> str:
    """A unit's design: its name before the unit state and position (``split-pccf``)."""
    return unit.rsplit("-", 2)[0]


def model_text(rows: list[dict], effects: dict) -> str:
    """The fitted model(s) of ``rows``: each row's own effects (``effects`` for rows written
    before they were recorded), per design where the designs' differ."""
    by_model: dict[str, list[str]] = {}
    for r in rows:
        designs = by_model.setdefault(json.dumps(r.get("effects", effects)), [])
        if _design(r["unit"]) not in designs:
            designs.append(_design(r["unit"]))
    if len(by_model) == 1:
        return f"base + {next(iter(by_model))}"
    return "; ".join(f"base + {model} on the {', '.join(designs)} loops" for model, designs in by_model.items())


def environment_text(rows: list[dict], record: str = "validation.json") -> str:
    """Where the rows were computed (the fits repeat to the digit there, not elsewhere); empty
    for rows written before the environment was recorded. ``record``: the file that keeps each row's."""
    envs = [r["environment"] for r in rows if r.get("environment")]
    if not envs:
        return ""
    distinct = {json.dumps(e, sort_keys=True) for e in envs}
    e = envs[0]
    packages = ", ".join(f"{name} {e[name]}" for name in NUMERICAL_PACKAGES if name in e)
    where = f"Python {e['python']}, {packages}; {e['cpu']}"
    more = "" if len(distinct) == 1 else f" ({len(distinct)} environments among the rows: {record} records each row's)"
    return (f"Computed with {where}{more}. A fit repeats to the digit on the same environment; on another (other package "
            "versions, another processor's instruction set) rounding moves the MAP within the solver's tolerance, and the "
            "columns read off it and the draws move with it.")


def markdown(rows: list[dict], decimate: int, sampler: str, effects: dict, noise: str, laplace_shape: str = "gaussian",
             hop: bool = False, hold_out_ramp: int = 1, optima_mixture: bool = False,
             gap_prior_from_crossings: bool = False) -> str:
    rows = sorted(rows, key=lambda r: r["unit"])  # the table in unit order, whatever order they were fitted in
    held = held_text(hold_out_ramp)
    split = ("without its last large ramp" if hold_out_ramp == 1 else
             f"up to {held} (the ramps after it are neither fitted nor scored)")
    lines = [
        f"Measured loops ({SOURCE}). Model: {model_text(rows, effects)}, "
        + ("the MAP hopped to the hold mode where that is higher (--hop-to-the-hold), " if hop else "")
        + ("the hold torque and the gap's crossing width with priors on the data's gap crossings (--gap-prior-from-crossings), "
           if gap_prior_from_crossings else "") +
        f"{noise_text(noise)}, posterior by {posterior_text(sampler, laplace_shape, optima_mixture)}, fitted to each file {split} (block means of {decimate} samples). "
        f"RMSE in arcsec on those block means, the model's and the reference's alike; held-out = {held} predicted from the file before it "
        "(posterior mean of the draws' predictions; (MAP): the prediction of the MAP alone); "
        "reference = Prandtl–Ishlinskii + tanh gap by NNLS (benchmarks/pi_reference.py) on the same split, as designed "
        "(play weights of either sign) and physical (weights ≥ 0: any break-away density, a clockwise loop); "
        "PI + gap lag = the reference with its gap columns on the torque through a first-order lag chosen on the fitted rows (lag in brackets); "
        "earlier ramps = no model: the held-out ramp predicted by the earlier large ramps' own twist at the same torque on the same branch "
        "(benchmarks/repeat_reference.py), whose error is the loop's ramp-to-ramp walk; "
        "widened × = the posterior covariance factor for structure the residuals keep (long-run variance ratio, 1 = not widened); "
        "k = the Pareto k of the posterior/approximation density ratios at the Laplace draws (≤ 0.7: they stand for the posterior); "
        "± s.e. = the standard error of the data's loading compliance from the scatter of its large branches' compliances, branch by branch "
        "(torsionfit.metrics.loading_compliance_cycles: the bench's cycle-to-cycle repeatability).",
        "",
        SUMMARY_HEAD,
        "",
        *summary_table(rows).splitlines(),
        "",
        "Per loop:",
        "",
        "| unit | in-sample RMSE | held-out RMSE | held-out RMSE (MAP) | reference held-out | ratio | physical PI held-out | PI + gap lag held-out (s) | earlier ramps held-out | 90 % PI coverage | play data (deg) | play model (deg, 95 % HDI) | compliance data (deg/N·m, ± s.e.) | compliance model (deg/N·m, 95 % HDI) | widened × | k | converged |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | --- | ---: | ---: | --- |",
    ]
    for r in rows:
        pm, cm = r.get("play_model_deg"), r.get("compliance_model_deg_per_Nm")
        pm_s = f"{pm['mean']:.3f} ({pm['hdi95'][0]:.3f}–{pm['hdi95'][1]:.3f})" if pm else "n/a"
        cm_s = f"{cm['mean']:.4f} ({cm['hdi95'][0]:.4f}–{cm['hdi95'][1]:.4f})" if cm else "n/a"
        cd = np.mean(r["compliance_data_deg_per_Nm"])
        se = compliance_se(r)
        cd_s = f"{cd:.4f}" + (f" ± {se:.4f}" if se is not None else "")
        lines.append(
            f"| {r['unit']} | {r['rmse_in_sample_arcsec']:.0f} | {r['rmse_held_out_arcsec']:.0f} | {_map_rmse(r)} | {r['reference']['oos_rest']:.0f} | "
            f"{r['ratio_held_out']:.2f} | {_physical(r)} | {_lagged(r)} | {_repeat(r)} | {coverage_text(r['coverage90_held_out'])} | {r['play_data_deg']:.3f} | {pm_s} | {cd_s} | {cm_s} | {r.get('misfit_inflation', 1.0):.1f} | {_pareto_k(r)} | {_converged(r)} |"
        )
    ratios = np.array([r["ratio_held_out"] for r in rows])
    cover = np.array([r["coverage90_held_out"] for r in rows])
    lines += ["", f"Held-out RMSE at or below the reference on {int(np.sum(ratios <= 1))} of {len(rows)} loops "
              f"(≤ 0.8× on {int(np.sum(ratios <= 0.8))}; median ratio {np.median(ratios):.2f}, worst {ratios.max():.2f}); "
              f"90 % predictive interval covering 80–95 % of the held-out ramp on {int(np.sum((cover >= COVERAGE_BAND[0]) & (cover <= COVERAGE_BAND[1])))} of {len(rows)} "
              f"(median {100 * np.median(cover):.0f} %, range {coverage_text(cover.min())[:-2]}–{coverage_text(cover.max())}); "
              f"converged on {sum(bool(r['diagnostics']['converged']) for r in rows)} of {len(rows)}{_short_text(rows)}."]
    k_text = pareto_k_text(rows)
    if k_text:
        lines += ["", k_text]
    optima_text = rival_text(rows)
    if optima_text:
        lines += ["", optima_text]
    if mixture_text(rows):
        lines += ["", mixture_text(rows)]
    env_text = environment_text(rows)
    if env_text:
        lines += ["", env_text]
    with_c = [r for r in rows if r.get("compliance_model_deg_per_Nm")]
    if with_c:
        own = [r for r in with_c if r["compliance_model_deg_per_Nm"]["hdi95"][0] <= np.mean(r["compliance_data_deg_per_Nm"])
               <= r["compliance_model_deg_per_Nm"]["hdi95"][1]]
        off = np.array([r["compliance_model_deg_per_Nm"]["mean"] / np.mean(r["compliance_data_deg_per_Nm"]) - 1 for r in with_c])
        lines += ["", f"The model's loading compliance against the data's own (same definition, same file): its 95 % HDI contains the "
                  f"data's value on {len(own)} of {len(with_c)} loops; the model's mean is {100 * off.min():+.0f} % to {100 * off.max():+.0f} % "
                  f"off (median |off| {100 * np.median(np.abs(off)):.0f} %)."]
    at_map = [r["rmse_held_out_map_arcsec"] / r["reference"]["oos_rest"] for r in rows if "rmse_held_out_map_arcsec" in r]
    if at_map:
        lines += ["", f"The MAP's own prediction of the held-out ramp: at or below the reference on {int(np.sum(np.array(at_map) <= 1))} "
                  f"of {len(at_map)} (median ratio {np.median(at_map):.2f}, worst {max(at_map):.2f})."]
    phys = [r["rmse_held_out_arcsec"] / r["reference"]["physical_oos_rest"] for r in rows if "physical_oos_rest" in r["reference"]]
    if phys:
        lines += ["", f"Against the physical PI reference (weights ≥ 0): held-out RMSE at or below it on "
                  f"{int(np.sum(np.array(phys) <= 1))} of {len(phys)} loops (median ratio {np.median(phys):.2f}, worst {max(phys):.2f})."]
    with_lag = [r for r in rows if "lagged_oos_rest" in r["reference"]]
    if with_lag:
        lagged = [r["rmse_held_out_arcsec"] / r["reference"]["lagged_oos_rest"] for r in with_lag]
        lags = [r["reference"]["lag_s"] for r in with_lag]
        lines += ["", f"Against the PI reference with a gap lag (lag {min(lags):.1f}–{max(lags):.1f} s): held-out RMSE at or below it on "
                  f"{int(np.sum(np.array(lagged) <= 1))} of {len(lagged)} loops (≤ 0.8× on {int(np.sum(np.array(lagged) <= 0.8))}; "
                  f"median ratio {np.median(lagged):.2f}, worst {max(lagged):.2f})."]
    with_repeat = [r for r in rows if "repeat_oos" in r["reference"]]
    if with_repeat:
        rep = np.array([r["reference"]["repeat_oos"] for r in with_repeat])
        model = np.array([r["rmse_held_out_arcsec"] for r in with_repeat])
        narrow = [r for r in with_repeat if r["coverage90_held_out"] < 0.8]
        walk = [r for r in narrow if r["rmse_held_out_arcsec"] <= 1.1 * r["reference"]["repeat_oos"]]
        lines += ["", f"No model, the earlier large ramps' own twist: held-out RMSE {rep.min():.0f}–{rep.max():.0f} (median {np.median(rep):.0f}); "
                  f"the model's held-out RMSE at or below it on {int(np.sum(model <= rep))} of {len(rep)} loops "
                  f"(median ratio {np.median(model / rep):.2f}, worst {np.max(model / rep):.2f}); of the {len(narrow)} loops whose "
                  f"90 % interval covers less than 80 %, the model is below it or within 10 % above on {len(walk)}."]
    flagged = [r for r in rows if "fit_json_off_data" in r]
    if flagged:
        count = {name: sum(name in r["fit_json_off_data"] for r in flagged) for name in CLASS_METRICS}
        lines += ["", "Off the data (the fit's own check, as `torsionfit fit` writes it to fit.json): the class metrics read off the "
                  "model's prediction of the fitted record, whose 95 % HDI misses the data's reading of the same record by more than "
                  "two of its standard errors, per loop:", "",
                  "| unit | off the data | play model / data (arcmin) | stiffness_loading model / data (Nm/arcmin) |", "| --- | --- | --- | --- |"]
        for r in flagged:
            m = r["fit_json_class_metrics"]

            def pair(name, digits):
                e = m.get(name)
                if not e or not e.get("data"):
                    return "n/a"
                return f"{e['mean']:.{digits}f} ({e['hdi95'][0]:.{digits}f}–{e['hdi95'][1]:.{digits}f}) / {e['data']['value']:.{digits}f}"

            lines.append(f"| {r['unit']} | {', '.join(r['fit_json_off_data']) or 'none'} | {pair('play', 1)} | {pair('stiffness_loading', 4)} |")
        lines += ["", f"Flagged on {sum(bool(r['fit_json_off_data']) for r in flagged)} of {len(flagged)} loops: "
                  + ", ".join(f"{name} on {n}" for name, n in count.items()) + "."]
    authors = authors_table()
    lines += ["", "Per configuration, positions averaged like the data's authors (their numbers from the data's README):", "",
              "| configuration | play authors (deg) | play data | play model (95 % HDI) | compliance authors (deg/N·m) | compliance data (± s.e.) | authors − data (in s.e.) | compliance model (95 % HDI) | authors' play in model HDI | authors' compliance in model HDI | data's compliance in model HDI |",
              "| --- | ---: | ---: | --- | ---: | ---: | ---: | --- | --- | --- | --- |"]
    checks, gaps, missing = [], [], []
    for config in dict.fromkeys(_config(r["unit"]) for r in rows):
        v = configuration_values([r for r in rows if _config(r["unit"]) == config], authors.get(config))
        if v is None:
            missing.append(config)
            continue
        a_play, a_comp, d_play, d_comp, d_se = v["a_play"], v["a_comp"], v["d_play"], v["d_comp"], v["d_se"]
        ok = v["play_model"] is not None
        if ok:
            (pm, ph), (cm, ch) = v["play_model"], v["compliance_model"]
            model_p = f"{pm:.3f} ({ph[0]:.3f}–{ph[1]:.3f})"
            model_c = f"{cm:.4f} ({ch[0]:.4f}–{ch[1]:.4f})"
            in_p, in_c = ph[0] <= a_play <= ph[1], ch[0] <= a_comp <= ch[1]
            in_d = ch[0] <= d_comp <= ch[1]
        else:
            model_p = model_c = "n/a"
            in_p = in_c = in_d = False
        if ok:
            model_p += f" ({100 * (pm / a_play - 1):+.0f} %)"
            model_c += f" ({100 * (cm / a_comp - 1):+.0f} %)"
            checks.append((abs(d_play / a_play - 1) <= 0.10, abs(d_comp / a_comp - 1) <= 0.10,
                           abs(pm / a_play - 1) <= 0.15 and in_p, abs(cm / a_comp - 1) <= 0.15 and in_c, in_d))
        z = (a_comp - d_comp) / d_se if d_se else None
        if z is not None:
            gaps.append(abs(z))
        d_c = f"{d_comp:.4f}" + (f" ± {d_se:.4f}" if d_se else "") + f" ({100 * (d_comp / a_comp - 1):+.0f} %)"
        lines.append(f"| {config} | {a_play:.3f} | {d_play:.3f} ({100 * (d_play / a_play - 1):+.0f} %) | {model_p} | {a_comp:.4f} | "
                     f"{d_c} | {'n/a' if z is None else f'{z:+.1f}'} | {model_c} | {in_p} | {in_c} | {in_d} |")
    if missing:
        lines += ["", f"Not in this table, the data's README has no numbers of the authors for them: {', '.join(missing)}."]
    if checks:
        c = np.array(checks)
        lines += ["", f"Of {len(c)} configurations: data-only play within 10 % of the authors' on {c[:, 0].sum()}, loading "
                  f"compliance on {c[:, 1].sum()}; the model's play within 15 % with the authors' value inside its 95 % HDI on "
                  f"{c[:, 2].sum()}, its loading compliance on {c[:, 3].sum()}; the data's own loading compliance inside the "
                  f"model's 95 % HDI on {c[:, 4].sum()}."]
    if gaps:
        g = np.array(gaps)
        lines += ["", f"The authors' compliance and the same definition applied here to the same files differ by more than two "
                  f"standard errors of the bench's cycle-to-cycle scatter on {int(np.sum(g > 2))} of {len(g)} configurations "
                  f"(median {np.median(g):.1f} s.e.; each file's standard error from its 2–3 large branches per side, a rough scale): "
                  f"the difference lies in how the slope is read (averaging, fit range) or in which files were read, not in the "
                  f"bench's repeatability. Where it exceeds two standard errors, a model that reproduced the data with an interval as "
                  f"wide as the data support would not contain the authors' value either."]
    return "\n".join(lines)


def main(argv=None) -> int:
    args = parse_args(argv)
    with torsionfit.float64():  # the script's own JAX calls (predictions, draws) in float64 too
        return _main(args)


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, default=Path("out/validation"))
    parser.add_argument("--units", nargs="*", help="example manifest names or designs, e.g. split-pccf (default: all 21)")
    parser.add_argument("--sampler", choices=("auto", "emcee", "nuts", "smc", "laplace"), default="laplace")
    parser.add_argument("--laplace-shape", choices=("gaussian", "split"), default="split",
                        help="Laplace draws from a split normal measured along the Gaussian's axes (default) or the Gaussian")
    parser.add_argument("--decimate", type=int, default=16)
    parser.add_argument("--hold-out-ramp", type=int, default=1, metavar="K",
                        help="hold out the K-th large ramp from the end (1: the last; 2: the one before it, the fit and "
                             "the references seeing the ramps before it): is the held-out error a property of the file?")
    parser.add_argument("--starts", type=int, default=FitOptions().n_starts, help="MAP starts (default: the fit's)")
    parser.add_argument("--draws", type=int, default=200, help="posterior draws for the predictive interval")
    parser.add_argument("--metric-draws", type=int, default=None,
                        help="draws for the model's play and loading compliance (default: all of --draws; each costs "
                             "a millisecond or two, and a 95 %% HDI from 40 moved its ends by up to 0.3° between runs)")
    parser.add_argument("--max-steps", type=int, default=20_000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--ar1", action="store_true",
                        help="AR(1) noise, the fit's default for runs of ≥ 100 samples, instead of iid noise (for comparison)")
    parser.add_argument("--no-misfit-inflation", action="store_true",
                        help="the posterior as the likelihood gives it, not widened for structure the residuals keep (fit/_misfit.py)")
    parser.add_argument("--no-torque-error-variance", action="store_true",
                        help="the angle noise alone, without the torque error carried along the measured branch "
                             "(NoiseOptions.torque_error_variance)")
    parser.add_argument("--student-t", type=float, default=None, metavar="DOF",
                        help="Student-t noise with DOF degrees of freedom (NoiseOptions.student_t_dof): heavy tails for "
                             "the stick-slip jumps; the predictive interval draws its noise from the same t")
    parser.add_argument("--cycle-noise", action="store_true",
                        help="noise level scaled by the amplitude of each sample's torque cycle (NoiseOptions.cycle_amplitude_noise)")
    parser.add_argument("--class-noise", action=argparse.BooleanOptionalAction, default=True,
                        help="a noise level per cycle class, their ratio read at the MAP (NoiseOptions.cycle_class_noise; "
                             "default on; --no-class-noise: one level per file)")
    parser.add_argument("--first-excursion-class", action="store_true",
                        help="the ramps that first load the file beyond its earlier peaks (the first large ramp) a cycle "
                             "class of their own (NoiseOptions.first_excursion_class; needs the class noise)")
    parser.add_argument("--condition-first-excursions", action="store_true",
                        help="the same first excursions drive the model's state but are out of the likelihood "
                             "(NoiseOptions.first_excursion_conditioning)")
    parser.add_argument("--condition-first-ramp", action="store_true",
                        help="the file's first large ramp (test_nr 100) conditioning rows: it drives the model's state "
                             "but is out of the likelihood ([runs.condition])")
    parser.add_argument("--optima-mixture", action="store_true",
                        help="draws from a mixture of split normals over the optima the starts reached, weighted by "
                             "their Laplace evidence (FitOptions.optima_mixture)")
    parser.add_argument("--hop-to-the-hold", action="store_true",
                        help="one more MAP run from the hold mode the cycles' readings point at (FitOptions.hop_to_the_hold)")
    parser.add_argument("--gap-prior-from-crossings", action="store_true",
                        help="the held gap's hold torque and the gap's crossing width centred on the data's gap "
                             "crossings (FitOptions.gap_prior_from_crossings)")
    parser.add_argument("--align-play-crossings", action="store_true",
                        help="diagnostic: the play ramps' torque (test_nr < 100) moved by the data's large-ramp gap-crossing "
                             "centre minus the play ramps' (in memory only), so one gap centre can place both")
    parser.add_argument("--effects", type=json.loads, default=None,
                        help=f"model effects as JSON for every unit (default: by design, {json.dumps(DESIGN_EFFECTS)}, "
                             f"else {json.dumps(EFFECTS)})")
    parser.add_argument("--save-predictions", type=Path, default=None,
                        help="also write each unit's data and predictive draws to DIR/<unit>.npz (derived from the "
                             "measured files: keep it outside the repository)")
    parser.add_argument("--jobs", type=int, default=1, help="units fitted in this many processes at once")
    parser.add_argument("--refresh-references", action="store_true",
                        help="recompute the reference fits for OUTPUT/validation.json (no model fit) and re-write the table")
    parser.add_argument("--refresh-data-metrics", action="store_true",
                        help="recompute the data-only play and loading compliance for OUTPUT/validation.json from the measured files "
                             "(no model fit) and re-write the table")
    parser.add_argument("--table-only", action="store_true", help="re-write validation.md from OUTPUT/validation.json")
    parser.add_argument("--append", action="store_true",
                        help="keep OUTPUT/validation.json's rows of the units not fitted now (their fits as they were)")
    args = parser.parse_args(argv)
    if args.first_excursion_class and not args.class_noise:
        parser.error("--first-excursion-class is a cycle class: it needs the class noise (drop --no-class-noise)")
    if args.condition_first_ramp and (args.condition_first_excursions or args.first_excursion_class or not args.class_noise):
        parser.error("--condition-first-ramp is compared with the class noise alone (no --first-excursion-class, "
                     "--condition-first-excursions or --no-class-noise)")
    if args.condition_first_excursions and args.first_excursion_class:
        parser.error("--condition-first-excursions takes the first excursions out of the likelihood: "
                     "--first-excursion-class would have nothing to weigh")
    return args


def _validate_in_float64(unit: str, args) -> dict:
    with torsionfit.float64(), tempfile.TemporaryDirectory() as folder:  # manifests naming this machine's paths
        return validate(unit, Path(folder), args)


def _main(args) -> int:
    if args.table_only or args.refresh_references or args.refresh_data_metrics:
        doc = json.loads((args.output / "validation.json").read_text())
        if args.refresh_references:
            refresh_references(doc["units"], doc.get("decimate", args.decimate), doc.get("hold_out_ramp", 1))
        if args.refresh_data_metrics:
            if not DATA.is_dir():
                print(f"{DATA} is absent: the data-only metrics are read from the measured files")
                return 1
            refresh_data_metrics(doc["units"], doc.get("decimate", args.decimate))
        if args.refresh_references or args.refresh_data_metrics:
            (args.output / "validation.json").write_text(json.dumps(doc, indent=1, default=float))
        # written before the noise / the Laplace shape were recorded: AR(1) / the Gaussian
        text = markdown(doc["units"], doc.get("decimate", args.decimate), doc.get("sampler", args.sampler), doc.get("effects", args.effects or EFFECTS),
                        doc.get("noise", "ar1"), doc.get("laplace_shape", "gaussian"), doc.get("hop_to_the_hold", False),
                        doc.get("hold_out_ramp", 1), doc.get("optima_mixture", False), doc.get("gap_prior_from_crossings", False))
        (args.output / "validation.md").write_text(text + "\n")
        print(text)
        return 0
    if not DATA.is_dir():
        print(f"{DATA} is absent: nothing to validate")
        return 0
    units = select_units(args.units)
    for path in files_out_of_layout():
        print(f"{path}: not validated (a measured file is named <state>-<position>.csv.gz, as the data's README lays out)",
              file=sys.stderr)
    reasons = {unit: not_validated(unit) for unit in units}
    for reason in filter(None, reasons.values()):
        print(f"not validated: {reason}", file=sys.stderr)
    from measured_metrics import fault_line

    for unit in units:
        if reasons[unit] is None and (line := fault_line(_data_path(unit))) is not None:
            print(line, file=sys.stderr)
    units = [unit for unit in units if reasons[unit] is None]
    args.output.mkdir(parents=True, exist_ok=True)
    kept = _kept_rows(args, units)  # checked before any fit
    # units in processes of their own (one JAX runtime and one XLA thread each, pinned to a CPU)
    with executor(workers=args.jobs) as run_map:
        results = run_map(functools.partial(_validate_in_float64, args=args), units)
        # each row is written as it comes (in order), so a run cut short keeps what it has done
        rows = _write_rows(args, units, results, kept)
    text = markdown(rows, args.decimate, args.sampler, args.effects or EFFECTS, _noise(args), args.laplace_shape, args.hop_to_the_hold,
                    args.hold_out_ramp, args.optima_mixture, args.gap_prior_from_crossings)
    (args.output / "validation.md").write_text(text + "\n")
    print(text)
    return 0


def _kept_rows(args, units) -> list[dict]:
    """With ``--append``, OUTPUT/validation.json's rows of units other than ``units``; they must
    have been fitted with the same settings."""
    path = args.output / "validation.json"
    if not (args.append and path.is_file()):
        return []
    doc = json.loads(path.read_text())
    settings = {"decimate": args.decimate, "sampler": args.sampler, "noise": _noise(args), "laplace_shape": args.laplace_shape,
                "hop_to_the_hold": args.hop_to_the_hold, "align_play_crossings": args.align_play_crossings,
                "optima_mixture": args.optima_mixture, "gap_prior_from_crossings": args.gap_prior_from_crossings,
                "hold_out_ramp": args.hold_out_ramp}
    recorded = {"hop_to_the_hold": False, "align_play_crossings": False, "optima_mixture": False,
                "gap_prior_from_crossings": False, "hold_out_ramp": 1, **doc}  # written only when on
    for key, value in settings.items():
        if recorded.get(key) != value:
            raise SystemExit(f"--append: {path} was written with {key} = {recorded.get(key)!r}, this run has {value!r}")
    # rows written before each recorded its model were fitted with the document's
    return [{"effects": doc.get("effects", EFFECTS), **r} for r in doc["units"] if r["unit"] not in units]


def _write_rows(args, units, results, kept: list[dict]) -> list[dict]:
    rows = list(kept)
    for unit, row in zip(units, results):
        rows.append(row)
        print(f"{unit}: held-out {row['rmse_held_out_arcsec']:.0f}″ (reference {row['reference']['oos_rest']:.0f}″, "
              f"ratio {row['ratio_held_out']:.2f}), coverage {100 * row['coverage90_held_out']:.0f} %, fit {row['seconds_fit']:.0f} s", file=sys.stderr)
        (args.output / "validation.json").write_text(json.dumps({"source": SOURCE, "decimate": args.decimate, "sampler": args.sampler,
                                                                       "effects": args.effects or EFFECTS,
                                                                       **({} if args.effects else {"design_effects": DESIGN_EFFECTS}),
                                                                       "noise": _noise(args),
                                                                       "laplace_shape": args.laplace_shape,
                                                                       **({"hold_out_ramp": args.hold_out_ramp} if args.hold_out_ramp != 1 else {}),
                                                                       **({"hop_to_the_hold": True} if args.hop_to_the_hold else {}),
                                                                       **({"optima_mixture": True} if args.optima_mixture else {}),
                                                                       **({"gap_prior_from_crossings": True} if args.gap_prior_from_crossings else {}),
                                                                       **({"align_play_crossings": True} if args.align_play_crossings else {}),
                                                                       "units": rows},
                                                                      indent=1, default=float))
    return rows


if __name__ == "__main__":
    sys.exit(main())
