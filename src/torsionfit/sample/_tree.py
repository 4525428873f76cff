"""The ArviZ tree of a fit (DESIGN §2 output, §5.2 ``posterior.nc``) and its netCDF file.

Built to be read with plain ArviZ ≥ 1.3 (an ``xarray.DataTree``, groups made with
``arviz_base.dict_to_dataset``): ``az.summary``, ``az.loo``, ``az.compare`` and the
``az.plot_*`` functions work on it as it is (user guide: ``docs/guide/arviz.md``).

**One sample grid.** Every group with draws — ``posterior``, ``sample_stats``,
``posterior_predictive``, ``log_likelihood`` — holds the same (chain, draw) grid: emcee's
walkers or NUTS's chains are the chains, the sampler's kept draws are the draws, thinned to
every k-th (:func:`draw_thinning`) when the whole chain would make the pointwise groups larger
than ``max_pointwise_values`` numbers each (or, in a fit, than the metrics' draws). The
``draw`` coordinate is the sampler's draw index, so a thinned tree says which draws it kept.
ArviZ's own relative efficiency for PSIS-LOO (posterior ESS / log-likelihood draws) is then
the right one. A Laplace fit's tree has one chain of independent draws of the approximation
(attrs ``sampler = "laplace"`` and ``posterior_kind``).

Groups:

- ``posterior`` (chain, draw, …): every model parameter on its natural scale in SI under its
  model name (``stiffness`` N·m/rad, ``friction_torque`` N·m, ``gap`` rad, …); per-run vectors
  carry a named dim (``angle_offset``/``friction_start``: ``hysteresis_run``; ``drift``:
  ``run``; ``kin_cos``/``kin_sin``: ``kinematic_order``). Linear parameters (offsets,
  harmonics, drift) are marginalised out of the sampler's density; per draw of u they are
  drawn from their exact conditional posterior N(β̂(u), A⁻¹) (``linear="sample"``, the
  default: joint posterior draws), or set to β̂(u) = ``problem.full_values(u)``
  (``linear="profile"``). Also ``noise_sigma`` (innovation sd per run, rad, dim ``run``),
  ``ar1_rho`` (per AR(1) run, dim ``ar1_run``) and ``torque_line_correction`` (latent
  drive-torque correction per ramp, its level and its tilt, N·m, dim ``torque_line``); and, when given, the
  catalog metrics of ``fit.json`` per draw in their display units (``stiffness_elastic``
  N·m/arcmin, ``lost_motion`` arcmin, …; ``kd_mean``/``kt`` with dim ``te_run``). A metric
  that is a model parameter already (``friction_torque``) is not stored twice. Every variable
  has attrs ``units``, ``description`` and ``role`` (``model`` / ``noise`` / ``latent`` /
  ``metric``).
- ``observed_data``: ``angle`` (rad), every measured sample of the campaign on one dim
  ``observation`` — output twist of the hysteresis runs, transmission error of the TE runs —
  with coords ``run`` (run name) and ``run_sample`` (sample index within its run).
- ``posterior_predictive`` and ``log_likelihood``: ``angle`` (chain, draw, observation), the
  one variable ``az.loo`` needs no name for. The predictive is the model total plus simulated
  noise (AR(1) with the draw's σ, ρ and the likelihood's per-sample scales; Student-t
  innovations when the likelihood is Student-t); the log-likelihood is the problem's
  per-sample density at the draw's (u, β) (AR(1) terms are conditional on the previous
  sample, so PSIS-LOO leaves out one sample given the one before it). Samples out of the
  likelihood (``NoiseOptions.first_excursion_conditioning``) are not in ``log_likelihood``:
  its ``observation`` dim holds the others, named by the same coords.
- ``constant_data`` (with ``campaign``): ``time`` (s), ``torque`` (N·m) and ``output_angle``
  (rad) on the same ``observation`` dim and coords, NaN where a run has no such column — a
  loop is re-plotted as ``observed_data.angle`` against ``constant_data.torque`` of one run.
- ``sample_stats`` (chain, draw): ``lp`` (log posterior density of u, up to a constant) and
  ``acceptance_rate`` (emcee: share of the steps in the draw's thinning window in which the
  walker moved; NUTS: mean Metropolis acceptance over the draw's trajectory); with NUTS also
  ``diverging`` (bool), ``tree_depth`` and ``n_steps`` (leapfrog steps, = gradient
  evaluations); with Laplace ``log_q``, the approximation's log density of u (``lp − log_q``
  are the importance ratios of its draws). Attrs ``sampler`` (``emcee`` / ``nuts`` /
  ``laplace``), ``tau_max``, ``n_steps``, ``burn_in``, ``thin``, ``tree_thin``, ``converged``
  (0/1), ``reason``, ``tau`` (JSON: τ per entry of u), ``acceptance_fraction``, and
  ``convergence`` (JSON: R̂ and ESS over all the sampler's kept draws, before the tree's
  thinning); with NUTS ``step_size`` (per chain), ``n_warmup``, ``n_divergent``,
  ``n_grad_evals``.
"""

