"""The ArviZ tree of a fit (DESIGN §2 output, §5.2 ``posterior.nc``) and its netCDF file.

Layout (ArviZ ≥ 1.3: an ``xarray.DataTree``, groups built with ``arviz_base.dict_to_dataset``;
emcee's walkers are the chains, kept steps the draws):

- ``posterior`` (chain, draw, …): every model parameter on its natural scale in SI under its
  model name (``stiffness`` N·m/rad, ``friction_torque`` N·m, ``gap`` rad, …); per-run vectors
  carry a named dim (``angle_offset``/``friction_start``: ``hysteresis_run``; ``drift``:
  ``run``; ``kin_cos``/``kin_sin``: ``kinematic_order``). Linear parameters (offsets,
  harmonics, drift) are marginalised out of the sampler's density; per draw of u they are
  drawn from their exact conditional posterior N(β̂(u), A⁻¹) (``linear="sample"``, the
  default: joint posterior draws), or set to β̂(u) = ``problem.full_values(u)``
  (``linear="profile"``). Also ``noise_sigma`` (innovation sd per run, rad, dim ``run``),
  ``ar1_rho`` (per AR(1) run, dim ``ar1_run``) and ``torque_knot`` (latent drive-torque
  correction at the knots, N·m, dim ``torque_knot``). Every variable has attrs ``units``,
  ``description`` and ``role`` (``model`` / ``noise`` / ``latent``).
- ``posterior_predictive`` and ``log_likelihood``: one variable per run (default
  ``angle_<run name made safe>``; the mapping run → variable is the root attr
  ``run_variables``, JSON) with dim ``<variable>_sample``. They hold a random subset of
  ``n_predictive_draws`` posterior (walker, draw) pairs, stored as one pseudo-chain
  (chain = [0], draw = 0…m−1) with coords ``posterior_chain`` / ``posterior_draw`` naming
  the source pair. The predictive is the model total plus simulated noise (AR(1) with the
  draw's σ, ρ and the likelihood's per-sample scales; Student-t innovations when the
  likelihood is Student-t); the log-likelihood is the problem's per-sample density at the
  draw's (u, β) (``problem.pointwise_log_likelihood`` with ``linear="profile"``; AR(1) terms
  are conditional on the previous sample).
- ``observed_data``: the measured angle per run (rad), same names and dims.
- ``sample_stats`` (chain, draw): ``lp`` (log posterior density of u, up to a constant) and
  ``acceptance_rate`` (emcee: share of the steps in the draw's thinning window in which the
  walker moved; NUTS: mean Metropolis acceptance over the draw's trajectory); with NUTS also
  ``diverging`` (bool), ``tree_depth`` and ``n_steps`` (leapfrog steps, = gradient
  evaluations); attrs ``sampler`` (``emcee`` / ``nuts``), ``tau_max``, ``n_steps``,
  ``burn_in``, ``thin``, ``converged`` (0/1), ``reason``, ``tau`` (JSON: τ per entry of u),
  ``acceptance_fraction`` (per walker or chain); with NUTS ``step_size`` (per chain),
  ``n_warmup``, ``n_divergent``, ``n_grad_evals``.

PSIS-LOO: the log-likelihood holds a subset of the draws, so ArviZ's default relative
efficiency (posterior ESS / number of log-likelihood draws) would be wrong; the group's attr
``reff`` holds the right one and :func:`psis_loo` passes it to ``arviz_stats.loo``.
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
from ._emcee import SampleResult

__all__ = ["convergence_summary", "load_tree", "psis_loo", "run_variable_names", "save_tree",
           "to_datatree"]

#: named dims of vector parameters (anything else: ``<name>_dim``)
_VECTOR_DIMS = {
    "angle_offset": "hysteresis_run",
    "friction_start": "hysteresis_run",
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
    log-density makes for Student-t), A = Σ_r X̃_rᵀ X̃_r with the design matrices whitened as
    the residuals are. ``sample_linear`` draws β from it — the joint posterior of (u, β);
    otherwise β = β̂(u), ``problem.full_values``'s profile. Returns (β, whitened residuals per
    run, per-sample scales per run, ρ per run)."""
    _, rho = problem.noise_values(u)
    white, beta, _, scales = problem.profile(u, return_scales=True)
    if sample_linear and problem.n_linear:
        wx = [problem.whiten(x, scales[r], rho[r]) for r, x in enumerate(problem.design)]
        a = sum(w.T @ w for w in wx)
        # the same ridge as ``FitProblem.profile`` (plus a floor for an all-zero design)
        a = a + (1e-10 * jnp.trace(a) / problem.n_linear + 1e-300) * jnp.eye(problem.n_linear)
        chol = jnp.linalg.cholesky(a)
        z = jax.random.normal(key, (problem.n_linear,), dtype=beta.dtype)
        delta = jax.scipy.linalg.solve_triangular(chol.T, z, lower=False)  # cov L⁻ᵀL⁻¹ = A⁻¹
        beta = beta + delta
        white = [v - w @ delta for v, w in zip(white, wx)]
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


