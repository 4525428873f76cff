"""Maximum a posteriori fit: optimistix Levenberg–Marquardt from several starts, then a
Laplace approximation of the posterior at the optimum.

The functions here are module-level and jitted on (problem, u): compiled once per shape of
problem, reused for every campaign of that shape.
"""

import functools
from dataclasses import dataclass, field

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._x64 import in_float64
from ._problem import NOISE_PRIOR_SD, RHO_MAX, RHO_PRIOR_SD, ROBUST_NOISE_ITERATIONS, FitProblem, student_t_weights

#: the closed-form ρ is capped just inside the density's bound ρ_max (where u would be infinite)
_RHO_CAP = RHO_MAX * (1.0 - 1e-3)

#: XLA options of the MAP's compiled programs (a noise pass, the Laplace parts, the misfit
#: check's whitened residuals): on CPU, XLA's LLVM IR emitter instead of its newer fusion
#: emitters, which took twice as long to compile them. Measured on the SYNTHETIC 10k loop of
#: benchmarks/bench_full_fit.py (2 cores, side by side): XLA compiled a noise pass in 0.65 s
#: instead of 1.4 s (1.2 s instead of 2.3 s with the other core busy) and the Laplace parts in
#: 0.3 s instead of 0.6 s; the warm fit took as long (0.27 s) and gave the same optimum and
#: covariance bit for bit. emcee's log-density (sample/_emcee.py, ``batch_log_density``) is
#: compiled with them too: it runs thousands of times, and measured its calls took as long.
MAP_COMPILER_OPTIONS = {"xla_cpu_use_fusion_emitters": False}


@functools.cache
def _map_compiler_options() -> dict | None:
    """:data:`MAP_COMPILER_OPTIONS` where this XLA knows them (a trivial program compiled with
    them once per process), else None (XLA's defaults)."""
    try:
        jax.jit(lambda x: x + 1, compiler_options=MAP_COMPILER_OPTIONS).lower(
            jax.ShapeDtypeStruct((), np.float32)).compile()
    except Exception:  # noqa: BLE001 - an XLA without these options compiles with its defaults
        return None
    return MAP_COMPILER_OPTIONS


def _map_jit(fn):
    """``eqx.filter_jit(fn)`` compiled with :data:`MAP_COMPILER_OPTIONS` (checked at the first call)."""
    jitted = []

    @functools.wraps(fn)
    def call(*args, **kwargs):
        if not jitted:
            jitted.append(eqx.filter_jit(fn, compiler_options=_map_compiler_options()))
        return jitted[0](*args, **kwargs)

    return call


def _weighted_residuals(u_phys, problem: FitProblem, u_noise, data_weight):
    white = problem.profile_all(jnp.concatenate([u_phys, u_noise]))[0]
    # Student-t: pseudo-residuals whose squares sum to its negative log density
    return jnp.concatenate([data_weight * problem.objective_residuals(white), problem.prior_residuals(u_phys)])


def _lm_residuals(u_phys, args):
    """Whitened residuals and prior pseudo-residuals: the Gauss–Newton part of the posterior."""
    problem, u_noise = args
    return _weighted_residuals(u_phys, problem, u_noise, 1.0)


def _lm_objective_residuals(u_phys, args):
    """What LM minimises: :func:`_lm_residuals` with the whitened residuals times √η, η the
    likelihood's power (1 but for a misfit-widened fit). Every sample's scale is fixed for a
    given noise level (the errors-in-variables part is read from the data), so this is the
    physics block of −log p up to the linear block's ½ log det A (a few dimensions)."""
    problem, u_noise = args
    return _weighted_residuals(u_phys, problem, u_noise, jnp.sqrt(problem.likelihood_power))


@eqx.filter_jit
def _solve(problem: FitProblem, u_phys, u_noise, solver, max_steps: int):
    sol = optx.least_squares(_lm_objective_residuals, solver, u_phys, args=(problem, u_noise),
                             max_steps=max_steps, throw=False)
    return sol.value, sol.result, sol.stats["num_steps"]


@eqx.filter_jit
def log_density(problem: FitProblem, u):
    return problem.log_density(u)