from __future__ import annotations

import json
import os
import re

import arviz_base
import arviz_stats
import emcee
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import xarray as xr

from .._x64 import in_float64
from ..fit._problem import student_t_weights
from ..fit._torque_error import torque_line_labels
from ._emcee import SampleResult

__all__ = ["MAX_POINTWISE_VALUES", "convergence_summary", "draw_thinning", "load_tree", "pointwise_draw_limit",
           "psis_loo", "save_tree", "to_datatree"]

#: named dims of vector parameters (anything else: ``<name>_dim``)
_VECTOR_DIMS = {
    "angle_offset": "hysteresis_run",
    "friction_start": "hysteresis_run",
    "gap_start": "hysteresis_run",
    "drift": "run",
    "kin_cos": "kinematic_order",
    "kin_sin": "kinematic_order",
}
_BATCH = 256  # draws per compiled batch (fixed, so one compilation per problem shape)


# --- jitted per-draw quantities -----------------------------------------------------------
def _joint_draw(problem, u, key, sample_linear: bool):
    """The linear parameters β for one draw of u, and the whitened residuals at them.

    The log-density marginalises β under a flat prior, so given u the posterior of β is
    exactly N(β̂(u), A(u)⁻¹) (Gaussian likelihood; the same Laplace approximation the
    log-density makes for Student-t, A then weighted by the t's (ν+1)/(ν+r²)), A = Σ_r X̃_rᵀ X̃_r
    with the design matrices whitened as the residuals are. ``sample_linear`` draws β from it — the joint posterior of (u, β);
    otherwise β = β̂(u), ``problem.full_values``'s profile. Returns (β, whitened residuals per
    run, per-sample scales per run, ρ per run)."""
    white, beta, _, scales, rho = problem.profile_all(u)
    if sample_linear and problem.n_linear:
        wx = problem.whitened_design(scales, rho)
        if problem.student_t_dof:
            # the reweighted curvature the profile solved β with (FitProblem._reweighted_linear)
            a = wx.T @ (student_t_weights(white**2, problem.student_t_dof)[:, None] * wx)
        else:
            a = wx.T @ wx
        # the same ridge as ``FitProblem.profile`` (plus a floor for an all-zero design)
        a = a + (1e-10 * jnp.trace(a) / problem.n_linear + 1e-300) * jnp.eye(problem.n_linear)
        chol = jnp.linalg.cholesky(a)
        z = jax.random.normal(key, (problem.n_linear,), dtype=beta.dtype)
        delta = jax.scipy.linalg.solve_triangular(chol.T, z, lower=False)  # cov L⁻ᵀL⁻¹ = A⁻¹
        beta = beta + delta
        white = white - wx @ delta
    white, scales = problem.split_runs(white), problem.split_runs(scales)
    return beta, white, scales, rho


def _values_one(problem, u, key, sample_linear):
    """Every model parameter (SI), σ and ρ per run for one draw."""
    sigma, rho = problem.noise_values(u)
    beta, _, _, _ = _joint_draw(problem, u, key, sample_linear)
    values = {**problem.physics_values(u[:problem.n_nonlinear]), **problem.linear_values(beta)}
    return values, sigma, rho


_batch_values = eqx.filter_jit(eqx.filter_vmap(_values_one, in_axes=(None, 0, 0, None)))


def _ar1_noise(key, scale, rho, dof):
    """Stationary AR(1) noise with innovations ``scale · ε`` (ε standard normal, or Student-t
    with ``dof``): the inverse of the likelihood's whitening (Prais–Winsten first sample)."""
    eps = jax.random.normal(key, scale.shape) if dof is None else jax.random.t(key, dof, scale.shape)
    innov = scale * eps
    first = innov[0] / jnp.sqrt(1.0 - rho**2)

    def step(prev, e):
        x = rho * prev + e
        return x, x

    _, rest = jax.lax.scan(step, first, innov[1:])
    return jnp.concatenate([first[None], rest])


