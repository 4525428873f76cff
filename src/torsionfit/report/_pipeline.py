"""One campaign, end to end: model → MAP → posterior (emcee, NUTS, emcee or NUTS chosen by
the first checks — ``auto`` — or the Laplace approximation) → derived metrics with
uncertainty → ``fit.json``, ``posterior.nc`` and figures."""

import dataclasses
import functools
import json
import logging
import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._x64 import in_float64
from .._chunks import map_chunks
from .._errors import InputError
from .._provenance import provenance
from ..fit import NoiseOptions, build_problem, fit_map, rival_note, rival_optima
from ..fit import _transform as tr
from ..fit._map import nested_start
from ..fit._prior import cycle_friction_readings_Nm
from ..fit._noise_classes import _residuals, class_shares, refit_with_class_noise
from ..fit._misfit import MISFIT_RHO, misfit_correlated_runs, widen_for_misfit
from ..fit._contraction import prior_dominated, prior_dominated_note
from ..fit._quantisation import quantisation_note, runs_below_the_encoder_step
from ..io import Campaign, decimate
from ..model import RelayGapBacklash, SteppedBacklash, model_with_effects
from ..units import ANGLE_UNITS
from ._against_data import against_data, data_readings, off_data_note, unreadable_notes
from ._derived import derived_metrics_for
from ._physical import dahl_hook_note, gap_segment_note, relay_gap_note
from ._follows import left_by_posterior_reason, not_followed_reason, runs_left_by_posterior, runs_not_followed

ARCSEC = ANGLE_UNITS["arcsec"]
#: progress lines (INFO); the command line shows them on stderr unless --quiet
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FitOptions:
    """How to fit. ``effects``: model extensions by catalog name (DESIGN §3), switched on by
    hand; ``sampler``: "auto" (emcee where its first checks say it converges within
    ``max_steps``, else NUTS — :func:`sample_posterior`), "emcee", "nuts" (BlackJAX, gradient
    based), "smc" (tempered SMC from the split normal to the posterior, ``smc_particles``
    particles: for posteriors the split normal does not stand for) or "laplace" (the MAP's
    Gaussian approximation, fast, for screening).
    ``max_steps``: emcee's step budget; ``n_chains``, ``n_warmup``, ``max_draws``: NUTS's
    chains, warm-up steps and cap on draws per chain (grown by half from 500 until converged).
    ``laplace_shape``: the Laplace sampler's draws from the Gaussian ("gaussian") or from a split
    normal whose half-axes are measured on the posterior ("split", :mod:`torsionfit.sample`'s
    ``split_normal``: for posteriors that are not Gaussian, e.g. widened fits of measured loops)."""

    effects: dict = field(default_factory=dict)
    noise: NoiseOptions = NoiseOptions()
    n_starts: int = 4
    sampler: str = "auto"
    n_walkers: int | None = None
    max_steps: int = 20_000
    n_chains: int = 4
    n_warmup: int = 500
    max_draws: int = 4000
    progress: bool = True
    backend_path: str | None = None
    resume: bool = False
    laplace_draws: int = 4000
    smc_particles: int = 1000  # tempered SMC's particles (= its draws)
    smc_max_moves: int = 100  # SMC's moves allowed at each stage (a stage that needs more is not converged)
    smc_final_max_moves: int = 100  # SMC's moves allowed at β = 1 (at least smc_max_moves)
    laplace_shape: str = "gaussian"
    metric_draws: int = 2000  # draws used for the derived metrics
    lost_motion_pct: float = 3.0
    decimate: int = 1  # block means of this many samples before fitting (recorded in fit.json)
    # widen the posterior when the whitened residuals keep structure the model lacks
    # (long-run variance ratio k > 1 at the MAP: likelihood to the power 1/k, fit/_misfit.py)
    misfit_inflation: bool = True
    # LM step budget of every MAP pass: a measured loop's long ridges need more than diagnose's
    # screening fits get (fit_map's default, 300). One budget for the first and the later passes:
    # the budget is part of the compiled solve, and two budgets compiled it twice
    map_steps: int = 1000
    # passes of map_steps more for a MAP whose last pass stopped at its budget short of the
    # tolerance (fit_map's ``continuations``): a preloaded measured loop (split preload 2,
    # position 1) met it between 1000 and 3000 steps. A budget of 3000 for every pass tripled the
    # first passes from far starts on the baseline loops; continuing costs only the fit that needs it
    map_continuations: int = 2
    # one more LM run from the MAP of a model with a held gap, from the hold mode the cycles'
    # readings point at (:func:`hop_to_the_hold`); measured on the 21 measured loops, an option
    hop_to_the_hold: bool = False
    # the split normal of each other optimum the starts reached beside the MAP's, the draws a
    # mixture weighted by their Laplace evidence (:func:`optima_mixture`); ``laplace_shape`` "split"
    optima_mixture: bool = False
    # the held gap's hold torque and the gap's crossing width centred on the data's gap crossings
    # (:func:`~torsionfit.fit._prior.gap_crossing_priors`) instead of the rated torque's scale;
    # measured on the 21 measured loops the fits get worse in and out of sample: an option
    gap_prior_from_crossings: bool = False

    @property
    def map_budget(self) -> dict:
        """fit_map's step budget under these options: every pass ``map_steps``, and
        ``map_continuations`` more where the chosen optimum stopped at it."""
        return {"max_steps": self.map_steps, "polish_steps": self.map_steps, "continuations": self.map_continuations}


@dataclass(frozen=True, eq=False)
class CampaignFit:
    campaign: Campaign
    options: FitOptions
    problem: object
    map_result: object
    draws_u: np.ndarray  # (draws, dim) posterior draws of u
    metric_specs: tuple
    metric_draws: np.ndarray  # (draws, metrics)
    diagnostics: dict
    rmse_arcsec: dict  # per run, at the MAP
    sample_result: object = None
    #: SI parameter values (name → (draws, ...)) of the draws behind ``metric_draws``, row by
    #: row: further model quantities of the same draws (e.g. K_d at any condition) use these.
    #: The physics and the linear parameters the metrics read (kinematic harmonics), not the
    #: per-run offsets and drift (nuisance of one measured run; the metrics' runs have none)
    metric_values: dict | None = None
    seed: int | None = None  # the fit's seed (fit.json's provenance)
    #: the ArviZ tree made with the fit (emcee, NUTS), or a function of no arguments that makes
    #: it (Laplace: a model run per draw, which callers reading only the metrics need not pay)
    tree_source: object = field(default=None, repr=False)

    @functools.cached_property
    def tree(self):
        """The ArviZ ``DataTree`` of the fit (``torsionfit.sample.to_datatree``; Laplace: draws
        of the approximation), made on first use for Laplace."""
        return self.tree_source() if callable(self.tree_source) else self.tree_source

    @property
    def run_names(self) -> list[str]:
        return [r.name for r in self.campaign.runs]


def _hdi(x: np.ndarray, prob: float = 0.95) -> tuple[float, float]:
    """Narrowest interval holding ``prob`` of the draws."""
    x = np.sort(np.asarray(x, float))
    n = len(x)
    k = max(1, int(math.floor(prob * n)))
    if k >= n:
        return float(x[0]), float(x[-1])
    widths = x[k:] - x[: n - k]
    i = int(np.argmin(widths))
    return float(x[i]), float(x[i + k])