@eqx.filter_jit
def _noise_update(problem: FitProblem, u):
    """Closed-form noise update at u: ρ_r = the conditional MLE Σ e_t e_{t−1} / Σ e_{t−1}² of the
    residuals (AR(1) runs), σ_r² = mean innovation², s_r² = σ_r² − floor_r² (kept positive); over
    the pairs of samples in the likelihood (``FitProblem.likelihood_keep``)."""
    # all runs at once (problem.sum_runs): sums over each run's pairs (e_{t-1}, e_t), t ≥ 1
    e = jnp.concatenate(problem.residuals(u))
    later = ~problem.first_samples()
    n_pairs = np.asarray(problem.run_lengths) - 1.0
    if problem.likelihood_keep is not None:
        # pairs of two samples in the likelihood (the others' residuals do not enter)
        keep = jnp.concatenate(problem.likelihood_keep)
        later = later & keep & jnp.concatenate([jnp.zeros(1, bool), keep[:-1]])
        n_pairs = jnp.maximum(problem.sum_runs(later.astype(e.dtype)), 1.0)
    prev = jnp.where(later, jnp.concatenate([jnp.zeros(1, e.dtype), e[:-1]]), 0.0)
    ar1 = np.asarray(problem.ar1)
    if problem.student_t_dof:
        return _robust_noise_update(problem, u, e, prev, later)
    rho = jnp.zeros(problem.n_runs, e.dtype)
    if ar1.any():
        # not demeaned: the likelihood's AR(1) has mean zero, and a run's constant misfit (TE
        # runs sharing one zero offset) stays in its innovations — with ρ of the demeaned
        # residual (≈ 0 for a level plus white noise) that level counted as white noise, and a
        # diagnose refit that removed a periodic error scored below the model without it
        fit = jnp.clip(problem.sum_runs(e * prev) / jnp.maximum(problem.sum_runs(prev**2), 1e-300), 0.01, _RHO_CAP)
        rho = jnp.where(ar1, fit, 0.0)
    innov2 = jnp.where(later, (e - problem.per_sample(rho) * prev) ** 2, 0.0)
    floor2 = problem.floors**2
    if problem.noise_shape is not None:
        # σ_i² = (s w_i)² + floor²: s² from the innovations above the floor, each over w_i²
        w2 = jnp.concatenate(problem.noise_shape) ** 2
        var_s = problem.sum_runs(jnp.maximum(innov2 - problem.per_sample(floor2), 0.0) / w2) / n_pairs
        log_s = 0.5 * jnp.log(jnp.maximum(var_s, 1e-4 * jnp.maximum(floor2, 1e-26)))
    else:
        var = problem.sum_runs(innov2) / n_pairs
        log_s = 0.5 * jnp.log(jnp.maximum(var - floor2, jnp.maximum(1e-4 * jnp.maximum(floor2, var), 1e-30)))
    rho_ar1 = rho[np.flatnonzero(ar1)]
    return jnp.concatenate([log_s, jnp.log(rho_ar1) - jnp.log(RHO_MAX - rho_ar1)])