def _predictive_one(problem, u, key, noise_key, sample_linear):
    """(replicated angle per run, pointwise log-likelihood per run) for one draw; ``key`` is
    the draw's key of the posterior pass, so β is the one stored in the posterior."""
    beta, white, scales, rho = _joint_draw(problem, u, key, sample_linear)
    values = {**problem.physics_values(u[:problem.n_nonlinear]), **problem.linear_values(beta)}
    totals = problem.model.predict(values, problem.corrected_inputs(u))
    keys = jax.random.split(noise_key, problem.n_runs)
    reps = [f + _ar1_noise(keys[r], scales[r], rho[r], problem.student_t_dof) for r, f in enumerate(totals)]
    if sample_linear:
        # FitProblem's own per-sample density, at the drawn β (pointwise_log_likelihood
        # evaluates it at β̂)
        loglik = problem._pointwise(white, scales, rho)
    else:
        loglik = problem.pointwise_log_likelihood(u)
    return reps, loglik


_batch_predictive = eqx.filter_jit(eqx.filter_vmap(_predictive_one, in_axes=(None, 0, 0, 0, None)))


def _batched(fn, problem, u, *extra, static=(), batch=_BATCH):
    """Apply a vmapped ``fn(problem, u, *extra, *static)`` over the rows of u (and of the
    arrays in ``extra``) in fixed-size batches — the last one padded, so there is one
    compilation per problem shape — returning the pytree of stacked NumPy results."""
    n = u.shape[0]
    out = []
    for lo in range(0, n, batch):
        idx = np.minimum(np.arange(lo, lo + batch), n - 1)  # pad with the last row
        args = [jnp.asarray(a[idx]) for a in (u, *extra)]
        res = fn(problem, *args, *static)
        take = min(batch, n - lo)
        out.append(jax.tree_util.tree_map(lambda x: np.asarray(x)[:take], res))
    return jax.tree_util.tree_map(lambda *xs: np.concatenate(xs, axis=0), *out)


# --- the grid ----------------------------------------------------------------------------------
#: numbers per pointwise variable (log-likelihood, predictive) the tree holds at most: 16 MB each
MAX_POINTWISE_VALUES = 2_000_000