def summarise(draws: np.ndarray) -> dict:
    lo, hi = _hdi(draws)
    return {"mean": float(np.mean(draws)), "sd": float(np.std(draws, ddof=1)), "hdi95": [lo, hi]}


@eqx.filter_jit
def _values_over_draws(problem, u_batch, linear: bool):
    """SI values of the draws: physics only, or with the linear parameters' profile β̂(u) (a
    model run over the data per draw, the larger part of a Laplace unit's metric cost)."""
    if linear:
        return jax.vmap(problem.full_values)(u_batch)
    return jax.vmap(lambda u: problem.physics_values(u[:problem.n_nonlinear]))(u_batch)


@in_float64
def campaign_model(campaign: Campaign, options: FitOptions = FitOptions()):
    """The model :func:`fit_campaign` fits to ``campaign`` with ``options``."""
    kinds = [r.kind for r in campaign.runs]
    return model_with_effects(kinds, options.effects, campaign.reducer.rated_torque_Nm, free_friction_start=True,
                              fitted=True, te_loads_Nm=[r.torque_Nm for r in campaign.te_runs])


@in_float64
def prepare_fit(campaign: Campaign, options: FitOptions = FitOptions()):
    """(decimated campaign, model, problem) that :func:`fit_campaign` fits; InputError on data
    that cannot be fitted."""
    if not campaign.runs:
        raise InputError("campaign has no runs to fit")
    campaign = decimate(campaign, options.decimate)
    model = campaign_model(campaign, options)
    return campaign, model, build_problem(campaign, model, options.noise,
                                          gap_prior_from_crossings=options.gap_prior_from_crossings)


#: effects whose model contains the model without them as their parameter goes to zero
#: (:attr:`~torsionfit.model.Parameter.vanishes_at_zero`); their fit also starts from the
#: optimum without them
NESTED_AT_ZERO = ("gap_lag",)


def _without_nested(effects: dict, model=None) -> dict:
    """``effects`` without the parts that vanish at zero: :data:`NESTED_AT_ZERO` effects, the
    lag of a load-dependent friction level (``{lag = true}`` → ``true``), and a gap in an odd
    number of steps when ``model`` has it (:func:`_middle_step`: the plain gap is its case of
    every share on the step at zero torque), and a relay gap in place of one held gap centred
    on a torque of its own (:func:`gap_on_the_held_relay`: one relay of the grid is a held
    gap)."""
    out = {k: v for k, v in effects.items() if not (k in NESTED_AT_ZERO and v)}
    if out.get("gap_relays"):
        out.pop("gap_relays")
        out["gap_hold"] = {"centred": False}
    if isinstance(out.get("load_dependent_friction"), dict) and out["load_dependent_friction"].get("lag"):
        out["load_dependent_friction"] = True
    if model is not None and _middle_step(model) is not None:
        out.pop("gap_steps", None)
    return out


def _middle_step(model) -> int | None:
    """:attr:`~torsionfit.model.SteppedBacklash.middle_step` of ``model``'s gap, None for any other gap."""
    backlash = getattr(model, "backlash", None)
    return backlash.middle_step if isinstance(backlash, SteppedBacklash) else None


def _nested_starts(campaign: Campaign, options: FitOptions, problem, seed: int):
    """Warm start for a model with a part that vanishes at zero (:func:`_without_nested`): the
    MAP without it, its parameter three prior sds below its centre, where the model is the
    smaller one (:func:`~torsionfit.fit._map.nested_start`). From the prior's starts alone such
    a fit stopped below the smaller model's optimum on a measured loop, though it contains it."""
    inner_effects = _without_nested(options.effects, problem.model)
    nested = [k for k in options.effects if options.effects[k] != inner_effects.get(k)]
    if not nested:
        return None
    inner_options = dataclasses.replace(options, effects=inner_effects)
    inner_problem = build_problem(campaign, campaign_model(campaign, inner_options), options.noise,
                                  gap_prior_from_crossings=options.gap_prior_from_crossings)
    names = [r.name for r in campaign.runs]
    log.info("first the MAP without %s (its optimum is a start of the full fit)", ", ".join(nested))
    inner = fit_map(inner_problem, names, n_starts=options.n_starts, seed=seed, **options.map_budget)
    start = nested_start(problem, names, inner.u, inner_problem.names(names))
    if "gap_steps" in nested:
        start = gap_on_the_middle_step(problem, names, start)
    if "gap_relays" in nested:
        # two starts: the grid at its prior span with the relay nearest the held gap, and the
        # grid narrowed until its innermost symmetric relay (±a of the unit grid) is the held
        # gap exactly — on a measured baseline loop held ±0.1 N·m the first alone ended 79″
        # above the held gap's fit in sample
        hold = float(inner_problem.physics_values(jnp.asarray(inner.u))["gap_hold_torque"])
        relays = problem.model.backlash
        up = relays.unit_switches()[0]
        exact = moved_start(problem, start, relays.span_values(hold / float(np.min(up[up > 0]))))
        return np.stack([gap_on_the_held_relay(problem, names, s, hold) for s in (start, exact)])
    return start[None, :]


def gap_on_the_middle_step(problem, run_names, start: np.ndarray) -> np.ndarray:
    """``start`` (a start of ``problem``, whose gap is taken up in an odd number of steps) with
    the plain gap's shape: the middle step's logit three prior sds up (≈ 94 % of the gap at zero
    torque with seven steps), the others at their prior centre. From even shares alone the
    stepped fit of measured baseline loops stopped below the plain gap's optimum in sample,
    though it contains it (docs/validation.md)."""
    middle = _middle_step(problem.model)
    if middle is None:
        raise ValueError("gap_on_the_middle_step: the problem's gap is not taken up in an odd number of steps")
    start = np.array(start, float)
    j = problem.names(run_names).index(f"gap_step_logits[{middle - 1}]")
    start[j] = float(problem.prior_mean[j]) + 3.0 * float(problem.prior_sd[j])
    return start


def gap_on_the_held_relay(problem, run_names, start: np.ndarray, hold_Nm: float) -> np.ndarray:
    """``start`` (a start of ``problem``, whose gap is a :class:`~torsionfit.model.RelayGapBacklash`
    centred at the held gap's centre) with about the held gap's shape: 95 % of the gap
    (:meth:`~torsionfit.model.RelayGapBacklash.logits_on`, the rest shared evenly) on the relay of the grid nearest
    ``c ± hold_Nm`` at the start's span. Not the held gap itself, whose switches need not lie on
    the grid; from even shares, though, the fit starts from a gap smeared over the whole grid."""
    relays = problem.model.backlash
    names = problem.names(run_names)
    span = float(relays.span_Nm(problem.physics_values(np.asarray(start[:problem.n_nonlinear], float))))
    first = names.index("gap_relay_logits[0]")
    start = np.array(start, float)
    start[first:first + relays.n_relays - 1] = relays.logits_on(relays.nearest_relay(hold_Nm / span, -hold_Nm / span))
    return start