def _robust_noise_update(problem: FitProblem, u, e, prev, later):
    """:func:`_noise_update` under a Student-t likelihood: the EM fixed point of its scale
    mixture, ``ROBUST_NOISE_ITERATIONS`` rounds from the noise at u. Each round weighs every
    innovation by (ν+1)/(ν+r²), r the innovation over its sample's scale (noise, floor and
    errors in variables, as the likelihood), and takes the weighted conditional MLE of ρ_r and
    the weighted stationarity of s_r: a jump the heavy tail explains no longer inflates the level
    or drags ρ."""
    nu = problem.student_t_dof
    n = problem.n_nonlinear
    ar1 = jnp.asarray(problem.ar1)
    floor2 = problem.per_sample(problem.floors**2)
    eiv = jnp.concatenate(problem.eiv_var)
    shape2 = (jnp.concatenate(problem.noise_shape) ** 2 if problem.noise_shape is not None
              else jnp.ones_like(e))
    # the samples in the likelihood; those that are not pairs' second (a run's or a kept
    # stretch's first) enter whitened as Prais–Winsten's first sample, e·√(1 − ρ²)
    kept = jnp.concatenate(problem.likelihood_keep) if problem.likelihood_keep is not None else jnp.ones(e.shape, bool)

    def innovations(rho):
        r = problem.per_sample(rho)
        return jnp.where(later, e - r * prev, e * jnp.sqrt(1.0 - r**2))

    def em_round(_, state):
        s2, rho = state
        scale2 = problem.per_sample(s2) * shape2 + floor2 + eiv
        weight = jnp.where(kept, student_t_weights(innovations(rho) ** 2 / scale2, nu), 0.0)
        pair_weight = jnp.where(later, weight, 0.0)
        fit = jnp.clip(problem.sum_runs(pair_weight * e * prev) / jnp.maximum(problem.sum_runs(pair_weight * prev**2), 1e-300),
                       0.01, _RHO_CAP)
        rho = jnp.where(ar1, fit, 0.0)
        # the likelihood's stationarity in s², scale² = s²·shape² + floor² + eiv:
        # Σ shape²/scale² · (w·innov²/scale² − 1) = 0, as a multiplicative fixed point (EM's
        # s² = mean(w·innov²/shape²) where floor and eiv vanish)
        at = jnp.where(kept, shape2 / scale2, 0.0)
        ratio = problem.sum_runs(at * weight * innovations(rho) ** 2 / scale2) / problem.sum_runs(at)
        return jnp.maximum(s2 * ratio, 1e-4 * jnp.maximum(problem.floors**2, 1e-26)), rho

    s2, rho = jax.lax.fori_loop(0, ROBUST_NOISE_ITERATIONS, em_round,
                                (jnp.exp(2.0 * u[n:n + problem.n_runs]), problem.noise_values(u)[1]))
    rho_ar1 = rho[np.flatnonzero(problem.ar1)]
    return jnp.concatenate([0.5 * jnp.log(s2), jnp.log(rho_ar1) - jnp.log(RHO_MAX - rho_ar1)])


def noise_pass(problem: FitProblem, u_phys, u_noise, solver, max_steps: int):
    """One noise pass of ``fit_map``: LM on the physics, then the closed-form noise update, and
    the log density there: (u_phys, u_noise, solver result, log density)."""
    u_phys, result, _ = _solve(problem, u_phys, u_noise, solver, max_steps)
    u_noise = _noise_update(problem, jnp.concatenate([u_phys, u_noise]))
    return u_phys, u_noise, result, problem.log_density(jnp.concatenate([u_phys, u_noise]))


#: one compiled program per pass (compilation dominates a cold fit)
_solve_pass = _map_jit(noise_pass)


def _physics_jacobian(problem: FitProblem, u):
    n = problem.n_nonlinear
    return jax.jacfwd(lambda a: _lm_residuals(a, (problem, u[n:])))(u[:n])


def laplace_parts(problem: FitProblem, u):
    """At u: the physics Jacobian, (σ_r, ρ_r), every parameter value, and the whitened residuals,
    per-sample scales and whitened design of all runs (:meth:`FitProblem.profile_all`) — one
    program for what a fit reads at its optimum (the misfit check and the linearised LOO read the
    last three: programs of their own compiled the model once more for each fit)."""
    sigma, rho = problem.noise_values(u)
    white, _, _, scales, _ = problem.profile_all(u)  # the same profile as full_values' (one in XLA)
    return (_physics_jacobian(problem, u), sigma, rho, problem.full_values(u),
            (white, scales, problem.whitened_design(scales, rho)))


_laplace_parts = _map_jit(laplace_parts)


def _objective_parts(problem: FitProblem, u):
    """What LM minimises (½‖r‖²) at u: its residuals r and their Jacobian in the physics block."""
    n = problem.n_nonlinear
    f = lambda a: _lm_objective_residuals(a, (problem, u[n:]))  # noqa: E731
    return f(u[:n]), jax.jacfwd(f)(u[:n])


_objective_parts_jit = _map_jit(_objective_parts)