def draw_thinning(n_chain: int, n_draw: int, max_draws: int, step: int = 1) -> int:
    """The smallest multiple k of ``step`` for which every k-th draw of each of ``n_chain``
    chains (draws 0, k, 2k, … of ``n_draw``) is at most ``max_draws`` draws in all; when even
    one draw per chain is more, every chain keeps its first draw. A multiple of ``step``, so
    the draws kept with it are among those kept with ``step``."""
    step = max(int(step), 1)
    k = step
    while k < n_draw and n_chain * -(-n_draw // k) > max_draws:
        k += step
    return k


def pointwise_draw_limit(n_observations: int, max_values: int = MAX_POINTWISE_VALUES) -> int:
    """Draws whose pointwise log-likelihood over ``n_observations`` fit in ``max_values``."""
    return max(1, int(max_values) // max(int(n_observations), 1))


# --- the tree ------------------------------------------------------------------------------
def _json(obj) -> str:
    return json.dumps(obj, ensure_ascii=False)


def _observation_coords(run_names, lengths) -> dict:
    return {"run": ("observation", np.concatenate([np.full(n, r, dtype=object) for r, n in zip(run_names, lengths)]).astype(str)),
            "run_sample": ("observation", np.concatenate([np.arange(n) for n in lengths]))}


def _constant_data(campaign, lengths) -> dict:
    """time (s), torque (N·m) and output angle (rad) per sample of the campaign's runs, NaN
    where a run has no such column (hysteresis runs: no output angle; TE runs without a
    torque series: their nominal load)."""
    cols = {"time": [], "torque": [], "output_angle": []}
    for run, n in zip(campaign.runs, lengths):
        if len(run) != n:
            raise ValueError(f"run {run.name!r} has {len(run)} samples, the problem {n}")
        nan = np.full(n, np.nan)
        if run.kind == "hysteresis":
            cols["time"].append(np.asarray(run.time_s, float))
            cols["torque"].append(np.asarray(run.torque_Nm, float))
            cols["output_angle"].append(nan)
        else:
            cols["time"].append(nan if run.time_s is None else np.asarray(run.time_s, float))
            cols["torque"].append(np.full(n, float(run.torque_Nm)) if run.torque_series_Nm is None
                                  else np.asarray(run.torque_series_Nm, float))
            cols["output_angle"].append(np.asarray(run.output_angle_rad, float))
    return {k: np.concatenate(v) for k, v in cols.items()}


_CONSTANT_ATTRS = {
    "time": dict(units="s", description="time of the sample (NaN: the run has no time column)"),
    "torque": dict(units="N·m", description="drive torque as measured (hysteresis runs, TE runs with a torque "
                                            "series), else the TE run's nominal load (≥ 0)"),
    "output_angle": dict(units="rad", description="output shaft angle of TE runs (NaN for hysteresis runs)"),
}


def _split_metric(name: str) -> tuple[str, str | None]:
    """``"kd_mean[te-5]"`` → (``"kd_mean"``, ``"te-5"``); ``"lost_motion"`` → (name, None)."""
    m = re.fullmatch(r"(.+)\[(.+)\]", name)
    return (m.group(1), m.group(2)) if m else (name, None)


def _add_metrics(post, dims, coords, var_attrs, specs, draws, te_runs):
    """The catalog metrics (``specs``, columns of ``draws`` (chain, draw, metric)) as
    posterior variables: one per metric, bracketed names (``kd_mean[run]``) as one vector per
    base name with dim ``te_run`` (or ``<base>_label``). A metric equal to the model
    parameter of the same name is marked on the parameter, not stored again. A metric that is
    not finite in every draw is left out (a NaN would void ArviZ's ESS, hence its PSIS-LOO);
    returns the names left out."""
    groups: dict[str, list] = {}
    left_out = []
    for j, spec in enumerate(specs):
        base, label = _split_metric(spec.name)
        groups.setdefault(base, []).append((label, j, spec))
    for base, items in groups.items():
        spec = items[0][2]
        attrs = dict(units=spec.unit, description=spec.description, role="metric")
        if items[0][0] is None:
            v = draws[..., items[0][1]]
        else:
            labels = [lab for lab, _, _ in items]
            dim = "te_run" if set(labels) <= set(te_runs) else f"{base}_label"
            if dim in coords and list(coords[dim]) != labels:
                dim = f"{base}_label"
            coords.setdefault(dim, labels)
            v = np.stack([draws[..., j] for _, j, _ in items], axis=-1)
            dims_v = [dim]
            conds = {lab: s.condition for lab, _, s in items if s.condition}
            if conds:
                attrs["conditions"] = _json(conds)
        if not np.all(np.isfinite(v)):
            left_out.append(base)
            continue
        name = base
        if base in post:
            same = np.shape(post[base]) == np.shape(v) and np.allclose(post[base], v, rtol=1e-12, equal_nan=True)
            if same:
                var_attrs[base]["catalog_metric"] = f"also the catalog metric {spec.name} of fit.json ({spec.unit})"
                continue
            name = f"{base}_metric"
        post[name] = v
        if items[0][0] is not None:
            dims[name] = dims_v
        var_attrs[name] = attrs
    return left_out


def _laplace(sample_result) -> bool:
    return getattr(sample_result, "sampler", "emcee") == "laplace"


@in_float64
def to_datatree(problem, sample_result: SampleResult, run_names, *, draws=None, metric_specs=(),
                metric_draws=None, campaign=None, seed: int = 0, linear: str = "sample",
                max_pointwise_values: int = MAX_POINTWISE_VALUES) -> xr.DataTree:
    """The ArviZ tree of a fit (layout in the module docstring).

    ``sample_result``: emcee's :class:`SampleResult`, NUTS's ``NutsResult`` or a
    ``LaplaceResult``; ``run_names`` in campaign order. ``draws``: the indices of the draws
    of every chain the tree keeps (default: every k-th, k = :func:`draw_thinning` so that the
    pointwise groups hold at most ``max_pointwise_values`` numbers each). ``metric_specs`` and
    ``metric_draws`` (chain, kept draw, metric), optional: the catalog metrics of those draws
    (``torsionfit.report``), stored as posterior variables. ``campaign`` (the one the problem
    was built from), optional: its time, torque and output angle as ``constant_data``.
    ``seed`` draws the linear parameters and the predictive's noise.

    ``linear``: ``"sample"`` (default) draws the linear parameters (offsets, harmonics, drift)
    from their exact conditional posterior N(β̂(u), A⁻¹) per draw, so the tree holds draws of
    the joint posterior and their uncertainty is counted (in their own spread, in the
    predictive and in PSIS-LOO's p_loo); ``"profile"`` stores β̂(u) =
    ``problem.full_values(u)`` instead, which leaves out the linear parameters' own
    uncertainty (a harmonic amplitude that does not depend on the physics would get a
    spread of ~0).
    """
    if linear not in ("sample", "profile"):
        raise ValueError(f"linear must be 'sample' or 'profile', got {linear!r}")
    sample_linear = linear == "sample"
    run_names = [str(r) for r in run_names]
    if len(run_names) != problem.n_runs:
        raise ValueError(f"{len(run_names)} run names for {problem.n_runs} runs")
    kinds = problem.model.run_kinds
    hyst_runs = [r for r, k in zip(run_names, kinds) if k == "hysteresis"]
    te_runs = [r for r, k in zip(run_names, kinds) if k != "hysteresis"]
    ar1_runs = [r for r, a in zip(run_names, problem.ar1) if a]
    lengths = [len(y) for y in problem.y]

    # chain = walker (emcee), chain (NUTS) or the one chain of Laplace draws; draw = kept step
    chain = np.transpose(np.asarray(sample_result.chain, dtype=float), (1, 0, 2))
    n_chain, n_draw, dim = chain.shape
    if dim != problem.dim:
        raise ValueError(f"the sample has dimension {dim}, the problem {problem.dim}")
    if draws is None:
        k = draw_thinning(n_chain, n_draw, pointwise_draw_limit(sum(lengths), max_pointwise_values))
        draws = np.arange(0, n_draw, k)
    draws = np.asarray(draws, dtype=int)
    if draws.ndim != 1 or not len(draws) or draws.min() < 0 or draws.max() >= n_draw or np.any(np.diff(draws) <= 0):
        raise ValueError(f"draws must be increasing indices of the {n_draw} draws per chain")
    n_kept = len(draws)
    if metric_draws is not None:
        metric_draws = np.asarray(metric_draws, dtype=float)
        if metric_draws.shape != (n_chain, n_kept, len(metric_specs)):
            raise ValueError(f"metric_draws has shape {metric_draws.shape}, expected "
                             f"{(n_chain, n_kept, len(metric_specs))} (chain, kept draw, metric)")
    flat = chain.reshape(-1, dim)  # row c·n_draw + d

    # posterior: every model parameter per draw of the whole chain (R̂ and ESS need all of
    # them), jitted and vmapped in batches; the tree keeps ``draws``
    draw_keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed), flat.shape[0]))
    values, sigma, rho = _batched(_batch_values, problem, flat, draw_keys, static=(sample_linear,))
    post, dims, coords, var_attrs = {}, {}, {}, {}
    coords["run"] = run_names
    if hyst_runs:
        coords["hysteresis_run"] = hyst_runs
    if problem.model.kinematic is not None:
        coords["kinematic_order"] = list(problem.model.kinematic.orders)
    for p in problem.model.parameters():
        v = np.asarray(values[p.name]).reshape(n_chain, n_draw, -1)
        if p.name in _VECTOR_DIMS:
            dims[p.name] = [_VECTOR_DIMS[p.name]]
        elif p.size > 1:
            dims[p.name] = [f"{p.name}_dim"]
        else:
            v = v[..., 0]
        post[p.name] = v
        var_attrs[p.name] = dict(units=p.unit, description=p.description, role="model",
                                 constraint=p.constraint, linear=int(p.linear))
        if p.linear:
            var_attrs[p.name]["linear_draws"] = linear
    model_vars = list(post)
    convergence = None
    if not _laplace(sample_result):
        full = xr.Dataset({k: (("chain", "draw") + tuple(dims.get(k, [])), post[k]) for k in model_vars},
                          coords={k: v for k, v in coords.items()})
        convergence = _rhat_ess(full, model_vars)
    post = {k: v[:, draws] for k, v in post.items()}
    post["noise_sigma"] = sigma.reshape(n_chain, n_draw, -1)[:, draws]
    dims["noise_sigma"] = ["run"]
    var_attrs["noise_sigma"] = dict(units="rad", role="noise",
                                    description="innovation sd per run, √(s² + encoder floor²)")
    if ar1_runs:
        post["ar1_rho"] = rho.reshape(n_chain, n_draw, -1)[:, draws][..., np.flatnonzero(problem.ar1)]
        dims["ar1_rho"] = ["ar1_run"]
        coords["ar1_run"] = ar1_runs
        var_attrs["ar1_rho"] = dict(units="1", role="noise", description="AR(1) coefficient of the residual")
    if problem.n_torque_lines:
        post["torque_line_correction"] = chain[:, draws, problem.n_model:problem.n_nonlinear]
        dims["torque_line_correction"] = ["torque_line"]
        coords["torque_line"] = [f"{r}{label}" for r, b in zip(run_names, problem.torque_line_basis)
                                 for label in torque_line_labels(b.shape[1])]
        var_attrs["torque_line_correction"] = dict(
            units="N·m", role="latent",
            description="latent correction to the denoised drive torque, per ramp of each hysteresis run: "
                        "its level, and its tilt (the correction at the ramp's ends relative to its middle)")
    left_out = [] if metric_draws is None else _add_metrics(post, dims, coords, var_attrs, metric_specs,
                                                           metric_draws, te_runs)

    # predictive and pointwise log-likelihood of the kept draws, all runs on one dim
    rows = (np.arange(n_chain)[:, None] * n_draw + draws[None, :]).ravel()
    noise_keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed + 1), len(rows)))
    reps, ll = _batched(_batch_predictive, problem, flat[rows], draw_keys[rows], noise_keys,
                        static=(sample_linear,), batch=64)
    pointwise = {"posterior_predictive": reps, "log_likelihood": ll}
    pointwise = {g: {"angle": np.concatenate(v, axis=1).reshape(n_chain, n_kept, -1)} for g, v in pointwise.items()}
    obs_coords = _observation_coords(run_names, lengths)
    angle_attrs = dict(units="rad", role="observed",
                       description="measured angle: output twist (hysteresis runs), transmission error (TE runs)")

    laplace = _laplace(sample_result)
    nuts = getattr(sample_result, "sampler", "emcee") == "nuts"
    if nuts:
        import blackjax

        lib = dict(inference_library="blackjax", inference_library_version=getattr(blackjax, "__version__", "?"))
    elif laplace:
        lib = dict(inference_library="torsionfit", inference_library_version="Laplace approximation at the MAP")
    elif getattr(sample_result, "sampler", "emcee") == "smc":
        lib = dict(inference_library="torsionfit", inference_library_version="tempered SMC from the split normal")
    else:
        lib = dict(inference_library="emcee", inference_library_version=emcee.__version__)
    groups = {}
    # check_conventions=False: an ensemble often has more walkers (chains) than kept draws,
    # which ArviZ's naming check would flag; the dims are named explicitly here
    conv = dict(sample_dims=["chain", "draw"], check_conventions=False)
    grid = dict(chain=np.arange(n_chain), draw=draws)
    post_attrs = dict(lib)
    if left_out:
        post_attrs["metrics_left_out"] = f"not finite in every draw: {', '.join(left_out)}"
    if laplace:
        post_attrs["posterior_kind"] = ("draws of the Laplace approximation N(MAP, cov) in the sampler's "
                                        "coordinates u, not of the posterior itself (sample_stats: lp − log_q)")
    groups["posterior"] = arviz_base.dict_to_dataset(post, dims=dims, coords={**coords, **grid}, attrs=post_attrs, **conv)
    obs_dims = {"angle": ["observation"]}
    for g, data in pointwise.items():
        groups[g] = arviz_base.dict_to_dataset(data, dims=obs_dims, coords=grid, attrs=lib, **conv).assign_coords(obs_coords)
    groups["observed_data"] = arviz_base.dict_to_dataset(
        {"angle": np.concatenate([np.asarray(y, dtype=float) for y in problem.y])}, dims=obs_dims, sample_dims=[],
        attrs=lib).assign_coords(obs_coords)
    for g in ("posterior_predictive", "log_likelihood", "observed_data"):
        groups[g]["angle"].attrs.update(angle_attrs)
    groups["log_likelihood"]["angle"].attrs.update(units="1", description="log density of each sample given the draw")
    if problem.likelihood_keep is not None:
        # samples out of the likelihood (conditioning) have no density: LOO reads the others
        # (their run / run_sample coords say which), where constant zeros would stop PSIS
        groups["log_likelihood"] = groups["log_likelihood"].isel(
            observation=np.flatnonzero(np.concatenate(problem.kept_samples())))
    if campaign is not None:
        groups["constant_data"] = arviz_base.dict_to_dataset(
            _constant_data(campaign, lengths), dims={k: ["observation"] for k in _CONSTANT_ATTRS}, sample_dims=[],
            attrs=lib).assign_coords(obs_coords)
        for k, a in _CONSTANT_ATTRS.items():
            groups["constant_data"][k].attrs.update(a)
    groups["sample_stats"] = _sample_stats(sample_result, draws, lib, conv, grid, convergence, n_draw)
    for name, attrs in var_attrs.items():
        if name in groups["posterior"]:
            groups["posterior"][name].attrs.update(attrs)

    tree = xr.DataTree.from_dict(groups)
    s = sample_result
    if laplace:
        how = "chain = the one chain of independent draws of the Laplace approximation, draw = draw index"
    elif nuts:
        how = "chain = NUTS chain, draw = draw after the warm-up of burn_in steps"
    elif getattr(s, "sampler", "emcee") == "smc":
        how = "chain = the one set of SMC particles (equally weighted draws of the posterior), draw = particle"
    else:
        how = "chain = emcee walker, draw = kept step (step = burn_in + thin·(draw + 1) − 1)"
    tree.attrs.update(
        created_by="torsionfit", run_kinds=_json(dict(zip(run_names, kinds))), seed=int(seed),
        sampler_seed=-1 if s.seed is None else int(s.seed), linear_parameters=linear,
        draws=how + (f"; the tree keeps every {int(draws[1] - draws[0])}-th draw of the {n_draw} per chain "
                     "(the draw coordinate)" if 1 < n_kept < n_draw else ""),
    )
    return tree