def moved_start(problem, u, values: dict) -> np.ndarray:
    """``u`` (a point of ``problem``) with the scalar physics parameters in ``values`` (name →
    SI value) moved there, the rest as they are."""
    start, i = np.array(u, float), 0
    for p in problem.physics:
        if p.name in values:
            if p.size != 1:
                raise ValueError(f"moved_start: {p.name} has {p.size} entries; only scalar parameters move")
            start[i] = float(tr.inverse(p.constraint, values[p.name]))
        i += p.size
    unknown = set(values) - {p.name for p in problem.physics}
    if unknown:
        raise ValueError(f"moved_start: the model has no parameter {', '.join(sorted(unknown))}")
    return start


def hold_mode_values(small_Nm: float, large_Nm: float) -> dict:
    """The hold mode's start from the smallest and largest cycles' readings (N·m): the friction
    level at the small cycles' reading, the hold at what the large cycles add to it."""
    return {"friction_torque": small_Nm, "gap_hold_torque": max(large_Nm - small_Nm, small_Nm)}


def hop_to_the_hold(campaign: Campaign, problem, map_result, options: FitOptions, seed: int):
    """``map_result``, or the optimum reached from it with the friction level moved to the
    smallest cycles' reading and the gap's hold to what the largest cycles add to it
    (:func:`~torsionfit.fit._prior.cycle_friction_readings_Nm`), whichever is higher; a model
    without a held gap, or data without cycles to read, keep ``map_result``.

    A held gap and friction that grows with the load both widen the large cycles; on measured
    preloaded loops the MAP had both modes and its starts found the friction one, though the
    hold one was higher (docs/validation.md). One more LM run from the optimum, not a search."""
    names = tuple(r.name for r in campaign.runs)
    readings = cycle_friction_readings_Nm(campaign)
    if readings is None or not {"friction_torque", "gap_hold_torque"} <= {p.name for p in problem.physics}:
        return map_result
    start = moved_start(problem, map_result.u, hold_mode_values(*readings))
    hopped = fit_map(problem, list(names), n_starts=0, seed=seed, warm_starts=start[None, :], **options.map_budget)
    log.info("hop to the hold: log posterior %.1f from the MAP's %.1f", hopped.log_density, map_result.log_density)
    return hopped if hopped.log_density > map_result.log_density else map_result


@in_float64
def fit_campaign(campaign: Campaign, options: FitOptions = FitOptions(), seed: int = 0) -> CampaignFit:
    """Fit ``campaign``; InputError on data that cannot be fitted."""
    campaign, model, problem = prepare_fit(campaign, options)
    warm = _nested_starts(campaign, options, problem, seed)
    log.info("MAP from %d starts, %d parameters (the first fit of a model shape compiles it first)",
             options.n_starts, problem.dim)
    map_result = fit_map(problem, [r.name for r in campaign.runs], n_starts=options.n_starts, seed=seed,
                         warm_starts=warm, **options.map_budget)
    if options.hop_to_the_hold:
        map_result = hop_to_the_hold(campaign, problem, map_result, options, seed)
    first = map_result  # the optima the starts reached, all under one objective
    if options.noise.cycle_class_noise:
        # the classes' noise levels read at this optimum, the fit repeated with them
        problem, map_result = refit_with_class_noise(problem, map_result, seed=seed, **options.map_budget)
    if options.misfit_inflation:
        problem, map_result = widen_for_misfit(problem, map_result)
    log.info("MAP %s; now the posterior (%s) and the metrics", "converged" if map_result.converged
             else f"not converged ({map_result.message})", options.sampler)
    # the other optima the starts reached (the MAP among them: the mixture drops what repeats it)
    others = [np.asarray(u) for _, u, converged in first.optima if converged] if options.optima_mixture else ()
    fit = finish_fit(campaign, options, model, problem, map_result, seed, other_optima=others)
    _record_rival_optima(fit.diagnostics, first, problem, map_result)
    return fit


def _record_rival_optima(diagnostics: dict, first, problem, map_result) -> None:
    """The other optima the starts reached (fit/_map.py :func:`rival_optima`), scored in the
    starts' problem, their distance in the final posterior's sd; a note (and a warning) when one
    the data support about as well lies beyond the intervals' reach."""
    n = problem.n_nonlinear
    rivals = rival_optima(first.u, first.log_density, first.optima, np.asarray(map_result.cov)[:n, :n],
                          float(problem.likelihood_power))
    diagnostics["map_other_optima"] = rivals
    note = rival_note(rivals)
    if note:
        diagnostics["map_rival_note"] = note
        warnings.warn(note)


def sampler_kwargs(options: FitOptions, seed: int) -> dict:
    """The keyword arguments of ``run_sampler`` for a fit with ``options`` and ``seed``."""
    return {"seed": seed, "n_walkers": options.n_walkers, "max_steps": options.max_steps, "progress": options.progress,
            "backend_path": options.backend_path, "resume": options.resume}


SAMPLERS = ("auto", "emcee", "nuts", "smc", "laplace")
#: emcee's check interval under ``--sampler auto`` (emcee's own default: 500)
AUTO_CHECK_EVERY = 250


def nuts_kwargs(options: FitOptions, seed: int) -> dict:
    """The keyword arguments of ``run_nuts`` for a fit with ``options`` and ``seed`` (its
    resume file next to emcee's: ``chain.h5`` → ``chain-nuts.npz``)."""
    path = None
    if options.backend_path is not None:
        path = str(Path(options.backend_path).with_name(Path(options.backend_path).stem + "-nuts.npz"))
    return {"seed": seed, "n_chains": options.n_chains, "n_warmup": options.n_warmup, "max_draws": options.max_draws,
            "progress": options.progress, "backend_path": path, "resume": options.resume}


def auto_switch_rule(max_steps: int, tau_factor: float = 50.0):
    """The rule of ``--sampler auto``, called by emcee at every check with (steps so far, τ
    per parameter): a reason to leave emcee for NUTS when the chain it needs —
    ``tau_factor`` · τ_max steps — is longer than the step budget, by either of

    - the estimate now: ``tau_factor`` · τ_max > ``max_steps`` (τ estimated on the chain so far,
      an estimate that grows with the chain, so this errs on emcee's side);
    - the estimate's trend over the last two checks: while a chain is much shorter than τ, the
      estimate grows about in proportion to the chain (measured on data/paper-small: τ_max ≈
      61, 133, 205, 271 at 500, 1000, 1500, 2000 steps, then past the budget at 3500). Along
      the power law through the two checks, τ(n) = τ_k (n / n_k)^p, the chain reaches
      ``tau_factor`` · τ(n) at n* = (``tau_factor`` τ_k / n_k^p)^(1 / (1 − p)), or never when
      p ≥ 1; the rule leaves when n* is beyond the budget. A resolved τ hardly grows (p near
      0: n* is about ``tau_factor`` τ_k), so a chain that converges within the budget stays."""
    last = {}

    def rule(n_steps: int, tau: np.ndarray) -> str | None:
        tau_max = float(np.max(tau))
        need = tau_factor * tau_max
        prev = last.copy()
        last.update(n=n_steps, tau=tau_max)
        if need > max_steps:
            what = "never moved" if not np.isfinite(tau_max) else f"τ_max = {tau_max:.0f} steps"
            return (f"emcee after {n_steps} steps: {what}, so convergence needs "
                    f"{tau_factor:g} × τ_max = {need:.0f} steps, more than the budget of {max_steps}")
        if not prev or n_steps <= prev["n"] or not 0 < prev["tau"] < tau_max:
            return None
        power = math.log(tau_max / prev["tau"]) / math.log(n_steps / prev["n"])
        if power < 1.0:
            n_star = (need / n_steps**power) ** (1.0 / (1.0 - power))
            if n_star <= max_steps:
                return None
            reach = (f"only after about {n_star:.0f} steps" if n_star < 100 * max_steps
                     else f"only after more than {100 * max_steps} steps")
        else:
            reach = "never"
        return (f"emcee after {n_steps} steps: τ_max grew from {prev['tau']:.0f} to {tau_max:.0f} steps since "
                f"step {prev['n']} (as steps^{power:.2f}), so along that trend the chain reaches "
                f"{tau_factor:g} × τ_max {reach}, beyond the budget of {max_steps}")

    return rule


