"""The best plain NumPy/SciPy pipeline we could write for torsionfit's hysteresis fit.

Same model, same data, same log-density, same sampler as ``fit_campaign`` with the default
options on a campaign of hysteresis runs (base model: linear compliance, Dahl friction with a
free initial state, smooth backlash, per-run angle offset; latent torque lines per ramp; errors-in-
variables variance; AR(1) noise), written without JAX:

- **Data preparation** (:func:`build`): torsionfit's own NumPy preprocessing — the denoised
  drive torque and its variance (``denoise_torque``), the latent torque lines per ramp (``ramp_line_basis``),
  the priors (``build_priors``). Nothing here is JAX, so both pipelines start from the same
  numbers.
- **Model** (:meth:`NumpyProblem.predict`): vectorised over walkers. Arrays are laid out
  (samples, walkers) so that the Dahl recurrence ``z[n] = a[n]·z[n−1] + b[n]`` is a tight
  loop over samples in which every step updates all walkers at once with two in-place ufunc
  calls on contiguous rows (the fastest of the plain-NumPy loops we timed: 1.8× faster than
  a Python-float loop per walker, 6× faster than a chunked closed form). For one parameter
  set (the optimiser's residuals) the loop runs over Python floats, which is faster there.
- **Log-density** (:meth:`NumpyProblem.log_density`): ``FitProblem.log_density`` term by
  term — the angle offset profiled analytically (one linear parameter: a closed-form weighted
  mean of the whitened residuals, marginalised under a flat prior), AR(1) Prais–Winsten
  whitening, per-sample scales √(σ² + eiv_i) (the errors-in-variables variance torsionfit reads
  from the data), normal priors in u.
  ``tests/test_scipy_pipeline_reference.py`` checks it equals torsionfit's to 1e-10 relative.
- **MAP** (:func:`fit_map`): ``fit_map``'s algorithm with ``scipy.optimize.least_squares``
  (MINPACK Levenberg–Marquardt, ``x_scale="jac"``): the same starts (prior centre, then draws
  around it from the same seed), the same three passes with the closed-form noise update in
  between, the same Laplace covariance. The Jacobian is by forward differences, all columns
  in one walker-vectorised model call (13 perturbed points cost about as much as 3 single
  evaluations).
- **Posterior** (:func:`run_emcee`): emcee exactly as ``run_sampler`` calls it (its move
  mixture — the Laplace independence move, DE and stretch, ``torsionfit.sample._emcee.moves``,
  plain NumPy — ``vectorize=True``, the same walker count, the same Laplace start and
  random state, τ checked every 500 steps, the same stopping rule, burn-in and thinning —
  ``run_sampler``'s own helpers are reused), plus an optional wall-time budget.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from torsionfit.fit._denoise import denoise_torque
from torsionfit.fit._torque_error import angle_variance_from_torque_error, ramp_line_basis, torque_line_labels
from torsionfit.fit._map import same_optimum
from torsionfit.fit._prior import build_priors
from torsionfit.fit._problem import AR1_MIN_SAMPLES, NOISE_PRIOR_SD, RHO_MAX, RHO_PRIOR_SD
from torsionfit.io import HysteresisRun
from torsionfit.model import Parameter
from torsionfit.sample._emcee import (_burn_thin, _check, _regularised_cov, _retire_if_rejected, _tau,
                                      default_n_walkers, moves)

#: the base model's non-linear parameters, in torsionfit's order, with their bijections
PHYSICS = (
    Parameter("stiffness", "positive", "N·m/rad", "elastic stiffness K"),
    Parameter("friction_torque", "positive", "N·m", "Coulomb friction level T_f"),
    Parameter("dahl_torque", "positive", "N·m", "torque change τ_d to saturate friction"),
    Parameter("gap", "positive", "rad", "geometric gap β"),
    Parameter("gap_torque", "positive", "N·m", "mesh torque τ_β over which the gap closes"),
)
_RHO_CAP = RHO_MAX * (1.0 - 1e-3)
_LOG_2PI = math.log(2.0 * math.pi)


def _affine_rows(a, b, x0, out):
    """out[0] = x0, out[n+1] = a[n]·out[n] + b[n]; ``a``, ``b`` (N−1, W), ``out`` (N, W).

    The tight loop: one step per sample, all walkers at once, two in-place ufunc calls on
    contiguous rows, no temporaries.
    """
    out[0] = x0
    mul, add = np.multiply, np.add
    prev = out[0]
    for an, bn, o in zip(a, b, out[1:]):
        mul(an, prev, out=o)
        add(o, bn, out=o)
        prev = o
    return out


def _dahl_by_runs(d_tau, t_d, z0, out, max_runs: int = 64):
    """The Dahl state without a loop over samples, or None when the torque has more than
    ``max_runs`` monotone runs (then the caller uses the loop).

    Not what the benchmark compares (see :meth:`NumpyProblem.predict`); measured beside it.
    Within a run where sgn Δτ = s is constant the update z ← a z + s(1 − a) is
    z − s ← a (z − s), so z[n] = s + (z[start] − s)·exp(−Σ|Δτ|/τ_d) over the run: one cumulative
    sum per run, vectorised over samples and walkers. Runs are cut wherever any walker's sign
    changes (a zero increment, a = 1, belongs to any run). A five-step loop has three runs.
    """
    s = np.sign(d_tau)
    m = len(s)
    idx = np.where(s != 0, np.arange(m)[:, None], 0)  # forward-fill zero increments
    np.maximum.accumulate(idx, axis=0, out=idx)
    s = np.take_along_axis(s, idx, axis=0)
    starts = np.concatenate([[0], np.flatnonzero(np.any(s[1:] != s[:-1], axis=1)) + 1])
    if len(starts) > max_runs:
        return None
    e = np.abs(d_tau) / t_d
    out[0] = z0
    for i0, i1 in zip(starts, [*starts[1:], m]):
        c = np.cumsum(e[i0:i1], axis=0)
        np.negative(c, out=c)
        np.exp(c, out=c)
        sr = s[i0]
        out[i0 + 1:i1 + 1] = sr + (out[i0] - sr) * c
    return out


def _affine_floats(a, b, x0):
    """The same recurrence for one parameter set, over Python floats; returns (N,)."""
    x = float(x0)
    res = [x]
    append = res.append
    for an, bn in zip(a.tolist(), b.tolist()):
        x = an * x + bn
        append(x)
    return np.array(res)


def _angle(mesh, k, gap, t_g):
    """Elastic + gap angle of the mesh torque."""
    return mesh / k + 0.5 * gap * np.tanh(mesh / t_g)


@dataclass(eq=False)
class NumpyProblem:
    """One hysteresis run, base model with a free initial friction state. The layout of u is
    torsionfit's: 5 physics, friction_start (atanh z0), the latent torque lines, log s, then
    logit ρ when AR(1) is on."""

    time_s: np.ndarray
    tau: np.ndarray  # denoised drive torque, N·m (N,)
    eiv_var: np.ndarray  # the angle variance its error causes per sample, rad² (N,), torsionfit's
    y: np.ndarray  # measured angle, rad (N,)
    basis: np.ndarray  # (N, 2·ramps) level and tilt columns of the latent torque correction
    floor: float  # encoder floor, rad
    ar1: bool
    prior_mean: np.ndarray  # (n_nonlinear,)
    prior_sd: np.ndarray
    noise_prior_mean: float
    run_name: str = "run0"
    # --- sizes and names -------------------------------------------------------------------
    n_model = len(PHYSICS) + 1  # + friction_start

    @property
    def n_torque_lines(self) -> int:
        return int(self.basis.shape[1])

    @property
    def n_nonlinear(self) -> int:
        return self.n_model + self.n_torque_lines

    @property
    def dim(self) -> int:
        return self.n_nonlinear + 1 + int(self.ar1)

    def names(self) -> list[str]:
        out = [p.name for p in PHYSICS] + ["friction_start"]
        out += [f"torque_line[{self.run_name}]{label}" for label in torque_line_labels(self.n_torque_lines)]
        out += [f"noise[{self.run_name}]"] + ([f"ar1[{self.run_name}]"] if self.ar1 else [])
        return out

    def physics_values(self, u) -> dict:
        """Constrained physics from u (1-D) or a batch (W, dim)."""
        u = np.asarray(u, float)
        col = (lambda j: u[..., j])
        out = {p.name: np.exp(col(j)) for j, p in enumerate(PHYSICS)}
        out["friction_start"] = np.tanh(col(len(PHYSICS)))
        return out

    # --- model -----------------------------------------------------------------------------
    def predict(self, u, recurrence: str = "loop"):
        """Predicted angle without the offset, (W, dim) → (N, W) (samples × walkers).

        ``recurrence="loop"`` (what the benchmark compares): the Dahl recurrence as a tight
        loop over samples. ``"runs"``: its closed form per monotone run (:func:`_dahl_by_runs`),
        a shortcut that exploits the Dahl update's structure (not a general recurrence
        method), measured beside the loop to show what model-specific NumPy can do."""
        u = np.atleast_2d(np.asarray(u, float))
        k, t_f, t_d, gap, t_g = (np.exp(u[:, j]) for j in range(len(PHYSICS)))
        z0 = np.tanh(u[:, len(PHYSICS)])
        tau = self.tau[:, None] + self.basis @ u[:, self.n_model:self.n_nonlinear].T if self.n_torque_lines \
            else np.repeat(self.tau[:, None], len(u), axis=1)
        d_tau = np.diff(tau, axis=0)
        z = _dahl_by_runs(d_tau, t_d, z0, np.empty_like(tau)) if recurrence == "runs" else None
        if z is None:
            a = np.exp(-np.abs(d_tau) / t_d)
            b = np.sign(d_tau) * (1.0 - a)
            z = _affine_rows(a, b, z0, np.empty_like(tau))
        mesh = tau - t_f * z
        return _angle(mesh, k, gap, t_g)

    def predict_one(self, u):
        """The same for one parameter set (Python-float recurrence): (dim,) → (N,)."""
        u = np.asarray(u, float)
        with np.errstate(over="ignore"):
            k, t_f, t_d, gap, t_g = np.exp(u[:len(PHYSICS)]).tolist()
        z0 = math.tanh(u[len(PHYSICS)])
        tau = self.tau + self.basis @ u[self.n_model:self.n_nonlinear] if self.n_torque_lines else self.tau
        d_tau = np.diff(tau)
        a = np.exp(-np.abs(d_tau) / t_d)
        b = np.sign(d_tau) * (1.0 - a)
        z = _affine_floats(a, b, z0)
        mesh = tau - t_f * z
        return _angle(mesh, k, gap, t_g)

    # --- likelihood pieces -----------------------------------------------------------------
    def noise_values(self, u):
        """(σ, ρ) from u (1-D) or a batch (W, dim): arrays of shape () or (W,)."""
        u = np.asarray(u, float)
        n = self.n_nonlinear
        s = np.exp(u[..., n])
        sigma = np.sqrt(s**2 + self.floor**2)
        rho = RHO_MAX / (1.0 + np.exp(-u[..., n + 1])) if self.ar1 else np.zeros_like(s)
        return sigma, rho

    def _scales(self, sigma, batch: bool):
        """Per-sample innovation sd √(σ² + eiv_i): (N, W) for a batch of σ (W,), else (N,)."""
        return np.sqrt(sigma**2 + (self.eiv_var[:, None] if batch else self.eiv_var))

    @staticmethod
    def _whiten(x, scale, rho):
        """AR(1) innovations of x (N, W) or (N,), divided by ``scale`` (same shape)."""
        out = np.empty_like(scale)
        out[0] = x[0] * np.sqrt(1.0 - rho**2)
        np.multiply(rho, x[:-1], out=out[1:])
        np.subtract(x[1:], out[1:], out=out[1:])
        out /= scale
        return out

    def profile(self, u, pred=None, recurrence: str = "loop"):
        """Whitened residuals with the angle offset at its weighted-LS optimum, for u (dim,)
        or a batch (W, dim): (white (N[, W]), offset, log A, scales, ρ). A = Σ wx², the
        normal-equation "matrix" of the one linear parameter (torsionfit's 1e-10 trace
        regularisation included). ``pred``: the prediction of u, when known."""
        batch = np.ndim(u) == 2
        if pred is None:
            pred = self.predict(u, recurrence) if batch else self.predict_one(u)
        f = pred
        sigma, rho = self.noise_values(u)
        scales = self._scales(sigma, batch)
        y = self.y[:, None] if batch else self.y
        we = self._whiten(y - f, scales, rho)
        # whitened design column of the offset (a column of ones)
        wx = np.empty_like(scales)
        wx[0] = np.sqrt(1.0 - rho**2)
        wx[1:] = 1.0 - rho
        wx /= scales
        a = np.einsum("n...,n...->...", wx, wx)
        b = np.einsum("n...,n...->...", wx, we)
        a = a + 1e-10 * a
        beta = b / a
        white = we - wx * beta
        return white, beta, np.log(a), scales, rho

    def log_prior(self, u):
        u = np.asarray(u, float)
        n = self.n_nonlinear
        z = (u[..., :n] - self.prior_mean) / self.prior_sd
        lp = -0.5 * np.sum(z**2, axis=-1)
        lp = lp - 0.5 * ((u[..., n] - self.noise_prior_mean) / NOISE_PRIOR_SD) ** 2
        if self.ar1:
            lp = lp - 0.5 * (u[..., n + 1] / RHO_PRIOR_SD) ** 2
        return lp

    def log_density(self, u, recurrence: str = "loop"):
        """Log posterior of u (up to torsionfit's constant), offset marginalised; (W, dim) →
        (W,) (the walker-vectorised model) or (dim,) → float (the Python-float recurrence).
        Non-finite values (and non-finite u) become −inf."""
        u = np.asarray(u, float)
        batch = u.ndim == 2
        ok = np.all(np.isfinite(u), axis=-1)
        safe = np.where(ok[..., None], u, 0.0) if batch else (u if ok else np.zeros_like(u))
        with np.errstate(all="ignore"):
            white, _, logdet, scales, rho = self.profile(safe, recurrence=recurrence)
            ll = -0.5 * np.einsum("n...,n...->...", white, white) - np.sum(np.log(scales), axis=0)
            ll = ll - 0.5 * _LOG_2PI * white.shape[0] + 0.5 * np.log(1.0 - rho**2)
            lp = ll - 0.5 * logdet + self.log_prior(safe)
        lp = np.where(ok & np.isfinite(lp), lp, -np.inf)
        return lp if batch else float(lp)

    __call__ = log_density  # emcee's vectorised log-probability: (W, dim) → (W,)

    def residuals(self, u):
        """Raw residuals y − prediction (rad) with the offset at its optimum; u (dim,)."""
        pred = self.predict_one(u)
        _, beta, _, _, _ = self.profile(u, pred)
        return self.y - (pred + beta)

    def lm_residuals(self, u_nl, u_noise, pred=None):
        """fit_map's least-squares vector: whitened residuals, then the prior of the non-linear
        block as pseudo-residuals; u_nl (n_nonlinear,) or a batch (W, ·) → (M[, W])."""
        u_nl = np.asarray(u_nl, float)
        batch = u_nl.ndim == 2
        u = (np.concatenate([u_nl, np.broadcast_to(u_noise, (len(u_nl), len(u_noise)))], axis=1) if batch
             else np.concatenate([u_nl, u_noise]))
        white, _, _, _, _ = self.profile(u, pred)
        prior = (u_nl - self.prior_mean) / self.prior_sd
        return np.concatenate([white, prior.T if batch else prior], axis=0)


def build(campaign, *, latent_torque: bool = True, ar1: bool | None = None,
          denoise_fraction: float | None = None) -> NumpyProblem:
    """The NumPy problem for a campaign of one hysteresis run (torsionfit's preprocessing)."""
    runs = campaign.runs
    if len(runs) != 1 or not isinstance(runs[0], HysteresisRun):
        raise ValueError("the NumPy pipeline handles a campaign of exactly one hysteresis run")
    run = runs[0]
    tau, var, lines = denoise_torque(run.torque_Nm, denoise_fraction, return_lines=True)
    params = PHYSICS + (Parameter("friction_start", "signed_unit", "1", "z at the start"),)
    priors = build_priors(params, campaign)
    prior_mean = [priors[p.name][0] for p in params]
    prior_sd = [priors[p.name][1] for p in params]
    if latent_torque:
        basis, line_sd, var = ramp_line_basis(lines, var)
        prior_mean += [0.0] * basis.shape[1]
        prior_sd += list(np.maximum(line_sd, 1e-6))
    else:
        basis = np.zeros((len(run), 0))
    y = np.asarray(run.angle_rad, float)
    return NumpyProblem(
        time_s=np.asarray(run.time_s, float), tau=np.asarray(tau, float), eiv_var=angle_variance_from_torque_error(run.angle_rad, run.torque_Nm, tau, var),
        y=y, basis=np.ascontiguousarray(basis), floor=float(campaign.instrument.angle_floor_rad or 0.0),
        ar1=bool(len(run) >= AR1_MIN_SAMPLES) if ar1 is None else bool(ar1),
        prior_mean=np.asarray(prior_mean, float), prior_sd=np.asarray(prior_sd, float),
        noise_prior_mean=float(np.log(1e-2 * max(float(np.ptp(y)), 1e-9))), run_name=run.name,
    )


# --- MAP ------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class MapResult:
    u: np.ndarray
    cov: np.ndarray
    log_density: float
    converged: bool
    message: str
    names: list
    starts: list
    n_fev: int  # model evaluations (single parameter sets) over all starts and passes
    n_jev: int  # Jacobian evaluations (one batched model call each)


def _fd_jacobian(problem: NumpyProblem, u_nl, u_noise, r0=None, central=False):
    """Jacobian of ``lm_residuals`` w.r.t. u_nl by finite differences, every column in one
    walker-vectorised model call. Forward differences (MINPACK's step √ε·max(1, |u|)) for the
    optimiser; central differences (step ε^⅓·max(1, |u|)) for the Laplace covariance."""
    n = len(u_nl)
    scale = np.maximum(1.0, np.abs(u_nl))
    if central:
        h = np.finfo(float).eps ** (1 / 3) * scale
        pts = np.concatenate([u_nl + np.diag(h), u_nl - np.diag(h)])
        r = problem.lm_residuals(pts, u_noise)
        return (r[:, :n] - r[:, n:]) / (2 * h)
    h = np.sqrt(np.finfo(float).eps) * scale
    pts = u_nl + np.diag(h)
    r = problem.lm_residuals(pts, u_noise)
    if r0 is None:
        r0 = problem.lm_residuals(u_nl, u_noise)
    return (r - r0[:, None]) / h


def _noise_update(problem: NumpyProblem, u):
    """fit_map's closed-form noise update (ρ = lag-1 autocorrelation, σ² = innovation variance)."""
    e = problem.residuals(u)
    rho = 0.0
    out = []
    if problem.ar1:
        # not demeaned, the conditional MLE: as torsionfit's fit_map
        rho = float(np.clip(np.dot(e[1:], e[:-1]) / max(np.dot(e[:-1], e[:-1]), 1e-300), 0.01, _RHO_CAP))
    var = float(np.mean((e[1:] - rho * e[:-1]) ** 2))
    floor2 = problem.floor**2
    out.append(0.5 * math.log(max(var - floor2, max(1e-4 * max(floor2, var), 1e-30))))
    if problem.ar1:
        out.append(math.log(rho) - math.log(RHO_MAX - rho))
    return np.array(out)


def laplace_covariance(problem: NumpyProblem, u) -> np.ndarray:
    """torsionfit's Laplace covariance: Gauss–Newton for the non-linear block, asymptotic
    variances for log s and logit ρ, the two blocks uncorrelated."""
    n = problem.n_nonlinear
    jac = _fd_jacobian(problem, u[:n], u[n:], central=True)
    cov = np.zeros((problem.dim, problem.dim))
    cov[:n, :n] = np.linalg.pinv(jac.T @ jac)
    sigma, rho = problem.noise_values(u)
    count = len(problem.y)
    s2 = math.exp(2 * u[n])
    cov[n, n] = min((sigma**2 / max(s2, 1e-300)) ** 2 / (2 * count), NOISE_PRIOR_SD**2)
    if problem.ar1:
        p = float(rho)
        q = p / RHO_MAX
        cov[n + 1, n + 1] = min((1 - p**2) / (count * max(RHO_MAX * q * (1 - q), 1e-12) ** 2), RHO_PRIOR_SD**2)
    return cov


def fit_map(problem: NumpyProblem, *, n_starts: int = 4, seed: int = 0, max_nfev: int = 1000,
            noise_passes: int = 3, tol: float = 1e-8, polish_nfev: int = 1000) -> MapResult:
    """fit_map with scipy's MINPACK Levenberg–Marquardt; the same starts, passes (later passes
    shared by starts at one optimum), budgets (``fit_campaign``'s: 1000 for every pass) and
    Laplace covariance as torsionfit's."""
    rng = np.random.default_rng(seed)
    n = problem.n_nonlinear
    starts = [problem.prior_mean.copy()]
    for _ in range(n_starts - 1):
        starts.append(problem.prior_mean + 0.7 * problem.prior_sd * rng.standard_normal(n))
    iid = np.array([problem.noise_prior_mean] + ([-30.0] if problem.ar1 else []))
    n_fev = n_jev = 0

    def one_pass(u_phys, u_noise, max_nfev=max_nfev):
        nonlocal n_fev, n_jev
        cache = {}

        def fun(x):
            r = problem.lm_residuals(x, u_noise)
            cache["x"], cache["r"] = x.copy(), r
            return r

        def jac(x):
            r0 = cache["r"] if "x" in cache and np.array_equal(cache["x"], x) else problem.lm_residuals(x, u_noise)
            return _fd_jacobian(problem, x, u_noise, r0=r0)

        with np.errstate(all="ignore"):
            sol = least_squares(fun, u_phys, jac=jac, method="lm", x_scale="jac",
                                ftol=tol, xtol=tol, gtol=tol, max_nfev=max_nfev)
        n_fev += sol.nfev
        n_jev += sol.njev or 0
        return sol.x, _noise_update(problem, np.concatenate([sol.x, u_noise])), bool(sol.status > 0), sol.message

    # as torsionfit's fit_map: starts whose first pass meets at one optimum share the later passes
    firsts = [one_pass(start.copy(), iid.copy()) for start in starts]
    rep = same_optimum([f[0] for f in firsts])
    finals = {}
    for j in sorted(set(rep)):
        u_phys, u_noise, ok, message = firsts[j]
        for _ in range(noise_passes - 1):
            u_phys, u_noise, ok, message = one_pass(u_phys, u_noise, polish_nfev)
        u = np.concatenate([u_phys, u_noise])
        finals[j] = (u, problem.log_density(u), ok, message)
    best, records = None, []
    for j in rep:
        u, ld, ok, message = finals[j]
        records.append((ld, message))
        if np.isfinite(ld) and (best is None or ld > best[1]):
            best = (u, ld, ok, message)
    if best is None:
        raise RuntimeError("MAP failed from every start: " + "; ".join(m for _, m in records))
    u, ld, ok, message = best
    cov = laplace_covariance(problem, u)
    return MapResult(u=u, cov=cov, log_density=ld, converged=ok, message=message, names=problem.names(),
                     starts=records, n_fev=n_fev, n_jev=n_jev)


# --- emcee ----------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class EmceeResult:
    chain: np.ndarray  # (draws, walkers, dim) after burn-in and thinning
    tau: np.ndarray
    n_steps: int
    burn_in: int
    thin: int
    converged: bool
    reason: str
    tau_history: tuple
    acceptance_fraction: np.ndarray
    sampling_s: float  # wall time of the emcee blocks (τ checks included)
    budget_hit: bool = False


def initial_walkers(problem: NumpyProblem, u_map, cov, n_walkers: int, rng, max_rounds: int = 100):
    """run_sampler's start: N(u_map, regularised cov), re-drawn until finite."""
    chol = np.linalg.cholesky(_regularised_cov(cov))
    walkers = np.empty((n_walkers, len(u_map)))
    todo = np.ones(n_walkers, dtype=bool)
    for _ in range(max_rounds):
        walkers[todo] = u_map + rng.standard_normal((int(todo.sum()), len(u_map))) @ chol.T
        todo = ~np.isfinite(problem.log_density(walkers))
        if not todo.any():
            return walkers
    raise RuntimeError("walkers with a non-finite log-density after 100 rounds")


def run_emcee(problem: NumpyProblem, map_result: MapResult, *, seed: int, n_walkers: int | None = None,
              max_steps: int = 20_000, check_every: int = 500, tau_factor: float = 50.0,
              min_steps: int = 1000, tau_rtol: float = 0.01, budget_s: float | None = None,
              progress=None) -> EmceeResult:
    """emcee as run_sampler runs it; with ``budget_s`` it also stops at the first τ check
    after which another block would end past the budget (``budget_hit``)."""
    import emcee

    dim = problem.dim
    n_walkers = default_n_walkers(dim) if n_walkers is None else int(n_walkers)
    names = tuple(map_result.names)
    mixture = moves(map_result.u, map_result.cov)
    sampler = emcee.EnsembleSampler(n_walkers, dim, problem, vectorize=True, moves=mixture)
    rng = np.random.default_rng(seed)
    start = initial_walkers(problem, map_result.u, map_result.cov, n_walkers, rng)
    sampler.random_state = np.random.RandomState(seed).get_state()
    t0 = time.perf_counter()
    converged, reason, history, tau_prev, tau, budget_hit = False, "", [], None, None, False
    while sampler.iteration < max_steps:
        n = min(check_every, max_steps - sampler.iteration)
        sampler.run_mcmc(start, n, progress=False)
        start = None
        _retire_if_rejected(mixture[0][0], sampler.iteration, check_every)
        tau = _tau(sampler)
        history.append((int(sampler.iteration), float(np.max(tau))))
        converged, reason = _check(tau, tau_prev, sampler.iteration, tau_factor, tau_rtol, min_steps, names)
        if progress:
            progress(sampler.iteration, float(np.max(tau)), time.perf_counter() - t0)
        if converged:
            break
        tau_prev = tau
        elapsed = time.perf_counter() - t0
        if budget_s is not None and elapsed * (sampler.iteration + n) / sampler.iteration > budget_s:
            budget_hit = True
            reason = f"stopped by the time budget ({budget_s:g} s) after {sampler.iteration} steps: {reason}"
            break
    sampling_s = time.perf_counter() - t0
    n_steps = int(sampler.iteration)
    if not converged and not budget_hit:
        reason = f"not converged after {n_steps} steps (max_steps = {max_steps}): {reason}"
    burn, thin = _burn_thin(tau, n_steps)
    return EmceeResult(chain=np.asarray(sampler.get_chain(discard=burn, thin=thin)), tau=np.asarray(tau),
                       n_steps=n_steps, burn_in=burn, thin=thin, converged=bool(converged), reason=reason,
                       tau_history=tuple(history), acceptance_fraction=np.asarray(sampler.acceptance_fraction),
                       sampling_s=sampling_s, budget_hit=budget_hit)
