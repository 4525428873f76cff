"""Maximum a posteriori fit: optimistix Levenberg–Marquardt from several starts, then a
Laplace approximation of the posterior at the optimum."""

from dataclasses import dataclass, field

import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ._problem import FitProblem


@dataclass(frozen=True, eq=False)
class MapResult:
    """The MAP point and its Laplace approximation (in the unconstrained space u)."""

    problem: FitProblem
    u: np.ndarray  # unconstrained MAP, length problem.dim
    cov: np.ndarray  # Laplace covariance of u
    values: dict  # every model parameter at the MAP, SI
    log_density: float
    converged: bool
    message: str  # optimistix's result for the chosen start
    starts: list = field(default_factory=list)  # (log_density, message) per start

    @property
    def sd(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0, None))

    def components(self) -> list[dict]:
        """Model components per run at the MAP (rad)."""
        comps = self.problem.model.components(self.values, self.problem.inputs)
        return [{k: np.asarray(v) for k, v in c.items()} for c in comps]


def _lm_residuals(problem: FitProblem):
    def fn(u_phys, u_noise):
        white, _, _ = problem.profile(jnp.concatenate([u_phys, u_noise]))
        return jnp.concatenate(white + [problem.prior_residuals(u_phys)])

    return fn


def _update_noise(problem: FitProblem, u) -> np.ndarray:
    """Closed-form noise update from the residuals at u: ρ_r = lag-1 autocorrelation,
    σ_r² = mean innovation², s_r² = σ_r² − floor_r² (kept positive)."""
    values = problem.full_values(jnp.asarray(u))
    preds = problem.model.predict(values, problem.inputs)
    log_s, logits = [], []
    for r, (y, f) in enumerate(zip(problem.y, preds)):
        e = np.asarray(y - f)
        rho = 0.0
        if problem.ar1[r]:
            e0 = e - e.mean()
            rho = float(np.clip(np.dot(e0[1:], e0[:-1]) / max(np.dot(e0, e0), 1e-300), 0.01, 0.995))
            logits.append(np.log(rho / (1 - rho)))
        innov = e[1:] - rho * e[:-1]
        var = float(np.mean(innov**2))
        floor2 = problem.floors[r] ** 2
        log_s.append(0.5 * np.log(max(var - floor2, 1e-4 * max(floor2, var), 1e-30)))
    return np.asarray(log_s + logits)


def _laplace(problem: FitProblem, u) -> np.ndarray:
    """Covariance = inverse of the negative Hessian of the log-density at u; falls back to
    Gauss–Newton for the physics if that Hessian is not positive definite."""
    h = np.asarray(jax.hessian(problem.log_density)(jnp.asarray(u)))
    h = 0.5 * (h + h.T)
    try:
        np.linalg.cholesky(-h)
        return np.linalg.inv(-h)
    except np.linalg.LinAlgError:
        fn = _lm_residuals(problem)
        n = problem.n_physics
        jac = np.asarray(jax.jacfwd(lambda a: fn(a, jnp.asarray(u[n:])))(jnp.asarray(u[:n])))
        cov = np.diag(np.full(problem.dim, 1e-2))
        cov[:n, :n] = np.linalg.pinv(jac.T @ jac)
        return cov


def fit_map(problem: FitProblem, *, n_starts: int = 4, seed: int = 0, max_steps: int = 300,
            noise_passes: int = 3, rtol: float = 1e-8, atol: float = 1e-10) -> MapResult:
    """MAP by Levenberg–Marquardt from ``n_starts`` starts (the prior centre, then draws around
    it); between passes the noise level and AR(1) coefficient are re-estimated in closed form."""
    rng = np.random.default_rng(seed)
    n = problem.n_physics
    solver = optx.LevenbergMarquardt(rtol=rtol, atol=atol)
    fn = _lm_residuals(problem)
    log_density = jax.jit(problem.log_density)

    starts = [problem.prior_mean.copy()]
    for _ in range(n_starts - 1):
        starts.append(problem.prior_mean + 0.7 * problem.prior_sd * rng.standard_normal(n))

    best, records = None, []
    for start in starts:
        # The first pass is iid (ρ → 0: logit −30): with ρ near 1 the whitened residuals are
        # increments and a fit from far away can match the loop's shape but not its level.
        iid = np.concatenate([problem.noise_prior_mean, np.full(problem.n_ar1, -30.0)])
        u_phys, u_noise, message = jnp.asarray(start), jnp.asarray(iid), ""
        ok = True
        for _ in range(noise_passes):
            sol = optx.least_squares(fn, solver, u_phys, args=u_noise, max_steps=max_steps, throw=False)
            ok = sol.result == optx.RESULTS.successful
            message = "successful" if ok else optx.RESULTS[sol.result] if hasattr(optx.RESULTS, "__getitem__") else str(sol.result)
            u_phys = sol.value
            u_noise = jnp.asarray(_update_noise(problem, np.concatenate([np.asarray(u_phys), np.asarray(u_noise)])))
        u = np.concatenate([np.asarray(u_phys), np.asarray(u_noise)])
        ld = float(log_density(jnp.asarray(u)))
        records.append((ld, message))
        if np.isfinite(ld) and (best is None or ld > best[1]):
            best = (u, ld, bool(ok), message)
    if best is None:
        raise RuntimeError("MAP failed from every start: " + "; ".join(m for _, m in records))
    u, ld, ok, message = best
    cov = _laplace(problem, u)
    return MapResult(problem=problem, u=u, cov=cov, values=problem.full_values(jnp.asarray(u)),
                     log_density=ld, converged=ok, message=message, starts=records)