@in_float64
def run_smc(problem, map_result, options: FitOptions, seed: int, other_optima=()):
    """Tempered SMC (:func:`~torsionfit.sample.tempered_smc`) from the split normal along the
    Laplace axes to ``problem``'s posterior (widened, when it is), ``options.smc_particles``
    particles moved by HMC (the posterior's gradient by JAX, in chunks of
    :data:`GRADIENT_BATCH`); the state is kept after every stage where ``options.backend_path``
    keeps a chain (:func:`smc_checkpoint_path`), and ``options.resume`` goes on from it. With ``options.optima_mixture`` the particles start from the mixture
    over ``other_optima`` and the MAP's (:func:`optima_mixture`), in every optimum by its weight."""
    from ..sample import tempered_smc
    from ..sample._emcee import _LogProb, _LogProbGrad

    approximation = laplace_approximation(problem, map_result, "split")
    if options.optima_mixture:
        approximation, _ = optima_mixture(problem, map_result, approximation, other_optima)
    log_density = _LogProb(problem, batch=LOG_DENSITY_BATCH)
    names = tuple(getattr(map_result, "names", None) or (f"u[{i}]" for i in range(len(map_result.u))))
    return tempered_smc(log_density, approximation, np.random.default_rng(seed), options.smc_particles,
                        log_p_and_grad=_LogProbGrad(problem, batch=GRADIENT_BATCH), names=names, seed=seed,
                        max_moves=options.smc_max_moves,
                        final_max_moves=max(options.smc_final_max_moves, options.smc_max_moves),
                        progress=log.info if options.progress else None,
                        checkpoint=smc_checkpoint_path(options), resume=options.resume)


def smc_checkpoint_path(options: FitOptions) -> str | None:
    """SMC's checkpoint file under ``options`` (next to emcee's chain: ``chain.h5`` →
    ``chain-smc.npz``), None when no chain is kept."""
    if options.backend_path is None:
        return None
    return str(Path(options.backend_path).with_name(Path(options.backend_path).stem + "-smc.npz"))


def sample_posterior(problem, map_result, options: FitOptions, seed: int, other_optima=()):
    """(sample result, sampler used, reason of the choice) for the MCMC samplers.

    ``auto``: emcee with :func:`auto_switch_rule` checked at every 500-step check; when it
    fires — or emcee ends unconverged anyway — NUTS from the same Laplace start. The emcee
    run's own τ and steps are in the reason."""
    from ..sample import run_nuts, run_sampler

    if options.sampler == "emcee":
        return run_sampler(problem, map_result, **sampler_kwargs(options, seed)), "emcee", "asked for (--sampler emcee)"
    if options.sampler == "nuts":
        return run_nuts(problem, map_result, **nuts_kwargs(options, seed)), "nuts", "asked for (--sampler nuts)"
    if options.sampler == "smc":
        return run_smc(problem, map_result, options, seed, other_optima), "smc", "asked for (--sampler smc)"
    with warnings.catch_warnings():
        from ..sample import ConvergenceWarning

        warnings.simplefilter("ignore", ConvergenceWarning)  # a switch to NUTS is not a failure
        # checks every AUTO_CHECK_EVERY steps, so that the rule's trend (two checks) is read
        # after 2 × AUTO_CHECK_EVERY steps: on a dense measured loop (34 359 samples) each emcee
        # step costs ~75 ms, and 500 steps more before NUTS were a seventh of the whole fit
        first = run_sampler(problem, map_result, **sampler_kwargs(options, seed), check_every=AUTO_CHECK_EVERY,
                            stop_when=auto_switch_rule(options.max_steps))
    if first.converged:
        return first, "emcee", (f"auto: emcee converged in {first.n_steps} steps "
                                f"(τ_max = {first.tau_max:.1f}, within the budget of {options.max_steps})")
    why = first.reason if first.stopped_early else f"emcee did not converge: {first.reason}"
    res = run_nuts(problem, map_result, **nuts_kwargs(options, seed))
    res = dataclasses.replace(res, preceded_by={"sampler": "emcee", "n_steps": int(first.n_steps),
                                                "n_walkers": int(first.n_walkers), "tau_max": float(first.tau_max)})
    return res, "nuts", f"auto: NUTS, because {why}"


def _sampler_diagnostics(sample_result, used: str, conv: dict, chain: np.ndarray) -> dict:
    """fit.json's diagnostics of an emcee, NUTS or SMC run; ``conv``: R̂ and ESS over all its
    kept draws (``convergence_summary``)."""
    if used == "smc":
        # converged: the tempering reached the posterior and every stage's moves decorrelated
        # the particles from where resampling put them (sample/_smc.py); one chain of particles
        return {
            "converged": bool(sample_result.converged),
            "rhat_max": None,
            "ess_min": float(chain.shape[0]),
            "smc_particles": int(chain.shape[0]),
            "smc_max_moves": [int(m) for m in sample_result.stage_max_moves],
            "smc_betas": [float(b) for b in sample_result.betas],
            "smc_moves": [int(m) for m in sample_result.stage_moves],
            "smc_acceptance": [float(a) for a in sample_result.stage_acceptance],
            "smc_correlation_max": float(max(sample_result.stage_correlation, default=0.0)),
            "smc_step_size": [float(h) for h in sample_result.stage_step_size],
            "smc_leapfrog_steps": [float(s) for s in sample_result.stage_leapfrog_steps],
            "smc_correlation_floor": float(sample_result.correlation_floor),
            "smc_modes": [int(k) for k in sample_result.stage_modes],
            "smc_mode_shares": [float(s) for s in sample_result.mode_shares],
            "smc_moves_kind": sample_result.moves,
            "approximation_pareto_k": float(sample_result.approximation_pareto_k),
            "reason": sample_result.reason or "",
        }
    if used == "nuts":
        # the rule (R̂ ≤ 1.01, bulk and tail ESS ≥ 400 for every entry of u, no divergence)
        # was checked on u by run_nuts; R̂ and ESS are rank based, so they hold for the
        # physical values (monotone maps of u) alike
        return {
            "converged": bool(sample_result.converged),
            "rhat_max": conv["rhat_max"],
            "ess_min": conv["ess_min"],
            "ess_tail_min": float(np.nanmin(sample_result.ess_tail)),
            "n_divergent": sample_result.n_divergent,
            "tau_max": float(np.max(sample_result.tau)),
            "n_steps": int(sample_result.n_steps),
            "n_warmup": int(sample_result.n_warmup),
            "n_chains": int(chain.shape[1]),
            "n_draws": int(chain.shape[0]),
            "n_grad_evals": int(sample_result.n_grad_evals),
            "step_size": [float(x) for x in sample_result.step_size],
            "mean_tree_depth": float(np.mean(sample_result.tree_depth)),
            "reason": sample_result.reason or "",
        }
    return {
        # emcee's own rule includes R̂ ≤ 1.01 and ESS ≥ 400 on u (sample/_convergence.py)
        "converged": bool(sample_result.converged),
        "rhat_max": conv["rhat_max"],
        "ess_min": conv["ess_min"],
        "tau_max": float(np.max(sample_result.tau)),
        "n_steps": int(sample_result.n_steps),
        "n_walkers": int(chain.shape[1]),
        "reason": sample_result.reason or "",
    }