def _sample_stats(s, draws, lib, conv, grid, convergence, n_draw) -> xr.Dataset:
    """The ``sample_stats`` group of the kept ``draws`` (layout in the module docstring)."""
    sampler = getattr(s, "sampler", "emcee")
    kept = np.asarray(draws)
    stats = {"lp": np.asarray(s.log_prob, dtype=float).T[:, kept]}
    if sampler == "laplace":
        stats["log_q"] = np.asarray(s.log_q, dtype=float).T[:, kept]
    elif s.acceptance_rate is not None:
        stats["acceptance_rate"] = np.asarray(s.acceptance_rate, dtype=float).T[:, kept]
    extra = {}
    if sampler == "nuts":
        stats["diverging"] = np.asarray(s.diverging, dtype=bool).T[:, kept]
        stats["tree_depth"] = np.asarray(s.tree_depth, dtype=int).T[:, kept]
        stats["n_steps"] = np.asarray(s.n_leapfrog, dtype=int).T[:, kept]
        extra = {"step_size": np.asarray(s.step_size, dtype=float), "n_warmup": int(s.n_warmup),
                 "n_divergent": int(s.n_divergent), "n_grad_evals": int(s.n_grad_evals)}
    if sampler == "laplace":
        extra = {"approximation": "Gaussian N(MAP, cov) in u; draws independent, one chain",
                 "n_draws": int(np.asarray(s.chain).shape[0])}
    else:
        extra.update({"tau_max": float(np.max(s.tau)),
                      "tau": _json({n: float(t) for n, t in zip(s.names, np.asarray(s.tau))}),
                      "n_steps": int(s.n_steps), "burn_in": int(s.burn_in), "thin": int(s.thin),
                      "n_walkers": int(np.asarray(s.chain).shape[1]),
                      "acceptance_fraction": np.asarray(s.acceptance_fraction, dtype=float),
                      "moves": str(s.moves)})
    if convergence is not None:
        extra["convergence"] = _json(convergence)
    ds = arviz_base.dict_to_dataset(stats, coords=grid, **conv, attrs={
        **lib, **extra, "sampler": sampler, "converged": int(bool(s.converged)), "reason": str(s.reason),
        "tree_thin": int(kept[1] - kept[0]) if len(kept) > 1 else int(n_draw)})
    ds["lp"].attrs.update(units="1", description="log posterior density of u (up to a constant)")
    if "log_q" in ds:
        ds["log_q"].attrs.update(units="1", description="log density of u under the Laplace approximation")
    if "acceptance_rate" in ds:
        ds["acceptance_rate"].attrs.update(
            units="1", description="mean Metropolis acceptance probability over the draw's trajectory"
            if sampler == "nuts" else "share of the steps in the draw's thinning window in which the walker moved")
    if sampler == "nuts":
        ds["diverging"].attrs.update(description="divergent transition (energy error above the threshold)")
        ds["tree_depth"].attrs.update(units="1", description="number of trajectory doublings")
        ds["n_steps"].attrs.update(units="1", description="leapfrog steps (gradient evaluations) of the draw")
    return ds