# --- names -----------------------------------------------------------------------------------
def run_variable_names(run_names, prefix: str = "angle_") -> list[str]:
    """Safe, unique variable names per run: ``angle_`` + the name with every character that
    is not a letter, digit or underscore replaced by ``_`` (a suffix keeps them unique)."""
    out, seen = [], set()
    for r in run_names:
        base = prefix + re.sub(r"\W", "_", str(r), flags=re.ASCII)
        name, k = base, 1
        while name in seen:
            k += 1
            name = f"{base}_{k}"
        seen.add(name)
        out.append(name)
    return out


def _json(obj) -> str:
    return json.dumps(obj, ensure_ascii=False)


# --- the tree ------------------------------------------------------------------------------
@in_float64
def to_datatree(problem, sample_result: SampleResult, run_names, observed_names=None, *,
                n_predictive_draws: int = 100, seed: int = 0, linear: str = "sample") -> xr.DataTree:
    """The ArviZ tree of a sampled fit (layout in the module docstring).

    ``run_names`` in campaign order; ``observed_names`` optionally gives the variable name of
    each run in ``posterior_predictive``/``log_likelihood``/``observed_data`` (default
    :func:`run_variable_names`). ``n_predictive_draws`` random (walker, draw) pairs, chosen
    with ``seed``, feed the predictive and the pointwise log-likelihood.

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
    var_names = list(observed_names) if observed_names is not None else run_variable_names(run_names)
    if len(var_names) != problem.n_runs or len(set(var_names)) != len(var_names):
        raise ValueError("observed_names must give one distinct name per run")
    taken = {p.name for p in problem.model.parameters()} | {"noise_sigma", "ar1_rho", "torque_knot_correction"}
    if taken & set(var_names):
        raise ValueError(f"observed_names {sorted(taken & set(var_names))} clash with parameter names")
    kinds = problem.model.run_kinds
    hyst_runs = [r for r, k in zip(run_names, kinds) if k == "hysteresis"]
    ar1_runs = [r for r, a in zip(run_names, problem.ar1) if a]

    # chain = walker (emcee) or chain (NUTS), draw = kept step
    chain = np.transpose(np.asarray(sample_result.chain, dtype=float), (1, 0, 2))
    n_chain, n_draw, dim = chain.shape
    if dim != problem.dim:
        raise ValueError(f"the sample has dimension {dim}, the problem {problem.dim}")
    flat = chain.reshape(-1, dim)

    # posterior: every model parameter per draw, jitted and vmapped in batches
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
    post["noise_sigma"] = sigma.reshape(n_chain, n_draw, -1)
    dims["noise_sigma"] = ["run"]
    var_attrs["noise_sigma"] = dict(units="rad", role="noise",
                                    description="innovation sd per run, √(s² + encoder floor²)")
    if ar1_runs:
        post["ar1_rho"] = rho.reshape(n_chain, n_draw, -1)[..., np.flatnonzero(problem.ar1)]
        dims["ar1_rho"] = ["ar1_run"]
        coords["ar1_run"] = ar1_runs
        var_attrs["ar1_rho"] = dict(units="1", role="noise", description="AR(1) coefficient of the residual")
    if problem.n_knots:
        post["torque_knot_correction"] = chain[..., problem.n_model:problem.n_nonlinear]
        dims["torque_knot_correction"] = ["torque_knot"]
        coords["torque_knot"] = [f"{r}[{k}]" for r, b in zip(run_names, problem.knot_basis)
                                 for k in range(b.shape[1])]
        var_attrs["torque_knot_correction"] = dict(
            units="N·m", role="latent",
            description="latent correction to the denoised drive torque at the knots "
                        "(turning points and ends of each hysteresis run), linear in between")

    # predictive and pointwise log-likelihood for a random subset of (walker, draw) pairs
    rng = np.random.default_rng(seed)
    m = int(min(max(n_predictive_draws, 1), flat.shape[0]))
    pick = np.sort(rng.choice(flat.shape[0], size=m, replace=False))
    noise_keys = np.asarray(jax.random.split(jax.random.PRNGKey(seed + 1), m))
    reps, ll = _batched(_batch_predictive, problem, flat[pick], draw_keys[pick], noise_keys,
                        static=(sample_linear,), batch=64)
    pp, lik, obs = {}, {}, {}
    for r, (name, var) in enumerate(zip(run_names, var_names)):
        pp[var] = reps[r][None]
        lik[var] = ll[r][None]
        obs[var] = np.asarray(problem.y[r], dtype=float)
        dims[var] = [f"{var}_sample"]
        kind = kinds[r]
        var_attrs[var] = dict(units="rad", run=name, kind=kind,
                              description="output twist" if kind == "hysteresis" else "transmission error")

    # relative efficiency of m random draws of a chain with mean ESS E: 1 / (1 + m / E)
    model_vars = [p.name for p in problem.model.parameters()]
    n_total = n_chain * n_draw
    try:
        ess_ds = arviz_stats.ess(xr.Dataset({k: (("chain", "draw") + tuple(dims.get(k, [])), post[k])
                                             for k in model_vars}), method="mean")
        ess_mean = float(np.nanmean(np.hstack([np.ravel(ess_ds[k].values) for k in model_vars])))
    except Exception:  # noqa: BLE001 - too short a chain for an ESS: treat the draws as independent
        ess_mean = float(n_total)
    if not np.isfinite(ess_mean) or ess_mean <= 0:
        ess_mean = float(n_total)
    reff = float(1.0 / (1.0 + m / min(ess_mean, n_total)))

    nuts = getattr(sample_result, "sampler", "emcee") == "nuts"
    if nuts:
        import blackjax

        lib = dict(inference_library="blackjax", inference_library_version=getattr(blackjax, "__version__", "?"))
    else:
        lib = dict(inference_library="emcee", inference_library_version=emcee.__version__)
    groups = {}
    sample_dims = ["chain", "draw"]
    # check_conventions=False: an ensemble often has more walkers (chains) than kept draws,
    # which ArviZ's naming check would flag; the dims are named explicitly here
    conv = dict(sample_dims=sample_dims, check_conventions=False)
    groups["posterior"] = arviz_base.dict_to_dataset(post, dims=dims, coords=coords, attrs=lib, **conv)
    sub_coords = dict(posterior_chain=("draw", pick // n_draw), posterior_draw=("draw", pick % n_draw))
    groups["posterior_predictive"] = arviz_base.dict_to_dataset(
        pp, dims=dims, attrs=lib, **conv).assign_coords(sub_coords)
    groups["log_likelihood"] = arviz_base.dict_to_dataset(
        lik, dims=dims, attrs={**lib, "reff": reff}, **conv).assign_coords(sub_coords)
    groups["observed_data"] = arviz_base.dict_to_dataset(obs, dims=dims, sample_dims=[], attrs=lib)
    s = sample_result
    stats = {"lp": np.asarray(s.log_prob, dtype=float).T}
    if s.acceptance_rate is not None:
        stats["acceptance_rate"] = np.asarray(s.acceptance_rate, dtype=float).T
    nuts_attrs = {}
    if nuts:
        stats["diverging"] = np.asarray(s.diverging, dtype=bool).T
        stats["tree_depth"] = np.asarray(s.tree_depth, dtype=int).T
        stats["n_steps"] = np.asarray(s.n_leapfrog, dtype=int).T
        nuts_attrs = {"step_size": np.asarray(s.step_size, dtype=float), "n_warmup": int(s.n_warmup),
                      "n_divergent": int(s.n_divergent), "n_grad_evals": int(s.n_grad_evals)}
    groups["sample_stats"] = arviz_base.dict_to_dataset(stats, **conv, attrs={
        **lib, **nuts_attrs, "sampler": "nuts" if nuts else "emcee",
        "tau_max": float(np.max(s.tau)),
        "tau": _json({n: float(t) for n, t in zip(s.names, np.asarray(s.tau))}),
        "n_steps": int(s.n_steps), "burn_in": int(s.burn_in), "thin": int(s.thin),
        "n_walkers": int(n_chain), "converged": int(bool(s.converged)), "reason": str(s.reason),
        "acceptance_fraction": np.asarray(s.acceptance_fraction, dtype=float),
        "moves": str(s.moves),
    })
    groups["sample_stats"]["lp"].attrs.update(units="1", description="log posterior density of u (up to a constant)")
    if "acceptance_rate" in groups["sample_stats"]:
        groups["sample_stats"]["acceptance_rate"].attrs.update(
            units="1", description="mean Metropolis acceptance probability over the draw's trajectory" if nuts else
            "share of the steps in the draw's thinning window in which the walker moved")
    if nuts:
        ss = groups["sample_stats"]
        ss["diverging"].attrs.update(description="divergent transition (energy error above the threshold)")
        ss["tree_depth"].attrs.update(units="1", description="number of trajectory doublings")
        ss["n_steps"].attrs.update(units="1", description="leapfrog steps (gradient evaluations) of the draw")

    for g in ("posterior", "posterior_predictive", "log_likelihood", "observed_data"):
        for name, attrs in var_attrs.items():
            if name in groups[g]:
                groups[g][name].attrs.update(attrs)
    for g in ("posterior_predictive", "log_likelihood"):
        groups[g]["posterior_chain"].attrs.update(description="walker (posterior chain) of this draw")
        groups[g]["posterior_draw"].attrs.update(description="posterior draw index of this draw")

    tree = xr.DataTree.from_dict(groups)
    tree.attrs.update(
        created_by="torsionfit", run_variables=_json(dict(zip(run_names, var_names))),
        run_kinds=_json(dict(zip(run_names, kinds))), seed=int(seed),
        sampler_seed=-1 if s.seed is None else int(s.seed), linear_parameters=linear,
        draws=("chain = NUTS chain, draw = draw after the warm-up of burn_in steps" if nuts else
               "chain = emcee walker, draw = kept step (step = burn_in + thin·(draw + 1) − 1)"),
    )
    return tree


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
def _model_vars(tree) -> list[str]:
    post = tree["posterior"]
    return [k for k in post.data_vars if post[k].attrs.get("role", "model") == "model"]


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


def convergence_summary(tree: xr.DataTree) -> dict:
    """R̂ (rank-normalised split R̂) and bulk ESS from ``arviz_stats.rhat`` /
    ``arviz_stats.ess``, over the model parameters only (not noise levels or torque knots):
    ``{"rhat_max", "ess_min", "rhat": {param: value}, "ess": {param: value}, "converged",
    "tau_max", "n_chains", "n_draws"}``. With emcee the chains are walkers of one ensemble,
    not independent runs: R̂ near 1 is necessary, not sufficient; τ and ESS carry the weight.
    Parameters that do not vary (a NaN statistic) are left out of the max/min."""
    names = _model_vars(tree)
    post = tree["posterior"].to_dataset()[names]
    rhat = arviz_stats.rhat(post)
    ess = arviz_stats.ess(post, method="bulk")
    rhat_d, ess_d = {}, {}
    for k in names:
        rhat_d.update(_labelled(rhat[k], k))
        ess_d.update(_labelled(ess[k], k))
    r = np.array(list(rhat_d.values()), dtype=float)
    e = np.array(list(ess_d.values()), dtype=float)
    stats = tree["sample_stats"].attrs if "sample_stats" in tree.children else {}
    return {
        "rhat_max": float(np.nanmax(r)) if np.isfinite(r).any() else float("nan"),
        "ess_min": float(np.nanmin(e)) if np.isfinite(e).any() else float("nan"),
        "rhat": rhat_d,
        "ess": ess_d,
        "converged": bool(stats.get("converged", 0)),
        "tau_max": float(stats.get("tau_max", float("nan"))),
        "n_chains": int(post.sizes["chain"]),
        "n_draws": int(post.sizes["draw"]),
    }


def psis_loo(tree: xr.DataTree, var_name: str | None = None, pointwise: bool = True):
    """PSIS-LOO with ``arviz_stats.loo``, passing the tree's ``reff`` (see the module note).

    ``var_name=None`` pools every run: the per-run log-likelihoods are concatenated along
    one ``observation`` dim (coords ``observation_run``) so the result is the campaign's
    ELPD; a variable name gives one run's."""
    ll = tree["log_likelihood"]
    reff = float(ll.attrs.get("reff", 1.0))
    if var_name is not None:
        return arviz_stats.loo(tree, var_name=var_name, reff=reff, pointwise=pointwise)
    parts, runs = [], []
    for k, da in ll.data_vars.items():
        obs_dim = [d for d in da.dims if d not in ("chain", "draw")]
        flat = da.stack(observation=obs_dim) if len(obs_dim) != 1 else da.rename({obs_dim[0]: "observation"})
        flat = flat.drop_vars([c for c in flat.coords if c not in ("chain", "draw")])
        parts.append(flat.transpose("chain", "draw", "observation"))
        runs += [da.attrs.get("run", k)] * flat.sizes["observation"]
    combined = xr.concat(parts, dim="observation").assign_coords(observation_run=("observation", runs))
    data = xr.DataTree.from_dict({
        "posterior": tree["posterior"].to_dataset(),
        "log_likelihood": xr.Dataset({"angle": combined}),
    })
    return arviz_stats.loo(data, var_name="angle", reff=reff, pointwise=pointwise)