@in_float64
def _laplace_tree(problem, map_result, draws_u, names, specs, metric_draws, campaign, seed, approximation=None):
    """The ArviZ tree of Laplace draws ``draws_u`` (one chain) with their metrics; drawn from
    ``approximation`` (a split normal) when given, else from the Gaussian."""
    from ..sample import laplace_result, to_datatree

    result = laplace_result(problem, map_result, draws_u, problem.names(names), seed=seed, approximation=approximation)
    return to_datatree(problem, result, names, metric_specs=specs, metric_draws=metric_draws, campaign=campaign,
                       seed=seed)


LAPLACE_SHAPES = ("gaussian", "split")
#: draws per call of the batched log density that measures the split normal and checks the
#: draws against the posterior: one batch shape, one compiled program for both
LOG_DENSITY_BATCH = 256
#: particles per call of the batched log density and gradient (SMC's HMC moves): on a measured
#: loop (block means of 16 samples) 64 of them took 0.07 s
GRADIENT_BATCH = 64


@in_float64
def laplace_approximation(problem, map_result, shape: str):
    """None for the Gaussian Laplace approximation; for ``shape="split"`` the
    :class:`~torsionfit.sample.SplitNormal` measured on ``problem``'s log density along the axes
    of ``map_result.cov``."""
    if shape not in LAPLACE_SHAPES:
        raise InputError(f"laplace shape must be one of {', '.join(LAPLACE_SHAPES)}, got {shape!r}")
    if shape == "gaussian":
        return None
    from ..sample import split_normal
    from ..sample._emcee import _LogProb

    log_density = _LogProb(problem, batch=LOG_DENSITY_BATCH)
    centre = np.asarray(map_result.u, float)
    if problem.likelihood_power < 1.0:
        # a widened posterior's mode is not the MAP: with the likelihood tempered the prior weighs
        # more (on measured loops the gap's closing torque and the torque knots move towards it,
        # by up to several Laplace sds) — the split normal is centred where its density peaks
        moved = np.asarray(_tempered_mode(problem, jnp.asarray(centre)), float)
        if np.all(np.isfinite(moved)) and log_density(moved[None])[0] > log_density(centre[None])[0]:
            centre = moved
    return split_normal(log_density, centre, map_result.cov)


#: two optima closer than this many posterior sd (either's) are one component of the mixture
MIXTURE_SAME_SD = 3.0
#: an optimum below the MAP's widened log posterior by more than this is not tried (its weight
#: would be below e⁻¹⁰ of the MAP's for components of about equal volume)
MIXTURE_MAX_GAP = 10.0
#: a component whose weight ends below this is dropped (and the weights renormalised)
MIXTURE_MIN_WEIGHT = 1e-3


def _physics_distance_sd(a, b, cov_physics) -> float:
    d = np.asarray(a, float)[: len(cov_physics)] - np.asarray(b, float)[: len(cov_physics)]
    return float(np.sqrt(max(d @ np.linalg.pinv(cov_physics) @ d, 0.0)))


@in_float64
def optima_mixture(problem, map_result, main, other_optima):
    """(:class:`~torsionfit.sample.SplitNormalMixture`, rows): ``main`` (the MAP's split normal)
    beside a split normal at each other optimum in ``other_optima`` (unconstrained points of the
    starts' problem), weighted by their Laplace evidence. Each is moved to the mode of ``problem``
    (widened, when it is) from its physics block with the MAP's noise block, its covariance the
    tempered Laplace one there; one within :data:`MIXTURE_SAME_SD` of a kept component, more than
    :data:`MIXTURE_MAX_GAP` below the MAP or whose weight ends below :data:`MIXTURE_MIN_WEIGHT` is
    left out. ``rows``: per kept component its weight, log posterior below the MAP's component and
    distance from it in the MAP's posterior sd."""
    from ..fit._misfit import tempered_physics_covariance
    from ..sample import SplitNormalMixture, evidence_log_weights, split_normal
    from ..sample._emcee import _LogProb

    log_density = _LogProb(problem, batch=LOG_DENSITY_BATCH)
    n = problem.n_nonlinear
    factor = 1.0 / float(problem.likelihood_power)
    components = [main]
    covs = [np.asarray(map_result.cov, float)[:n, :n]]
    top = float(log_density(main.mean[None])[0])
    for u in other_optima:
        start = np.array(map_result.u, float)
        start[:n] = np.asarray(u, float)[:n]
        if float(log_density(start[None])[0]) < top - 3.0 * MIXTURE_MAX_GAP:
            continue  # far below even before the move to the widened mode: not worth the search
        mode = np.asarray(_tempered_mode(problem, jnp.asarray(start)), float)
        lp = float(log_density(mode[None])[0]) if np.all(np.isfinite(mode)) else -np.inf
        if not np.isfinite(lp) or lp < top - MIXTURE_MAX_GAP:
            continue
        if any(min(_physics_distance_sd(mode, c.mean, cv), _physics_distance_sd(c.mean, mode, cv)) < MIXTURE_SAME_SD
               for c, cv in zip(components, covs)):
            continue  # the same optimum as a kept one
        cov = np.array(map_result.cov, float)
        cov[:n, :n] = tempered_physics_covariance(problem, mode, factor)
        components.append(split_normal(log_density, mode, cov))
        covs.append(cov[:n, :n])
    centres = np.stack([c.mean for c in components])
    lps = np.asarray(log_density(centres), float)
    lqs = np.array([c.log_density(c.mean[None])[0] for c in components])
    log_w = evidence_log_weights(lps, lqs)
    keep = [0] + [i for i in range(1, len(components)) if np.exp(log_w[i]) >= MIXTURE_MIN_WEIGHT]
    log_w = evidence_log_weights(lps[keep], lqs[keep])
    rows = [{"weight": float(np.exp(w)), "log_density_gap": float(lps[0] - lps[i]),
             "distance_sd": _physics_distance_sd(centres[i], centres[0], covs[0])} for w, i in zip(log_w, keep)]
    return SplitNormalMixture(tuple(components[i] for i in keep), log_w), rows