# --- files ---------------------------------------------------------------------------------
def save_tree(tree: xr.DataTree, path) -> None:
    """Write ``tree`` to a netCDF-4 file (h5netcdf engine), readable by ``arviz.from_netcdf``
    / ``xarray.open_datatree``."""
    tree.to_netcdf(os.fspath(path), engine="h5netcdf")


def load_tree(path) -> xr.DataTree:
    """Read a tree written by :func:`save_tree`, fully into memory (the file is closed)."""
    with xr.open_datatree(os.fspath(path), engine="h5netcdf") as tree:
        return tree.load().copy()


# --- diagnostics ---------------------------------------------------------------------------
def _labelled(da: xr.DataArray, name: str) -> dict:
    """{``name`` or ``name[label]``: float} for a DataArray of per-parameter statistics."""
    if da.ndim == 0:
        return {name: float(da.values)}
    out = {}
    stacked = da.stack(_i=da.dims)
    for i in range(stacked.sizes["_i"]):
        item = stacked.isel(_i=i)
        label = ",".join(str(item[d].values) for d in da.dims)
        out[f"{name}[{label}]"] = float(item.values)
    return out


def _rhat_ess(post: xr.Dataset, names) -> dict:
    """R̂ (rank-normalised split R̂) and bulk ESS of ``names`` in ``post`` (``arviz_stats``):
    ``{"rhat_max", "ess_min", "rhat": {param: value}, "ess": {...}, "n_chains", "n_draws"}``;
    NaN statistics (parameters that do not vary) are left out of the max/min."""
    post = post[list(names)]
    with np.errstate(invalid="ignore", divide="ignore"):  # a parameter that does not vary: NaN
        rhat = arviz_stats.rhat(post)
        ess = arviz_stats.ess(post, method="bulk")
    rhat_d, ess_d = {}, {}
    for k in names:
        rhat_d.update(_labelled(rhat[k], k))
        ess_d.update(_labelled(ess[k], k))
    r = np.array(list(rhat_d.values()), dtype=float)
    e = np.array(list(ess_d.values()), dtype=float)
    return {
        "rhat_max": float(np.nanmax(r)) if np.isfinite(r).any() else float("nan"),
        "ess_min": float(np.nanmin(e)) if np.isfinite(e).any() else float("nan"),
        "rhat": rhat_d,
        "ess": ess_d,
        "n_chains": int(post.sizes["chain"]),
        "n_draws": int(post.sizes["draw"]),
    }