@in_float64
def newton_step(problem: FitProblem, u) -> tuple[float, np.ndarray]:
    """How far the MAP's objective says its optimum is from u: (λ, z). The Gauss–Newton step δ
    from u (−δ, δ the least-squares solution of J δ = r), measured by the objective's own curvature:
    λ = √(δᵀ JᵀJ δ), the step in posterior standard deviations (the Newton decrement: λ²/2 is
    the log density the step is predicted to gain), and z_k = δ_k / sd_k per physics parameter
    (|z_k| ≤ λ). Near 0 at an optimum; a point where LM stopped with λ of order 1 or more is
    not at one (on a smooth objective the step is there to take; where it is not taken the
    objective is not smooth along it)."""
    r, jac = _objective_parts_jit(problem, jnp.asarray(u))
    r, jac = np.asarray(r, float), np.asarray(jac, float)
    step = -np.linalg.lstsq(jac, r, rcond=None)[0]  # u − δ minimises the linearised ½‖r + J·step‖²
    lam = float(np.linalg.norm(jac @ step))
    sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(jac.T @ jac)), 1e-300, None))
    return lam, step / sd


def stopped_short(problem: FitProblem, run_names, u, message: str) -> tuple[float, str]:
    """For a solve that ended without meeting its tolerance at u: (λ, the solver's ``message``
    with the Newton step from u, :func:`newton_step` — how far the optimum is and along which
    parameter)."""
    lam, z = newton_step(problem, u)
    names = problem.names(run_names)
    k = int(np.argmax(np.abs(z)))
    return lam, (f"{message.split('. ')[0].rstrip('.')}; the Gauss–Newton step from there is {lam:.2g} posterior sd "
                 f"(largest along {names[k]}, {z[k]:+.2g} sd)")


@in_float64
def laplace_covariance(problem: FitProblem, u) -> np.ndarray:
    """Laplace covariance of u at the MAP: Gauss–Newton (JᵀJ)⁻¹ for the physics (J of the
    whitened residuals and prior pseudo-residuals), the asymptotic variances for the noise
    parameters (var log σ ≈ 1/2N, var ρ ≈ (1 − ρ²)/N, mapped to s and logit(ρ/ρ_max) and capped by
    their priors). The two blocks are taken as uncorrelated, as they are asymptotically."""
    jac, sigma, rho, _, _ = _laplace_parts(problem, jnp.asarray(u))
    return laplace_from_parts(problem, u, jac, sigma, rho)


@in_float64
def laplace_from_parts(problem: FitProblem, u, jac, sigma, rho) -> np.ndarray:
    """:func:`laplace_covariance` from its parts at u: the physics Jacobian ``jac`` and the noise
    values (σ_r, ρ_r) — computed for many units at once by ``torsionfit.batch``."""
    u, jac = np.asarray(u), np.asarray(jac)
    sigma, rho = np.asarray(sigma), np.asarray(rho)
    n = problem.n_nonlinear
    cov = np.zeros((problem.dim, problem.dim))
    cov[:n, :n] = np.linalg.pinv(jac.T @ jac)
    counts = np.array([len(y) for y in problem.y], float)
    s2 = np.exp(2 * u[n:n + problem.n_runs])
    var_log_s = (sigma**2 / np.maximum(s2, 1e-300)) ** 2 / (2 * counts)
    if problem.student_t_dof:
        # a t scale's Fisher information per sample is 2ν/(ν+3) of the Gaussian's 2
        var_log_s = var_log_s * (problem.student_t_dof + 3.0) / problem.student_t_dof
    var_log_s = np.minimum(var_log_s, NOISE_PRIOR_SD**2)
    for r in range(problem.n_runs):
        cov[n + r, n + r] = var_log_s[r]
    k = n + problem.n_runs
    for r in np.flatnonzero(problem.ar1):
        p, q = rho[r], rho[r] / RHO_MAX  # dρ/du = ρ_max q (1 − q)
        var = (1 - p**2) / (counts[r] * max(RHO_MAX * q * (1 - q), 1e-12) ** 2)
        cov[k, k] = min(var, RHO_PRIOR_SD**2)
        k += 1
    return cov