@in_float64
def approximation_pareto_k(problem, map_result, approximation, draws_u) -> float:
    """Pareto k̂ of the posterior/approximation density ratios at ``draws_u``, drawn from
    ``approximation`` (a split normal) or, when None, from the Gaussian N(MAP, cov)
    (:func:`~torsionfit.sample.importance_pareto_k`)."""
    from ..sample import importance_pareto_k
    from ..sample._emcee import _LogProb
    from ..sample._laplace import _gaussian_log_density

    draws_u = np.asarray(draws_u, float)
    log_p = _LogProb(problem, batch=LOG_DENSITY_BATCH)(draws_u)
    if approximation is not None:
        log_q = approximation.log_density(draws_u)
    else:
        log_q = _gaussian_log_density(draws_u, np.asarray(map_result.u, float), np.asarray(map_result.cov, float))
    return importance_pareto_k(log_p, log_q)


def pareto_k_note(k: float, n_draws: int) -> str:
    """A line when the Laplace draws do not stand for the posterior (k̂ above the PSIS
    threshold for ``n_draws``, or not defined); empty otherwise."""
    from ..sample import good_k

    limit = good_k(n_draws)
    if k <= limit:
        return ""
    k_text = f"{k:.2f}" if np.isfinite(k) else "undefined"
    return (f"the draws do not stand for the posterior: Pareto k of the posterior/approximation density ratios at them "
            f"{k_text}, above {limit:.2f} (the posterior has mass where the approximation has little); the intervals are "
            "the approximation's — emcee or NUTS (--sampler) sample the posterior itself")


@eqx.filter_jit
def _tempered_mode(problem, u):
    """The mode of ``problem``'s log density (a widened one) by BFGS from ``u``."""
    import optimistix as optx

    sol = optx.minimise(lambda x, _: -problem.log_density(x), optx.BFGS(rtol=1e-8, atol=1e-8), u,
                        max_steps=1000, throw=False)
    return sol.value


def _mark_not_converged(diagnostics: dict, key: str, runs, reason: str) -> None:
    """A fit that does not draw the data: ``runs`` under ``key``, not converged, ``reason``
    first in the reason, and a warning."""
    from ..sample import ConvergenceWarning

    diagnostics[key] = runs
    diagnostics["converged"] = False
    diagnostics["reason"] = "; ".join(x for x in (reason, diagnostics.get("reason", "")) if x)
    warnings.warn(reason, ConvergenceWarning)


@in_float64
def finish_fit(campaign: Campaign, options: FitOptions, model, problem, map_result, seed: int,
               sample_result=None, other_optima=()) -> CampaignFit:
    """Everything after the MAP: posterior (emcee or Laplace draws), derived metrics, RMSE —
    for a ``map_result`` of ``problem`` (``prepare_fit``) found one unit at a time or many at
    once (``torsionfit.batch``). ``sample_result``: the emcee run of ``run_sampler`` with
    ``sampler_kwargs(options, seed)``, when it was made already (the batch samples many units
    together); else it is made here (:func:`sample_posterior`). ``other_optima``: unconstrained
    points of the other optima the starts reached, for ``options.optima_mixture``."""
    names = [r.name for r in campaign.runs]
    rng = np.random.default_rng(seed)
    if options.sampler not in SAMPLERS:
        raise InputError(f"sampler must be one of {', '.join(SAMPLERS)}, got {options.sampler!r}")
    from ..sample import convergence_summary, draw_thinning, pointwise_draw_limit, to_datatree

    # draws the ArviZ tree can hold with its pointwise log-likelihood and predictive
    tree_limit = pointwise_draw_limit(sum(len(y) for y in problem.y))
    if options.sampler != "laplace":
        if sample_result is None:
            sample_result, used, choice = sample_posterior(problem, map_result, options, seed, other_optima)
        else:
            used, choice = sample_result.sampler, "sampled with the other units of its shape (batch)"
        chain = np.asarray(sample_result.chain)
        draws_u = chain.reshape(-1, chain.shape[-1])
        n_draw, n_chain = chain.shape[:2]
        # the metrics of every k-th draw of each chain (at most metric_draws in all); the tree
        # keeps every j·k-th of them (within its size limit), so its metrics are the same numbers
        k_metric = draw_thinning(n_chain, n_draw, options.metric_draws)
        metric_grid = np.arange(0, n_draw, k_metric)
        tree_grid = np.arange(0, n_draw, draw_thinning(n_chain, n_draw, tree_limit, step=k_metric))
        pick = (metric_grid[None, :] * n_chain + np.arange(n_chain)[:, None]).ravel()  # chain by chain
        diagnostics = {"sampler": used, "sampler_choice_reason": choice}
    else:
        approximation = laplace_approximation(problem, map_result, options.laplace_shape)
        mixture_rows = None
        if options.optima_mixture:
            if approximation is None:
                raise InputError("optima_mixture needs laplace_shape='split' (a split normal per optimum)")
            approximation, mixture_rows = optima_mixture(problem, map_result, approximation, other_optima)
        # a widened posterior (misfit) is where the Gaussian fails: its half-axes measured
        # anyway, to say so when the Gaussian's draws are used
        measured = getattr(approximation, "main", approximation)
        if approximation is None and problem.likelihood_power < 1.0:
            measured = laplace_approximation(problem, map_result, "split")
        if approximation is None:
            cov = 0.5 * (map_result.cov + map_result.cov.T)
            draws_u = rng.multivariate_normal(map_result.u, cov, size=options.laplace_draws, method="eigh")
        else:
            draws_u = approximation.draw(rng, options.laplace_draws)
        diagnostics = {
            "sampler": "laplace",
            "laplace_shape": options.laplace_shape,
            # the split normal's half-axis widths over the Laplace ones (1: the Gaussian holds)
            "laplace_scale_range": None if measured is None else [float(np.min(measured.scales)),
                                                                     float(np.max(measured.scales))],
            "converged": bool(map_result.converged),
            "rhat_max": None,
            "ess_min": float(options.laplace_draws),
            "reason": "" if map_result.converged else f"MAP did not converge: {map_result.message}",
        }
        if mixture_rows is not None:
            diagnostics["laplace_optima"] = mixture_rows
        pick = rng.choice(len(draws_u), size=min(options.metric_draws, len(draws_u)), replace=False)
        if measured is not None:
            # where the posterior's shape was measured (widened, or split drawn): do the draws stand
            # for it? The same compiled log density as the measurement's, at the metrics' draws
            k = approximation_pareto_k(problem, map_result, approximation, draws_u[pick])
            diagnostics["laplace_pareto_k"] = k
            k_note = pareto_k_note(k, len(pick))
            if k_note:
                diagnostics["laplace_pareto_k_note"] = k_note
                warnings.warn(k_note)
        note = laplace_note(measured, options.laplace_shape, problem.n_nonlinear)
        if note:
            diagnostics["laplace_note"] = note
            warnings.warn(note)
    diagnostics["map_converged"] = bool(map_result.converged)
    # 1: the posterior as the likelihood gives it; k > 1: widened for misfit (fit/_misfit.py)
    diagnostics["misfit_inflation"] = float(1.0 / problem.likelihood_power)
    diagnostics["map_message"] = map_result.message
    # not converged: how far the optimum is, in posterior sd (fit/_map.py newton_step)
    diagnostics["map_newton_step_sd"] = map_result.newton_step_sd
    near_bound = {names[r]: rho for r, rho in misfit_correlated_runs(problem, map_result.u).items()}
    diagnostics["ar1_misfit_runs"] = near_bound
    if options.noise.cycle_class_noise:
        # noise level of each cycle class over the largest cycles', per run (fit/_noise_classes.py)
        diagnostics["noise_class_shares"] = dict(zip(names, class_shares(problem)))
    if problem.likelihood_keep is not None:
        # samples that drove the model's state but were out of the likelihood, per run
        diagnostics["conditioning_samples"] = {n: int(np.sum(~k)) for n, k in zip(names, problem.kept_samples())}
    if near_bound:
        diagnostics["noise_note"] = noise_note(near_bound)
    # rounding that is most of the angle's error repeats with the loop (fit/_quantisation.py)
    below = runs_below_the_encoder_step(problem, map_result.u, names)
    if below:
        diagnostics["quantisation_runs"] = below
        diagnostics["quantisation_note"] = quantisation_note(below)
        warnings.warn(diagnostics["quantisation_note"])
    # a parameter the runs do not see keeps its prior's width: its value is the prior's
    diagnostics["prior_dominated"] = prior_dominated(problem, draws_u)
    note = prior_dominated_note(diagnostics["prior_dominated"], problem)
    if note:
        diagnostics["prior_dominated_note"] = note
        warnings.warn(note)

    derived = derived_metrics_for(campaign, model, options.lost_motion_pct)
    linear = derived.reads_linear()
    values = map_chunks(lambda u: _values_over_draws(problem, u, linear), draws_u[pick])
    all_metric_draws = np.asarray(derived.over_draws(values))
    # a metric its definition reads off no draw, or off fewer than half of them (the loading
    # slope of a record whose largest cycles have no branch beyond the play, …), is left out
    # with a note rather than every metric with it, or the draws it happens to read
    read_share = np.mean(np.isfinite(all_metric_draws), axis=0)
    readable = read_share >= 0.5
    specs = tuple(s for s, ok in zip(derived.specs, readable) if ok)
    unread = derived.not_read_notes()
    if not readable.all():
        unread |= unreadable_notes({s.name: share for s, ok, share in zip(derived.specs, readable, read_share) if not ok},
                                   campaign, len(all_metric_draws))
        all_metric_draws = all_metric_draws[:, readable]
    if unread:
        diagnostics["metrics_not_computed"] = unread
        warnings.warn("metrics not computed: " + "; ".join(f"{k}: {v}" for k, v in unread.items()))
    bad = ~np.all(np.isfinite(all_metric_draws), axis=1)
    if bad.any():
        warnings.warn(f"{bad.sum()} of {len(bad)} draws gave non-finite metrics and were dropped")
    metric_draws = all_metric_draws[~bad]
    metric_values = {k: np.asarray(v)[~bad] for k, v in values.items()}

    if options.sampler == "laplace":
        # the first of the metrics' (independent) draws, as one chain, when first asked for
        n_tree = min(len(pick), tree_limit)
        tree = functools.partial(_laplace_tree, problem, map_result, draws_u[pick[:n_tree]], names,
                                 specs, all_metric_draws[None, :n_tree], campaign, seed, approximation)
    else:
        tree_metrics = all_metric_draws.reshape(n_chain, len(metric_grid), -1)[:, np.searchsorted(metric_grid, tree_grid)]
        tree = to_datatree(problem, sample_result, names, draws=tree_grid, metric_specs=specs,
                           metric_draws=tree_metrics, campaign=campaign, seed=seed)
        diagnostics.update(_sampler_diagnostics(sample_result, used, convergence_summary(tree), chain))
    residuals = _residuals(problem, jnp.asarray(map_result.u))
    rmse = {n: float(np.sqrt(np.mean(np.asarray(e) ** 2)) / ARCSEC) for n, e in zip(names, residuals)}
    # "converged" is the optimiser's and the sampler's word; whether the fit draws the data is
    # checked apart (report/_follows.py): a fit worse than a straight line is never a result
    not_followed = runs_not_followed(campaign.runs, residuals)
    diagnostics["follows_data"] = not not_followed
    if not_followed:
        _mark_not_converged(diagnostics, "not_followed", not_followed, not_followed_reason(not_followed))
    if options.sampler != "laplace" and not not_followed:
        left = runs_left_by_posterior(campaign.runs, _residuals(problem, jnp.asarray(np.median(draws_u, axis=0))),
                                      residuals)
        diagnostics["posterior_follows_data"] = not left
        if left:
            _mark_not_converged(diagnostics, "left_by_posterior", left, left_by_posterior_reason(left))
    return CampaignFit(campaign=campaign, options=options, problem=problem, map_result=map_result,
                       draws_u=np.asarray(draws_u), metric_specs=specs, metric_draws=metric_draws,
                       diagnostics=diagnostics, rmse_arcsec=rmse, tree_source=tree, sample_result=sample_result,
                       metric_values=metric_values, seed=seed)