def convergence_summary(tree: xr.DataTree) -> dict:
    """R̂ and bulk ESS over the model parameters only (not noise levels, torque knots or
    metrics): ``{"rhat_max", "ess_min", "rhat": {param: value}, "ess": {param: value},
    "converged", "tau_max", "n_chains", "n_draws"}``. Computed on all the sampler's kept draws
    when the tree was built (``sample_stats`` attr ``convergence``; the tree itself may keep
    a thinned subset), else from the tree's posterior. With emcee the chains are walkers of
    one ensemble, not independent runs: R̂ near 1 is necessary, not sufficient; τ and ESS
    carry the weight."""
    stats = tree["sample_stats"].attrs if "sample_stats" in tree.children else {}
    if "convergence" in stats:
        out = json.loads(stats["convergence"])
    else:
        post = tree["posterior"].to_dataset()
        out = _rhat_ess(post, [k for k in post.data_vars if post[k].attrs.get("role", "model") == "model"])
    out.update(converged=bool(stats.get("converged", 0)), tau_max=float(stats.get("tau_max", float("nan"))))
    return out


def psis_loo(tree: xr.DataTree, run: str | None = None, pointwise: bool = True):
    """PSIS-LOO of the whole campaign (``run=None``, the same as ``arviz.loo(tree)``) or of the
    samples of one run (by name), with ``arviz_stats``. The draws of a Laplace tree are of the
    approximation, not of the posterior: their LOO is corrected by the importance ratios
    ``lp − log_q`` of ``sample_stats`` (``arviz_stats.loo_approximate_posterior``)."""
    data = tree
    if run is not None:
        ll = tree["log_likelihood"].to_dataset()
        mask = ll["run"].values == run
        if not mask.any():
            runs = dict.fromkeys(ll["run"].values.tolist())
            raise ValueError(f"no run {run!r} in the tree; its runs: {', '.join(runs)}")
        data = xr.DataTree.from_dict({"posterior": tree["posterior"].to_dataset(),
                                      "log_likelihood": ll.isel(observation=np.flatnonzero(mask))})
    stats = tree["sample_stats"]
    if "log_q" in stats:
        return arviz_stats.loo_approximate_posterior(data, log_p=stats["lp"], log_q=stats["log_q"],
                                                     pointwise=pointwise)
    return arviz_stats.loo(data, pointwise=pointwise)