@dataclass(frozen=True, eq=False)
class MapResult:
    """The MAP point and its Laplace approximation (in the unconstrained space u)."""

    problem: FitProblem
    run_names: tuple
    u: np.ndarray  # unconstrained MAP, length problem.dim
    cov: np.ndarray  # Laplace covariance of u
    values: dict  # every model parameter at the MAP, SI
    log_density: float
    converged: bool
    message: str  # optimistix's result for the chosen start
    starts: list = field(default_factory=list)  # (log_density, message) per start (shared: same optimum)
    #: not converged: the Gauss–Newton step from u in posterior sd (:func:`newton_step`); None when converged
    newton_step_sd: float | None = None
    #: (log density, u, converged) of each distinct optimum the starts reached, highest first
    optima: tuple = ()

    @property
    def names(self) -> list[str]:
        return self.problem.names(self.run_names)

    @property
    def sd(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    @in_float64
    def components(self) -> list[dict]:
        """Model components per run at the MAP (rad)."""
        inputs = self.problem.corrected_inputs(jnp.asarray(self.u))
        comps = self.problem.model.components(self.values, inputs)
        return [{k: np.asarray(v) for k, v in c.items()} for c in comps]


def _message(result) -> str:
    if result == optx.RESULTS.successful:
        return "successful"
    try:
        return str(optx.RESULTS[result])
    except Exception:  # noqa: BLE001 - the code is what we have
        return f"optimistix result {result}"


@in_float64
def map_starts(problem: FitProblem, n_starts: int, seed: int) -> np.ndarray:
    """(n_starts, n_nonlinear) starting points: the prior centre, then draws around it."""
    rng = np.random.default_rng(seed)
    prior_mean, prior_sd = np.asarray(problem.prior_mean), np.asarray(problem.prior_sd)
    if n_starts < 1:  # warm starts alone (fit_map's ``warm_starts``)
        return np.zeros((0, problem.n_nonlinear))
    starts = [prior_mean.copy()]
    for _ in range(n_starts - 1):
        starts.append(prior_mean + 0.7 * prior_sd * rng.standard_normal(problem.n_nonlinear))
    return np.stack(starts)


def _with_warm_starts(problem: FitProblem, starts: np.ndarray, warm) -> list:
    """(u_phys, u_noise or None) per start, the warm ones first: a warm start of length
    ``problem.dim`` brings its own noise block, one of length ``n_nonlinear`` starts from iid
    noise as the prior's starts do."""
    out = []
    for w in ([] if warm is None else np.atleast_2d(np.asarray(warm, float))):
        if w.size not in (problem.n_nonlinear, problem.dim):
            raise ValueError(f"warm starts have {w.size} entries, the problem's non-linear block {problem.n_nonlinear} "
                             f"(or all of u, {problem.dim})")
        out.append((w[:problem.n_nonlinear], w[problem.n_nonlinear:] if w.size == problem.dim else None))
    return out + [(start, None) for start in starts]


def nested_start(problem: FitProblem, run_names, u_from, names_from) -> np.ndarray:
    """A starting point for ``problem`` from another fit of the same runs: every entry whose
    name the other fit has takes its value there, the rest their prior centre (for a model that
    extends the other one: its optimum, with the new parameters at their priors) — except a new
    parameter the smaller model is the zero limit of
    (:attr:`~torsionfit.model.Parameter.vanishes_at_zero`): three prior sds below its centre,
    where the extension is the smaller model. The non-linear block; the whole of u (its noise
    levels and AR(1) coefficients too) when the other fit names them all, so that the start's
    first pass weighs the residuals as the other fit's optimum did (from iid noise the first
    pass moved a measured loop's extension away from the optimum it contains, to a fit 61 nats
    lower)."""
    names = problem.names(run_names)
    index = {name: i for i, name in enumerate(names_from)}
    full = all(name in index for name in names[problem.n_nonlinear:])
    start = np.zeros(problem.dim if full else problem.n_nonlinear)
    start[:problem.n_nonlinear] = np.asarray(problem.prior_mean, float)
    at_zero = problem.vanishing_at_zero()
    for j, name in enumerate(names[:start.size]):
        if name in index:
            start[j] = float(u_from[index[name]])
        elif j in at_zero:
            start[j] = float(problem.prior_mean[j]) - 3.0 * float(problem.prior_sd[j])
    return start


def iid_noise(problem: FitProblem) -> np.ndarray:
    """The first pass's noise block: prior noise levels, ρ ≈ 0 (iid). A NumPy array (float64),
    as the starts: a jitted pass takes it as it is, where ``jnp.asarray`` compiled a program."""
    return np.concatenate([np.asarray(problem.noise_prior_mean, np.float64), np.full(problem.n_ar1, -30.0)])


def best_start(us, lds, oks, messages):
    """(u, log density, converged, message) of the start with the highest finite log density
    (the first on ties); RuntimeError when no start is finite."""
    best = None
    for u, ld, ok, message in zip(us, lds, oks, messages):
        if np.isfinite(ld) and (best is None or ld > best[1]):
            best = (np.asarray(u), float(ld), bool(ok), message)
    if best is None:
        raise RuntimeError("MAP failed from every start: " + "; ".join(messages))
    return best


#: starts whose first-pass optima agree to this (relative to max(|u|, 1)) share the later passes
SAME_OPTIMUM_RTOL = 1e-6


def same_optimum(firsts) -> list[int]:
    """For each start's first-pass physics ``u``: the index of the first start that reached the
    same optimum (itself when none before it did). Non-finite points are never merged."""
    firsts = [np.asarray(u, float) for u in firsts]
    rep = []
    for j, u in enumerate(firsts):
        match = j
        if np.all(np.isfinite(u)):
            for i in sorted(set(rep)):
                v = firsts[i]
                if np.all(np.isfinite(v)) and np.max(np.abs(u - v) / np.maximum(np.maximum(np.abs(u), np.abs(v)), 1.0)) < SAME_OPTIMUM_RTOL:
                    match = i
                    break
        rep.append(match)
    return rep


@in_float64
def fit_map(problem: FitProblem, run_names=None, *, n_starts: int = 4, seed: int = 0,
            max_steps: int = 300, noise_passes: int = 3, rtol: float = 1e-8,
            atol: float = 1e-10, warm_starts=None, polish_steps: int = 300, continuations: int = 0) -> MapResult:
    """MAP by Levenberg–Marquardt from ``n_starts`` starts (the prior centre, then draws around
    it; 0: the warm starts alone). The first pass treats the noise as iid (with ρ near 1 the whitened residuals are
    increments, and a fit from far away can match the loop's shape but not its level);
    between passes the noise level and AR(1) coefficient are re-estimated in closed form.
    Starts whose first pass ends at the same optimum (:data:`SAME_OPTIMUM_RTOL`) share the
    later passes: they would repeat the same steps from the same point. ``warm_starts``:
    (k, n_nonlinear) further starting points tried first (e.g. a nested model's optimum), or
    (k, dim) with their noise block, which their first pass then uses instead of iid noise.
    ``max_steps`` caps each start's first pass, ``polish_steps`` the later passes, which run
    from near an optimum for the distinct optima only: on a measured loop's long
    ridges LM may need more there (``fit_campaign`` gives
    :attr:`FitOptions.map_steps` for both; diagnose's screening fits keep these defaults). Each
    budget is part of a compiled program: equal budgets compile the solve once. ``continuations``:
    where the chosen optimum's last pass ended at its budget without meeting the tolerance, up to
    this many more passes from where it stopped, with the same budget (the same compiled
    program): the step budget grows only for the fit that needs it."""
    if noise_passes < 1:
        raise ValueError(f"noise_passes must be at least 1, got {noise_passes}")
    if n_starts < 1 and warm_starts is None:
        raise ValueError("fit_map: n_starts = 0 needs warm_starts to start from")
    run_names = tuple(run_names or (f"run{i}" for i in range(problem.n_runs)))
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    iid = iid_noise(problem)
    # NumPy starts: the jitted pass takes them as they are (jnp.asarray compiled a program per shape)
    firsts = [_solve_pass(problem, np.asarray(start, float), iid if noise is None else np.asarray(noise, float),
                          solver, max_steps)
              for start, noise in _with_warm_starts(problem, map_starts(problem, n_starts, seed), warm_starts)]
    rep = same_optimum([f[0] for f in firsts])
    finals = {}
    for j in sorted(set(rep)):
        u_phys, u_noise, result, ld = firsts[j]
        for _ in range(noise_passes - 1):
            u_phys, u_noise, result, ld = _solve_pass(problem, u_phys, u_noise, solver, polish_steps)
        finals[j] = (np.concatenate([np.asarray(u_phys), np.asarray(u_noise)]), float(ld),
                     bool(result == optx.RESULTS.successful), _message(result))
    us, lds, oks, messages = zip(*(finals[r] for r in rep))
    u, ld, ok, message = best_start(us, lds, oks, messages)
    n = problem.n_nonlinear
    for _ in range(continuations if not ok else 0):
        u_phys, u_noise, result, pass_ld = _solve_pass(problem, u[:n], u[n:], solver, polish_steps)
        if not np.isfinite(float(pass_ld)):
            break  # keep the finite point it started from
        u, ld = np.concatenate([np.asarray(u_phys), np.asarray(u_noise)]), float(pass_ld)
        ok, message = bool(result == optx.RESULTS.successful), _message(result)
        if ok:
            break
    step_sd = None
    if not ok:
        step_sd, message = stopped_short(problem, run_names, u, message)
    jac, sigma, rho, values, _ = _laplace_parts(problem, u)
    cov = laplace_from_parts(problem, u, jac, sigma, rho)
    values = {k: np.asarray(v) for k, v in values.items()}
    return MapResult(problem=problem, run_names=run_names, u=u, cov=cov, values=values,
                     log_density=ld, converged=ok, message=message, starts=list(zip(lds, messages)),
                     newton_step_sd=step_sd,
                     optima=tuple(sorted(((f[1], f[0], f[2]) for f in finals.values() if np.isfinite(f[1])),
                                         key=lambda o: -o[0])))


#: a rival optimum this many posterior sd or more from the MAP lies beyond the intervals' reach
RIVAL_DISTANCE_SD = 3.0
#: ... and within this many nats of its log posterior (as widened) carries comparable mass
RIVAL_LOG_DENSITY_GAP = 3.0


def rival_optima(best_u, best_log_density: float, optima, cov_physics, likelihood_power: float = 1.0) -> list[dict]:
    """The optima in ``optima`` ((log density, u, converged) of one problem, e.g.
    :attr:`MapResult.optima`) other than the MAP ``best_u``: for each, its log posterior below the MAP's (``log_density_gap``,
    as the starts' problem scores it, and ``log_density_gap_widened``, times ``likelihood_power``:
    the gap of the posterior the intervals are drawn from when it was widened for misfit) and its
    distance from the MAP in that posterior's sd (``distance_sd``: Mahalanobis over the physics
    block, ``cov_physics`` its covariance); ``rival``: converged, far (≥ :data:`RIVAL_DISTANCE_SD`)
    and close in density (≤ :data:`RIVAL_LOG_DENSITY_GAP`): the intervals, drawn around one
    optimum, do not reach another the data support about as well. A start that stopped short of its
    tolerance is listed (``converged`` false), never a rival: it may be on its way to the MAP."""
    best_u = np.asarray(best_u, float)
    n = np.shape(cov_physics)[0]
    precision = np.linalg.pinv(np.asarray(cov_physics, float))
    out = []
    for ld, u, converged in optima:
        d = np.asarray(u, float)[:n] - best_u[:n]
        distance = float(np.sqrt(max(d @ precision @ d, 0.0)))
        if distance < 1e-6:
            continue  # the MAP itself
        gap = float(best_log_density - ld)
        widened = gap * float(likelihood_power)
        out.append({"log_density_gap": gap, "log_density_gap_widened": widened, "distance_sd": distance,
                    "converged": bool(converged),
                    "rival": bool(converged and distance >= RIVAL_DISTANCE_SD and widened <= RIVAL_LOG_DENSITY_GAP)})
    return out


def rival_note(rivals: list[dict]) -> str:
    """One line when :func:`rival_optima` found a rival; empty otherwise."""
    close = [r for r in rivals if r["rival"]]
    if not close:
        return ""
    r = min(close, key=lambda r: r["log_density_gap_widened"])
    return (f"the starts reached {len(close)} other optimum(s) the data support about as well: the closest "
            f"{r['log_density_gap_widened']:.2g} below the MAP's log posterior (as widened), {r['distance_sd']:.0f} "
            f"posterior sd from it; the intervals are drawn around one of them, and its predictions can differ "
            f"from theirs — more starts (--starts) show how many there are")