def metrics_against_data(fit: CampaignFit) -> tuple[dict, list[str]]:
    """fit.json's ``metrics`` (name → mean, sd, 95 % HDI, unit, description; with ``"data"``
    where the data read the metric directly, ``report/_against_data.py``) and the names whose
    HDI misses the data's own reading."""
    metrics = {}
    for spec, col in zip(fit.metric_specs, fit.metric_draws.T):
        entry = {**summarise(col), "unit": spec.unit, "description": spec.description}
        if spec.condition:
            entry["condition"] = spec.condition
        metrics[spec.name] = entry
    return metrics, against_data(metrics, data_readings(fit.campaign))


def fit_json(fit: CampaignFit, command: str | None = None) -> dict:
    """The ``fit.json`` document (DESIGN §5.2); ``command``: the command line that made it."""
    metrics, off = metrics_against_data(fit)
    components = {k: metrics[k] for k in metrics if k.startswith("twist_")}
    diagnostics = dict(fit.diagnostics)
    diagnostics["metrics_off_data"] = off
    if off:
        diagnostics["metrics_off_data_note"] = off_data_note(metrics, off)
    problem = fit.problem
    params = {}
    for name, col in zip(problem.names(fit.run_names), fit.draws_u.T):
        params[name] = col
    physics = {}
    i = 0
    from ..fit._transform import forward

    for p in problem.physics:
        for j in range(p.size):
            key = p.name if p.size == 1 else f"{p.name}[{j}]"
            physics[key] = {**summarise(np.asarray(forward(p.constraint, jnp.asarray(fit.draws_u[:, i])))),
                            "unit": p.unit, "description": p.description}
            i += 1
    means = {k: v["mean"] for k, v in physics.items()}  # the physical checks read the posterior mean
    hysteresis = fit.campaign.hysteresis_runs
    if hysteresis:
        # at the posterior mean and the largest load any loop reaches
        peak = max(float(np.max(np.abs(r.torque_Nm))) for r in hysteresis)
        hook = dahl_hook_note(problem.model.friction, means, peak)
        if hook:
            diagnostics["friction_hook_note"] = hook
        relays = problem.model.backlash
        if isinstance(relays, RelayGapBacklash):
            logits = np.array([means[f"gap_relay_logits[{j}]"] for j in range(relays.n_relays - 1)])
            relay = relay_gap_note(relays, {**means, "gap_relay_logits": logits},
                                   min(float(np.min(r.torque_Nm)) for r in hysteresis),
                                   max(float(np.max(r.torque_Nm)) for r in hysteresis))
            if relay:
                diagnostics["relay_gap_note"] = relay
    segment = gap_segment_note(problem.model.compliance, means, metrics.get("gap_with_first_segment", {}).get("hdi95"))
    if segment:
        diagnostics["gap_segment_note"] = segment
    return {
        "campaign": str(fit.campaign.path) if fit.campaign.path else None,
        "label": fit.campaign.notes,
        "reducer": {"name": fit.campaign.reducer.name, "rated_torque_Nm": fit.campaign.reducer.rated_torque_Nm},
        "decimate": fit.options.decimate,
        "model": {"effects": sorted(fit.options.effects), "components": ["elastic", "friction", "geometric"]
                  + (["creep"] if problem.model.creep is not None else [])},
        "metrics": metrics,
        "components": components,
        "parameters": physics,
        "diagnostics": diagnostics,
        "rmse": {name: {"value": v, "unit": "arcsec"} for name, v in fit.rmse_arcsec.items()},
        **_runs_json(fit.campaign, problem.model.temperature is not None),
        "provenance": provenance(fit.seed, command),
    }


def _runs_json(campaign, temperature_term: bool) -> dict:
    """The fitted runs' conditions: kind, temperature (°C: the manifest's ``temperature_C``,
    else the median of the run's temperature column; None when neither is given), the notes
    of its reading (a column negated or unwrapped, a pad dropped) and, for TE
    runs, load, speed, direction and zero group; the distinct temperatures the fit spans; and,
    when the model has the temperature term, the reference temperature its metrics are at."""
    runs = {}
    for run in campaign.runs:
        entry = {"kind": run.kind, "temperature_C": campaign.run_temperature_C(run), "reading": list(run.notes)}
        if run.kind == "transmission_error":
            entry |= {"torque_Nm": run.torque_Nm, "speed_rpm": run.speed_rpm,
                      "direction": "forward" if run.direction > 0 else "backward", "zero_group": run.zero_group}
        runs[run.name] = entry
    temperatures = sorted({t for t in map(campaign.run_temperature_C, campaign.runs) if t is not None})
    return {"runs": runs, "temperatures_C": temperatures,
            "reference_temperature_C": campaign.reference_temperature_C if temperature_term else None}


def noise_note(near_bound: dict) -> str:
    """What an AR(1) coefficient near its bound on hysteresis runs means, and what to try."""
    runs = ", ".join(f"{k} (ρ {v:.3f})" for k, v in near_bound.items())
    return (f"AR(1) coefficient ≥ {MISFIT_RHO} on {runs}: a correlation that long is rather the model's misfit "
            "than the bench's noise, and the fit then follows the loop's increments more than its level; "
            "compare with --ar1 off (iid noise, the posterior widened for misfit), the setting validated on measured loops")


#: half-axis widths over the Gaussian's outside this range: the Gaussian does not hold
GAUSSIAN_SCALE_RANGE = (0.5, 2.0)


def laplace_note(measured, shape: str, n_physics: int) -> str:
    """A line when the Gaussian's draws stand for a posterior the split normal ``measured`` (or
    None) found far from Gaussian along an axis of the physics (the first ``n_physics`` entries
    of u carry most of it; the noise block's asymptotic variances are rough even on a bench);
    empty otherwise, and when the split normal draws."""
    if measured is None or shape != "gaussian":
        return ""
    lo, hi = GAUSSIAN_SCALE_RANGE
    physics = np.linalg.norm(measured.axes[:n_physics], axis=0) > np.sqrt(0.5)
    scales = measured.scales[physics]
    off = (scales < lo) | (scales > hi)
    if not off.any():
        return ""
    return (f"the widened posterior is not Gaussian: along {int(off.any(axis=1).sum())} of its {len(off)} physics axes "
            f"(Laplace) a half-width is {float(scales.min()):.2f}–{float(scales.max()):.2f} × the Gaussian's; "
            "the draws are the Gaussian's and land where the posterior has little mass; "
            "--laplace-shape split draws from the split normal measured along these axes")


def summary_table(doc: dict) -> str:
    """One screen: the headline metrics with 95 % HDIs, the diagnostics, RMSE per run."""
    lines = [f"{doc['reducer']['name']}  ({doc['label']})" if doc.get("label") else doc["reducer"]["name"]]
    lines.append(f"{'metric':34s} {'mean':>11s} {'sd':>9s}   {'95 % HDI':>23s}  unit")
    for name, e in doc["metrics"].items():
        lo, hi = e["hdi95"]
        lines.append(f"{name:34s} {e['mean']:11.5g} {e['sd']:9.3g}   [{lo:10.5g}, {hi:10.5g}]  {e['unit']}")
    d = doc["diagnostics"]
    # Laplace draws around the MAP: its "converged" is the optimiser's, not a sampler's
    conv = ("MAP converged" if d["sampler"] == "laplace" else "converged") if d["converged"] \
        else f"NOT CONVERGED ({d.get('reason', '')})"
    rhat = "n/a" if d.get("rhat_max") is None else f"{d['rhat_max']:.3f}"
    ess = "n/a" if d.get("ess_min") is None else f"{d['ess_min']:.0f}"
    extra = f", {d['n_divergent']} divergent" if "n_divergent" in d else ""
    lines.append(f"sampler {d['sampler']}: {conv}; R-hat max {rhat}, ESS min {ess}{extra}")
    if d.get("sampler_choice_reason"):
        lines.append(f"sampler choice: {d['sampler_choice_reason']}")
    if d.get("noise_note"):
        lines.append(f"noise: {d['noise_note']}")
    if d.get("quantisation_note"):
        lines.append(f"noise: {d['quantisation_note']}")
    if d.get("conditioning_samples"):
        # the RMSE below counts them; the likelihood does not
        shown = ", ".join(f"{k} {v}" for k, v in d["conditioning_samples"].items())
        lines.append(f"conditioning (out of the likelihood, in the RMSE): {shown} samples")
    if d.get("prior_dominated_note"):
        lines.append(f"prior: {d['prior_dominated_note']}")
    if d.get("laplace_note"):
        lines.append(f"laplace: {d['laplace_note']}")
    if d.get("laplace_pareto_k_note"):
        lines.append(f"laplace: {d['laplace_pareto_k_note']}")
    if d.get("map_rival_note"):
        lines.append(f"optima: {d['map_rival_note']}")
    if d.get("metrics_off_data_note"):
        lines.append(f"off the data: {d['metrics_off_data_note']}")
    for key in ("friction_hook_note", "gap_segment_note", "relay_gap_note"):
        if d.get(key):
            lines.append(f"physics: {d[key]}")
    for name, note in (d.get("metrics_not_computed") or {}).items():
        lines.append(f"not computed: {name}: {note}")
    lines.append("RMSE: " + ", ".join(f"{k} {v['value']:.3g}″" for k, v in doc["rmse"].items()))
    return "\n".join(lines)


def write_fit(fit: CampaignFit, out_dir, command: str | None = None) -> dict:
    """Write ``fit.json`` and ``posterior.nc`` (the ArviZ tree) to ``out_dir``; return fit.json."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    doc = fit_json(fit, command)  # command: recorded in its provenance
    (out / "fit.json").write_text(json.dumps(doc, indent=2))
    if fit.tree is not None:
        from ..sample import save_tree

        save_tree(fit.tree, out / "posterior.nc")
    return doc
